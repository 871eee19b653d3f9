from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from hier_ssl.config import ConfigError, EnvConfig, GoToPointConfig
from hier_ssl.envs import parse_config
from hier_ssl.envs.gotopoint import GoToPointCore, GoToPointEnv, evaluate_worker, uniform_task
from hier_ssl.envs.vector import RslRlVecEnv
from hier_ssl.worker import make_worker
from hier_ssl.worker.observation import worker_observation
from hier_ssl.worker.rewards import (
    GOTOPOINT_REWARD_TERMS,
    gotopoint_reward,
    pose_potential,
    progress_reward,
    smooth_penalty,
)
from hier_ssl.world.physics import RobotSpec


def _core(n: int = 8, autoreset: bool = True, max_steps: int = 400, **task: object) -> GoToPointCore:
    return GoToPointCore(EnvConfig(max_steps=max_steps), GoToPointConfig(**task), n, autoreset=autoreset)


def _put_on_subgoal(core: GoToPointCore, fields: np.ndarray, offset: float = 0.0) -> None:
    """Place the robots of ``fields`` at rest on their sub-goal (``offset`` m to +x)."""
    goal = core.subgoal[fields]
    pos = goal[:, None, 0:2] + np.array([offset, 0.0])
    core.world.set_state(fields, pos, goal[:, None, 2])


# -- reward terms, by hand ----------------------------------------------------------------------------------


def test_pose_potential_and_progress_by_hand() -> None:
    # 2 m and a half turn with angle_weight 0.5: 2 + 0.5 * pi / pi = 2.5.
    np.testing.assert_allclose(pose_potential([2.0, 0.0], [math.pi, 0.0], 0.5), [2.5, 0.0])
    # From phi 2.5 to 2.0 earns +0.5; moving away costs.
    np.testing.assert_allclose(progress_reward([2.5, 1.0], [2.0, 1.25]), [0.5, -0.25])


def test_smooth_penalty_is_the_squared_command_change() -> None:
    a = np.array([[1.0, 0.0, 0.0], [0.5, 0.5, -1.0]])
    prev = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, -1.0]])
    np.testing.assert_allclose(smooth_penalty(a, prev, 0.1), [-0.1, 0.0])


def test_gotopoint_reward_terms_sum_to_the_total() -> None:
    total, terms = gotopoint_reward(
        [1.0, 0.04],
        [0.9, 0.0],
        np.zeros((2, 3)),
        np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        np.array([False, True]),
        time_cost=0.01,
        smooth_cost=0.5,
        success_bonus=10.0,
    )
    assert tuple(terms) == GOTOPOINT_REWARD_TERMS
    np.testing.assert_allclose(terms["progress"], [0.1, 0.04])
    np.testing.assert_allclose(terms["time"], [-0.01, -0.01])
    np.testing.assert_allclose(terms["smooth"], [0.0, -0.5])
    np.testing.assert_allclose(terms["success"], [0.0, 10.0])
    np.testing.assert_allclose(total, [0.09, 9.53])


# -- the task ----------------------------------------------------------------------------------------------


def test_reset_sampling_follows_the_config() -> None:
    core = _core(256, near_fraction=1.0, near_radius=0.5, moving_fraction=0.0)
    core.reset(seed=3)
    s = core.world.state
    half = np.array([2.9, 1.9])  # 6 x 4 m field less the 0.1 m spawn margin
    assert np.all(np.abs(core.subgoal[:, 0:2]) <= half + 1e-12)
    assert np.all(np.linalg.norm(core.subgoal[:, 0:2] - s.pos[:, 0], axis=1) <= 0.5 + 1e-9)
    assert np.all(s.vel == 0.0) and np.all(s.ang_vel == 0.0) and np.all(core.subgoal[:, 3:5] == 0.0)
    moving = _core(256, moving_fraction=1.0)
    moving.reset(seed=3)
    speed = np.linalg.norm(moving.world.state.vel[:, 0], axis=1)
    assert np.all(speed <= RobotSpec().max_speed + 1e-9) and np.median(speed) > 0.5
    # Seeded: the same episodes again.
    again = _core(256, near_fraction=1.0, near_radius=0.5, moving_fraction=0.0)
    again.reset(seed=3)
    np.testing.assert_array_equal(again.subgoal, core.subgoal)


def test_observation_is_the_worker_observation() -> None:
    core = _core(4)
    obs = core.reset(seed=0)
    s = core.world.state
    expected = worker_observation(
        s.pos[:, 0], s.angle[:, 0], s.vel[:, 0], s.ang_vel[:, 0], core.subgoal, core.robot, 3.8
    )
    np.testing.assert_array_equal(obs, expected)
    assert obs.shape == (4, 9) and obs.dtype == np.float32


def test_success_ends_the_episode_with_the_bonus_and_autoresets() -> None:
    core = _core(3, success_bonus=10.0)
    core.reset(seed=1)
    _put_on_subgoal(core, np.array([0]))
    _put_on_subgoal(core, np.array([1]), offset=0.06)  # just outside D_th = 0.05 m
    goal_before = core.subgoal.copy()
    result = core.step(np.zeros((3, 3)))
    assert result.terminated.tolist() == [True, False, False] and not result.truncated.any()
    assert result.reward[0] > 9.0 and result.reward[1] < 1.0
    episode = result.info["task"]
    assert episode["field"].tolist() == [0] and episode["length"].tolist() == [1]
    assert episode["success"].tolist() == [1.0]
    # Field 0 starts over: a new sub-goal, and obs differs from the final observation.
    assert not np.array_equal(core.subgoal[0], goal_before[0])
    np.testing.assert_array_equal(core.subgoal[1:], goal_before[1:])
    assert not np.array_equal(result.obs[0], result.info["final_obs"][0])
    np.testing.assert_array_equal(result.obs[1:], result.info["final_obs"][1:])


def test_reach_thresholds_end_training_episodes_and_evaluation_uses_the_envs() -> None:
    tight = _core(2, reach_d_th=0.02, reach_theta_th_deg=2.0)
    loose = _core(2)
    for core in (tight, loose):
        core.reset(seed=4)
        _put_on_subgoal(core, np.array([0]), offset=0.03)  # 3 cm off: inside 5 cm, outside 2 cm
        _put_on_subgoal(core, np.array([1]), offset=0.01)
    assert tight.step(np.zeros((2, 3))).terminated.tolist() == [False, True]
    assert loose.step(np.zeros((2, 3))).terminated.tolist() == [True, True]
    evaluation = uniform_task(GoToPointConfig(reach_d_th=0.02, reach_theta_th_deg=2.0, near_fraction=0.7))
    assert evaluation == GoToPointConfig(near_fraction=0.0, moving_fraction=0.0)


def test_timeout_truncates_and_finished_fields_hold_without_autoreset() -> None:
    core = _core(2, autoreset=False, max_steps=3, near_fraction=0.0)
    core.reset(seed=2)
    _put_on_subgoal(core, np.array([0]))
    first = core.step(np.zeros((2, 3)))
    assert first.terminated.tolist() == [True, False]
    held = core.world.state.pos[0].copy()
    for _ in range(2):
        result = core.step(np.ones((2, 3)))  # a finished field ignores its action
    assert result.truncated.tolist() == [False, True] and not result.terminated.any()
    assert result.reward[0] == 0.0 and core.done.all()
    np.testing.assert_array_equal(core.world.state.pos[0], held)
    with pytest.raises(RuntimeError, match="reset"):
        core.step(np.zeros((2, 3)))


def test_bad_actions_are_named() -> None:
    core = _core(2)
    core.reset(seed=0)
    with pytest.raises(ValueError, match="worker.*shape"):
        core.step(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="NaN"):
        core.step(np.full((2, 3), np.nan))


def test_vector_view_and_rsl_rl_adapter() -> None:
    env = GoToPointEnv(EnvConfig(max_steps=5), GoToPointConfig(), 4, seed=0)
    obs = env.reset()
    assert obs.shape == (4, 9) and obs.dtype == torch.float32
    assert (env.num_obs, env.num_actions, env.max_episode_length) == (9, 3, 5)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(torch.zeros(4, 3))
    assert reward.dtype == torch.float32 and truncated.dtype == torch.bool
    assert set(info["task"]) == {"return", "length", "success", "start_distance"}
    adapter = RslRlVecEnv(GoToPointEnv(EnvConfig(), GoToPointConfig(), 4, seed=0))
    td, reward, dones, extras = adapter.step(torch.full((4, 3), 5.0))  # clamped to [-1, 1]
    assert td["policy"].shape == (4, 9) and dones.shape == (4,)


@pytest.mark.parametrize("name", ["paper", "bangbang"])
def test_scripted_workers_reach_random_subgoals(name: str) -> None:
    worker = make_worker(name, RobotSpec(), 0.025)
    result = evaluate_worker(worker, EnvConfig(max_steps=400), uniform_task(GoToPointConfig()), 100, seed=0)
    assert result["success_rate"] == 1.0
    # Never faster than the analytic minimum for the distance, bang-bang within 25 % of it.
    length, distance = result["per_episode"]["length"], result["per_episode"]["distance"]
    assert result["time_s"]["median"] >= result["min_time_s"]["median"] - 0.025
    assert np.all(length >= 1) and distance.shape == (100,)
    if name == "bangbang":
        assert result["optimal_ratio_median"] < 1.25


def test_worker_config_kind_and_errors() -> None:
    config = parse_config({"kind": "worker", "algo": "ppo"})
    assert config.gotopoint == GoToPointConfig()
    with pytest.raises(ConfigError, match="gotopoint: only read when kind is 'worker'"):
        parse_config({"gotopoint": {}})
    with pytest.raises(ConfigError, match="algo: kind 'worker' trains with 'ppo'"):
        parse_config({"kind": "worker", "algo": "sac"})
    with pytest.raises(ConfigError, match="gotopoint.near_fraction"):
        parse_config({"kind": "worker", "algo": "ppo", "gotopoint": {"near_fraction": 2}})
