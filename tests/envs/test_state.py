"""``state()`` and ``state_space``: the global field state on the paper tasks and every scenario."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, state_test
from pettingzoo.utils.conversions import parallel_to_aec

import hier_ssl
from hier_ssl.envs.state import state_columns, state_dim
from hier_ssl.manager.observation import MANAGER_OBS_SLICES

VIEWS = [
    ("proposed", {"frame_skip": 16}),
    ("obstacle", {"frame_skip": 4, "expose_worker": True, "expose_obstacles": True}),
    ("crossing", {"num_agents": 3, "num_obstacles": 2}),
    ("crowd", {}),
    ("formation", {}),
]


def _env(name: str, settings: dict) -> hier_ssl.envs.HierarchicalSSLEnv:
    return hier_ssl.parallel_env(name, **settings)


@pytest.mark.parametrize(("name", "settings"), VIEWS)
def test_pettingzoo_state_test_and_api_test_pass(name: str, settings: dict) -> None:
    state_test(parallel_to_aec(_env(name, settings)), _env(name, settings), num_cycles=20)
    parallel_api_test(_env(name, settings), num_cycles=30)


@pytest.mark.parametrize(("name", "settings"), VIEWS)
def test_the_state_space_is_built_once_and_holds_every_state(name: str, settings: dict) -> None:
    env = _env(name, settings)
    m, k = env.core.num_agents, env.core.num_obstacles
    assert env.state_space is env.state_space and env.state_space.shape == (state_dim(m, k),)
    assert len(state_columns(m, k)) == state_dim(m, k) == 7 * (m + k) + 13 * m
    env.reset(seed=1)
    while env.agents:
        state = env.state()
        assert state.dtype == np.float32 and env.state_space.contains(state)
        env.step({a: env.action_space(a).sample() for a in env.agents})


def test_columns_match_the_observation_and_the_core() -> None:
    env = hier_ssl.parallel_env(task="obstacle", frame_skip=4)
    obs = env.reset(seed=2)[0]["manager_0"]
    env.step({"manager_0": np.array([0.4, -0.3, 0.6, 0.8])})
    obs = env.step({"manager_0": np.array([0.4, -0.3, 0.6, 0.8])})[0]["manager_0"]
    state = dict(zip(state_columns(1, 1), env.state(), strict=True))
    core, s = env.core, env.core.state
    # Normalised as the manager observation is: the robot's and target's columns are its values.
    robot = [state[f"manager_0_{c}"] for c in ("x", "y", "sin", "cos", "vx", "vy", "omega")]
    np.testing.assert_array_equal(robot[0:2], obs[MANAGER_OBS_SLICES["robot_pos"]])
    np.testing.assert_array_equal(robot[2:4], obs[MANAGER_OBS_SLICES["robot_sincos"]])
    np.testing.assert_array_equal(robot[4:6], obs[MANAGER_OBS_SLICES["robot_vel"]])
    np.testing.assert_array_equal(robot[6:7], obs[MANAGER_OBS_SLICES["robot_ang_vel"]])
    target = [state[f"manager_0_target_{c}"] for c in ("x", "y", "sin", "cos", "vx", "vy")]
    np.testing.assert_array_equal(target[0:2], obs[MANAGER_OBS_SLICES["target_pos"]])
    np.testing.assert_array_equal(target[2:4], obs[MANAGER_OBS_SLICES["target_sincos"]])
    # The obstacle and the held sub-goal, in physical units.
    max_pos, max_v = core.field.max_pos, core.robot.max_speed
    np.testing.assert_allclose(
        [state["obstacle_0_x"], state["obstacle_0_y"]], s.pos[0, 1] / max_pos, rtol=1e-6
    )
    np.testing.assert_allclose(
        [state["obstacle_0_vx"], state["obstacle_0_vy"]], s.vel[0, 1] / max_v, rtol=1e-6
    )
    np.testing.assert_allclose(state["obstacle_0_sin"], np.sin(s.angle[0, 1]), rtol=1e-6)
    subgoal = core.subgoal[0, 0]
    np.testing.assert_allclose(
        [state["manager_0_subgoal_x"], state["manager_0_subgoal_y"]], subgoal[:2] / max_pos, rtol=1e-6
    )
    np.testing.assert_allclose(
        [state["manager_0_subgoal_sin"], state["manager_0_subgoal_cos"]], [0.6, 0.8], rtol=1e-6
    )
    assert state["manager_0_active"] == 1.0


def test_the_active_columns_follow_the_agents_that_are_left() -> None:
    env = hier_ssl.parallel_env("crossing", num_agents=3, action_frame="target", max_steps=400)
    env.reset(seed=3)
    names = state_columns(3, 0)
    active = [names.index(f"manager_{i}_active") for i in range(3)]
    seen = set()
    while env.agents:
        # Robot 0 heads straight for its target (the zero action), the others wander.
        actions = {a: env.action_space(a).sample() * (a != "manager_0") for a in env.agents}
        env.step(actions)
        flags = env.state()[active].tolist()
        assert flags == [float(f"manager_{i}" in env.agents) for i in range(3)]
        seen.add(tuple(flags))
    assert len(seen) == 3  # robot 0 reached its target first, the others timed out later
