from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from hier_ssl.config import ConfigError, dump_config
from hier_ssl.config.learners import PPOConfig
from hier_ssl.envs import parse_config, vector_env
from hier_ssl.policies.actor import load_policy
from hier_ssl.policies.networks import SquashedGaussianActor
from hier_ssl.policies.ppo import make_ppo_runner, ppo_policy

OBS_DIM, ACT_DIM = 13, 4  # the Proposed task's manager


def _write_config(run_dir: Path, algo: str) -> None:
    config = parse_config(
        {"algo": algo, "env": {"task": "proposed", "frame_skip": 16}, algo: {"hidden": [16, 24]}}
    )
    run_dir.mkdir()
    (run_dir / "config.yaml").write_text(dump_config(config))


def _obs(n: int = 64) -> np.ndarray:
    return np.random.default_rng(0).uniform(-1.0, 1.0, (n, OBS_DIM)).astype(np.float32)


@pytest.fixture
def sac_run(tmp_path: Path) -> tuple[Path, SquashedGaussianActor]:
    """A SAC run directory holding a random actor in best_actor.pt."""
    torch.manual_seed(0)
    actor = SquashedGaussianActor(OBS_DIM, ACT_DIM, hidden=(16, 24))
    run_dir = tmp_path / "sac"
    _write_config(run_dir, "sac")
    torch.save({"actor": actor.state_dict(), "step": 0}, run_dir / "best_actor.pt")
    return run_dir, actor


def test_sac_policy_is_the_mean_or_a_seeded_sample_of_the_actor(sac_run) -> None:
    run_dir, actor = sac_run
    obs = _obs()
    x = torch.from_numpy(obs)
    with torch.no_grad():
        mean = actor.deterministic(x).numpy()
        drawn = actor(x, torch.Generator().manual_seed(5))[0].numpy()
    np.testing.assert_allclose(load_policy(run_dir)(obs), mean, atol=1e-6)
    sampled = load_policy(run_dir, sample=True, seed=5)
    np.testing.assert_allclose(sampled(obs), drawn, atol=1e-6)
    assert sampled(obs).dtype == np.float32 and np.abs(sampled(obs)).max() <= 1.0
    # Each call draws afresh; the same seed repeats the stream, another seed does not.
    again = load_policy(run_dir, sample=True, seed=5)
    first, second = again(obs), again(obs)
    np.testing.assert_array_equal(first, drawn)
    assert not np.array_equal(first, second)
    assert not np.allclose(load_policy(run_dir, sample=True, seed=6)(obs), drawn)


def test_ppo_policy_samples_its_gaussian_with_the_saved_std(tmp_path: Path) -> None:
    run_dir = tmp_path / "ppo"
    _write_config(run_dir, "ppo")
    torch.manual_seed(1)
    runner = make_ppo_runner(
        vector_env(task="proposed", frame_skip=16, num_envs=2), PPOConfig(hidden=(16, 24))
    )
    actor = runner.alg.get_policy()
    with torch.no_grad():  # small weights keep the mean inside [-1, 1], where the clip does not act
        for p in actor.mlp.parameters():
            p.mul_(0.1)
        actor.distribution.std_param.copy_(torch.tensor([0.1, 0.2, 0.3, 0.4]))
    runner.save(str(run_dir / "model_3.pt"))
    obs = _obs()
    mean = ppo_policy(runner)(obs)
    assert np.abs(mean).max() < 0.9
    np.testing.assert_allclose(load_policy(run_dir)(obs), mean, atol=1e-6)
    noise = torch.randn((len(obs), ACT_DIM), generator=torch.Generator().manual_seed(2)).numpy()
    expected = np.clip(mean + np.array([0.1, 0.2, 0.3, 0.4], np.float32) * noise, -1.0, 1.0)
    np.testing.assert_allclose(load_policy(run_dir, sample=True, seed=2)(obs), expected, atol=1e-5)


def test_a_checkpoint_without_the_std_is_refused_naming_the_file(tmp_path: Path) -> None:
    run_dir = tmp_path / "ppo"
    _write_config(run_dir, "ppo")
    runner = make_ppo_runner(
        vector_env(task="proposed", frame_skip=16, num_envs=2), PPOConfig(hidden=(16, 24))
    )
    saved = runner.alg.save()
    del saved["actor_state_dict"]["distribution.std_param"]
    torch.save({**saved, "iter": 0}, run_dir / "model_0.pt")
    with pytest.raises(ConfigError, match=r"model_0\.pt: not a usable ppo checkpoint .*std"):
        load_policy(run_dir, sample=True)


def test_final_and_best_checkpoints_are_both_readable_and_distinct(sac_run) -> None:
    from hier_ssl.checkpoints.actor import checkpoint_path, load_actor, run_config

    run_dir, best = sac_run
    torch.manual_seed(7)
    final = SquashedGaussianActor(OBS_DIM, ACT_DIM, hidden=(16, 24))
    torch.save({"sac": {"actor": final.state_dict()}, "step": 9}, run_dir / "model.pt")
    x = torch.from_numpy(_obs())
    with torch.no_grad():
        for which, actor in (("best", best), ("final", final)):
            np.testing.assert_allclose(load_actor(run_dir, which)[0](x), actor.deterministic(x), atol=1e-6)
            sampled = load_policy(run_dir, sample=True, seed=3, which=which)(_obs())
            np.testing.assert_allclose(sampled, actor(x, torch.Generator().manual_seed(3))[0], atol=1e-6)
    with pytest.raises(ConfigError, match="checkpoint 'last'"):
        checkpoint_path(run_dir, run_config(run_dir), "last")
    (run_dir / "model.pt").unlink()
    with pytest.raises(ConfigError, match="no final checkpoint"):
        load_actor(run_dir, "final")
