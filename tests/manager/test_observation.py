from __future__ import annotations

import math

import numpy as np

from hier_ssl.manager.observation import (
    MANAGER_OBS_BASE_DIM,
    MANAGER_OBS_SLICES,
    OBSTACLE_OBS_DIM,
    OBSTACLE_OBS_SLICES,
    first_robot_observation,
    manager_obs_dim,
    manager_observation,
    observation_scales,
    obstacle_obs_slice,
)
from hier_ssl.world.robot import RobotState


def _build_inputs(n: int = 1, k: int = 1, **overrides: np.ndarray) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    inputs = {
        "target": rng.uniform(-1, 1, (n, 5)),
        "pos": rng.uniform(-1, 1, (n, 2)),
        "angle": rng.uniform(-3, 3, n),
        "vel": rng.uniform(-1, 1, (n, 2)),
        "ang_vel": rng.uniform(-1, 1, n),
        "obs_pos": rng.uniform(-1, 1, (n, k, 2)),
        "obs_vel": rng.uniform(-1, 1, (n, k, 2)),
        "obs_ang_vel": rng.uniform(-1, 1, (n, k)),
    }
    inputs.update(overrides)
    return inputs


def test_values_worked_by_hand() -> None:
    obs = manager_observation(
        target=np.array([[1.9, -0.76, math.pi / 2, 1.25, 0.0]]),  # 1.9 / 3.8 = 0.5, -0.76 / 3.8 = -0.2
        pos=np.array([[5.7, -3.8]]),  # 5.7 / 3.8 = 1.5 -> clipped to 1.2
        angle=np.array([math.pi]),
        vel=np.array([[1.25, -5.0]]),  # -5 / 2.5 = -2 -> clipped to -1.2
        # 5 rad/s / 10 = 0.5; the public code's deg/s reading would give 286.5 / 10 -> 1.2
        ang_vel=np.array([5.0]),
        obs_pos=np.array([[[0.38, 0.0]]]),
        obs_vel=np.array([[[2.5, 0.0]]]),
        obs_ang_vel=np.array([[-20.0]]),  # -2 -> clipped to -1.2
    )
    expected = [0.5, -0.2, 1.0, 0.0, 0.5, 0.0, 1.2, -1.0, 0.0, -1.0, 0.5, -1.2, 0.5, 0.1, 0.0, 1.0, 0.0, -1.2]
    assert obs.dtype == np.float32
    assert obs.shape == (1, 18)
    np.testing.assert_allclose(obs[0], expected, atol=1e-6)


def test_named_slices_tile_the_layout() -> None:
    columns = np.concatenate([np.arange(13)[s] for s in MANAGER_OBS_SLICES.values()])
    np.testing.assert_array_equal(columns, np.arange(MANAGER_OBS_BASE_DIM))
    block = np.concatenate([np.arange(5)[s] for s in OBSTACLE_OBS_SLICES.values()])
    np.testing.assert_array_equal(block, np.arange(OBSTACLE_OBS_DIM))
    assert obstacle_obs_slice(1) == slice(18, 23)
    assert manager_obs_dim(0) == 13 and manager_obs_dim(2) == 23


def test_slices_read_the_right_quantities() -> None:
    inputs = _build_inputs(n=3, k=2)
    obs = manager_observation(**inputs)
    np.testing.assert_allclose(obs[:, MANAGER_OBS_SLICES["robot_vel"]], inputs["vel"] / 2.5, atol=1e-6)
    sincos = obs[:, MANAGER_OBS_SLICES["target_sincos"]]
    np.testing.assert_allclose(np.arctan2(sincos[:, 0], sincos[:, 1]), inputs["target"][:, 2], atol=1e-6)
    second = obs[:, obstacle_obs_slice(1)]
    np.testing.assert_allclose(
        second[:, OBSTACLE_OBS_SLICES["pos"]], inputs["obs_pos"][:, 1] / 3.8, atol=1e-6
    )
    np.testing.assert_allclose(
        second[:, OBSTACLE_OBS_SLICES["ang_vel"]][:, 0], inputs["obs_ang_vel"][:, 1] / 10, atol=1e-6
    )


def test_batched_rows_match_single_fields_and_no_obstacle() -> None:
    inputs = _build_inputs(n=4, k=0)
    obs = manager_observation(**inputs)
    assert obs.shape == (4, 13)
    for i in range(4):
        single = manager_observation(**{name: value[i : i + 1] for name, value in inputs.items()})
        np.testing.assert_array_equal(obs[i], single[0])


def test_first_robot_observation_is_manager_observation_of_the_states_columns() -> None:
    rng = np.random.default_rng(3)
    n, r = 5, 4  # robot 0 observed, robots 1-3 its obstacles; values past the clip included
    target = rng.uniform(-5, 5, (n, 2, 5))
    pos, vel = rng.uniform(-5, 5, (n, r, 2)), rng.uniform(-3, 3, (n, r, 2))
    angle, ang_vel = rng.uniform(-3, 3, (n, r)), rng.uniform(-12, 12, (n, r))
    scales = observation_scales(r - 1, 3.8, 2.5, 10.0)
    obs = first_robot_observation(target, RobotState(pos, angle, vel, ang_vel), scales)
    own = (target[:, 0], pos[:, 0], angle[:, 0], vel[:, 0], ang_vel[:, 0])
    expected = manager_observation(*own, pos[:, 1:], vel[:, 1:], ang_vel[:, 1:])
    assert obs.dtype == np.float32 and obs.shape == (n, manager_obs_dim(r - 1))
    np.testing.assert_array_equal(obs, expected)
