from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from hier_ssl.config import EnvConfig, GoToPointConfig, TrainConfig, dump_config
from hier_ssl.envs import HierarchicalCore, parse_config
from hier_ssl.envs.gotopoint import GoToPointCore, GoToPointEnv
from hier_ssl.policies.ppo import make_ppo_runner, ppo_policy
from hier_ssl.runs.train import train
from hier_ssl.worker import LearnedWorker, make_worker
from hier_ssl.world.physics import RobotSpec, RobotState

SPEC, DT = RobotSpec(), 0.025
# Near sub-goals from rest, 2 s episodes: what a short run can learn.
NEAR = {"near_fraction": 1.0, "near_radius": 1.0, "moving_fraction": 0.0, "time_cost": 0.05}


def _worker_config(**overrides: object) -> TrainConfig:
    data = {
        "name": "worker-test",
        "kind": "worker",
        "algo": "ppo",
        "num_envs": 64,
        "total_steps": 16 * 20,  # 20 PPO iterations of 16 steps x 64 fields
        "eval_episodes": 8,
        "threads": 1,
        "env": {"max_steps": 80},
        "gotopoint": NEAR,
        "ppo": {"hidden": [64, 64], "num_steps_per_env": 16, "gamma": 0.99, "init_noise_std": 0.5},
    }
    return parse_config({**data, **overrides})


@pytest.fixture(scope="module")
def trained_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A worker trained by ``hier_ssl.runs.train`` for 20 short PPO iterations, seed 0."""
    run_dir = tmp_path_factory.mktemp("worker") / "run"
    train(_worker_config(), run_dir)
    return run_dir


def _final_distance(worker: object, seed: int = 123, fields: int = 200) -> tuple[float, float]:
    """Median start and end distance to near sub-goals after 80 steps (2 s) of ``worker``."""
    config = _worker_config()
    core = GoToPointCore(config.env, config.gotopoint, fields, autoreset=False)
    core.reset(seed)
    start = core.start_distance.copy()
    while not core.done.all():
        core.step_command(worker(core.world.state, core.subgoal[:, None])[:, 0])
    end = np.linalg.norm(core.world.state.pos[:, 0] - core.subgoal[:, 0:2], axis=1)
    return float(np.median(start)), float(np.median(end))


class _Random:
    def __init__(self) -> None:
        self.rng = np.random.default_rng(0)

    def reset(self, fields: np.ndarray) -> None:
        pass

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        action = self.rng.uniform(-1.0, 1.0, (*state.angle.shape, 3))
        return action * np.array([SPEC.max_speed, SPEC.max_speed, SPEC.max_ang_speed])


def test_a_short_run_learns_to_approach_near_subgoals(trained_run: Path) -> None:
    learned = make_worker(str(trained_run), SPEC, DT)
    start, end = _final_distance(learned)
    _, random_end = _final_distance(_Random())
    print(
        f"\nmedian distance to the sub-goal: start {start:.3f} m, learned {end:.3f} m, "
        f"random {random_end:.3f} m"
    )
    # Standing still keeps the start distance; random commands drift away; the learner closes in.
    assert end < 0.85 * start and end < 0.85 * random_end
    summary = json.loads((trained_run / "eval.json").read_text())
    assert summary["task"] == "gotopoint" and set(summary["workers"]) == {"learned", "paper", "bangbang"}


def test_learned_worker_is_frozen_and_acts_as_the_trained_policy(trained_run: Path) -> None:
    worker = make_worker(str(trained_run), SPEC, DT)
    assert isinstance(worker, LearnedWorker) and worker.actor is not None
    assert not worker.actor.training
    assert all(not p.requires_grad for p in worker.actor.parameters())
    # The same commands as the rsl-rl actor it was read from (the highest-numbered checkpoint).
    config = _worker_config()
    env = GoToPointEnv(config.env, config.gotopoint, 16, seed=4)
    runner = make_ppo_runner(env, config.ppo, log_dir=None)  # resets the env
    obs = env.observe()
    saved = max(trained_run.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))
    runner.alg.load(torch.load(saved, weights_only=True), None, strict=True)
    core = env.core
    command = worker(core.world.state, core.subgoal[:, None])[:, 0]
    expected = ppo_policy(runner)(obs.numpy()) * np.array([2.5, 2.5, 10.0])
    np.testing.assert_allclose(command, expected, rtol=1e-6, atol=1e-6)


def test_loading_is_read_only_and_the_core_runs_a_learned_worker(trained_run: Path) -> None:
    before = {p.name: p.read_bytes() for p in trained_run.iterdir() if p.is_file()}
    core = HierarchicalCore(EnvConfig(worker=f"{trained_run}+latency=1"), num_fields=2)
    core.reset(seed=0)
    result = core.step(np.tile([0.1, 0.1, 0.0, 1.0], (2, 1, 1)))
    assert result.obs.shape == (2, 1, 13)
    assert {p.name: p.read_bytes() for p in trained_run.iterdir() if p.is_file()} == before


def test_unusable_run_directories_are_named(tmp_path: Path, trained_run: Path) -> None:
    with pytest.raises(ValueError, match="unknown worker 'nowhere'"):
        make_worker("nowhere", SPEC, DT)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match=f"{empty}: not a run directory"):
        make_worker(str(empty), SPEC, DT)
    (empty / "config.yaml").write_text(dump_config(_worker_config()))
    with pytest.raises(ValueError, match=f"{empty}: no usable checkpoint"):
        make_worker(str(empty), SPEC, DT)
    (empty / "model_3.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="model_3.pt: not a usable ppo checkpoint"):
        make_worker(str(empty), SPEC, DT)
    manager = tmp_path / "manager"
    manager.mkdir()
    (manager / "config.yaml").write_text(dump_config(parse_config({"algo": "ppo"})))
    for src in trained_run.glob("model_*.pt"):
        (manager / src.name).write_bytes(src.read_bytes())
    with pytest.raises(ValueError, match="a manager run, not a goToPoint worker"):
        make_worker(str(manager), SPEC, DT)
    with pytest.raises(ValueError, match="trained at dt 0.025 s, the environment steps at 0.05 s"):
        make_worker(str(trained_run), SPEC, 0.05)


def test_learned_worker_batches_fields_and_robots() -> None:
    seen = []

    def policy(obs: np.ndarray) -> np.ndarray:
        seen.append(obs.shape)
        return np.tile([1.5, -0.5, 0.25], (len(obs), 1))  # out of range on purpose: clipped

    worker = LearnedWorker(policy, SPEC, max_pos=3.8)
    state = RobotState(np.zeros((3, 2, 2)), np.zeros((3, 2)), np.zeros((3, 2, 2)), np.zeros((3, 2)))
    command = worker(state, np.zeros((3, 2, 5)))
    assert seen == [(6, 9)] and command.shape == (3, 2, 3)
    np.testing.assert_allclose(command[1, 1], [2.5, -1.25, 2.5])


def test_goto_config_defaults_are_used_when_kind_is_worker() -> None:
    assert _worker_config(gotopoint=None).gotopoint == GoToPointConfig()
