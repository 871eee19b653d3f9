from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import hier_ssl
from hier_ssl.config.learners import PPOConfig
from hier_ssl.policies.ppo import load_ppo, make_ppo_runner, ppo_policy, ppo_train_cfg


def _build_runner(seed: int = 0, **overrides: object):
    """A tiny PPO runner on 32 Proposed fields with frame skip 16."""
    torch.manual_seed(seed)
    settings = {"hidden": (32, 32), "num_steps_per_env": 8, "num_learning_epochs": 2, "num_mini_batches": 2}
    cfg = PPOConfig(**{**settings, **overrides})
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=32)
    return make_ppo_runner(env, cfg, log_dir=None, device="cpu")


def _obs(n: int = 16) -> np.ndarray:
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=n)
    return env.reset(seed=7).numpy()


def test_train_cfg_maps_ppo_config_and_is_fresh() -> None:
    cfg = PPOConfig(hidden=(64, 32), learning_rate=3e-4, entropy_coef=0.001, init_noise_std=0.3, gamma=0.98)
    a, b = ppo_train_cfg(cfg), ppo_train_cfg(cfg)
    assert a == b and a is not b and a["algorithm"] is not b["algorithm"]
    assert a["obs_groups"] == {"actor": ["policy"], "critic": ["policy"]}
    assert a["algorithm"]["learning_rate"] == 3e-4 and a["algorithm"]["entropy_coef"] == 0.001
    assert a["algorithm"]["gamma"] == 0.98
    assert a["actor"]["hidden_dims"] == [64, 32] and a["critic"]["hidden_dims"] == [64, 32]
    assert a["actor"]["distribution_cfg"]["init_std"] == 0.3
    assert not a["actor"]["obs_normalization"] and not a["critic"]["obs_normalization"]


def test_learn_updates_and_policy_acts_in_bounds() -> None:
    runner = _build_runner()
    actor, critic = runner.alg.get_policy(), runner.alg.critic
    before = [p.detach().clone() for p in (*actor.parameters(), *critic.parameters())]
    runner.learn(2)
    after = list((*actor.parameters(), *critic.parameters()))
    # Every tensor, the learned std included, has moved: the update path ran for actor and critic.
    assert all(not torch.equal(b, a) for b, a in zip(before, after, strict=True))
    obs = _obs()
    policy = ppo_policy(runner)
    actions = policy(obs)
    assert actions.shape == (16, 4) and actions.dtype == np.float32
    assert np.all(np.abs(actions) <= 1.0)
    # Deterministic, and the actor's train/eval mode is left as it was.
    assert np.array_equal(actions, policy(obs))
    assert actor.training


def test_policy_clips_the_gaussian_mean() -> None:
    runner = _build_runner()
    last = runner.alg.get_policy().mlp[-1]
    with torch.no_grad():
        last.bias.copy_(torch.tensor([5.0, -5.0, 0.5, 0.0]))
        last.weight.zero_()
    actions = ppo_policy(runner)(_obs(4))
    np.testing.assert_array_equal(actions, np.tile(np.float32([1.0, -1.0, 0.5, 0.0]), (4, 1)))


def test_save_load_round_trip_gives_same_actions(tmp_path: Path) -> None:
    trained = _build_runner(seed=0)
    trained.learn(1)
    path = tmp_path / "model.pt"
    trained.save(str(path))
    # rsl-rl's checkpoint holds only tensors and plain data: the safe loader accepts it.
    assert set(torch.load(path, weights_only=True)) >= {"actor_state_dict", "critic_state_dict", "iter"}
    obs = _obs()
    fresh = _build_runner(seed=1)
    assert not np.array_equal(ppo_policy(fresh)(obs), ppo_policy(trained)(obs))
    load_ppo(fresh, path)
    np.testing.assert_array_equal(ppo_policy(fresh)(obs), ppo_policy(trained)(obs))
    assert fresh.current_learning_iteration == trained.current_learning_iteration


def test_load_missing_checkpoint_names_it(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nope.pt"):
        load_ppo(_build_runner(), tmp_path / "nope.pt")
