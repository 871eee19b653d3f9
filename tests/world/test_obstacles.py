from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.world.frames import to_field_frame
from hier_ssl.world.obstacles import PublicCodeRandom, RandomWalk, Stationary, make_obstacle

N = 512


def _frames(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return rng.uniform(-2, 2, (N, 2)), rng.uniform(-np.pi, np.pi, N)


def test_make_obstacle_by_name_and_options() -> None:
    assert isinstance(make_obstacle("stationary", 4), Stationary)
    walk = make_obstacle("random_walk", 4, speed=(0.5, 0.7))
    assert isinstance(walk, RandomWalk) and walk.speed == (0.5, 0.7)
    public = make_obstacle("public_code", 4, p_still=0.25)
    assert isinstance(public, PublicCodeRandom) and public.num_fields == 4


def test_unknown_obstacle_or_option_raises_naming_it() -> None:
    with pytest.raises(ValueError, match=r"unknown obstacle behaviour 'kamikaze'; known: \['public_code'"):
        make_obstacle("kamikaze", 1)
    with pytest.raises(ValueError, match="random_walk.*velocity"):
        make_obstacle("random_walk", 1, velocity=1.0)
    with pytest.raises(ValueError, match="speed range"):
        RandomWalk(speed=(1.0, 0.5))
    with pytest.raises(ValueError, match="p_still"):
        PublicCodeRandom(p_still=1.5)


def test_stationary_stands_still() -> None:
    pos, angle = _frames(np.random.default_rng(0))
    np.testing.assert_array_equal(Stationary()(pos, angle, np.random.default_rng(0)), np.zeros((N, 3)))


def test_random_walk_speed_in_range_any_direction_no_spin() -> None:
    rng = np.random.default_rng(1)
    pos, angle = _frames(rng)
    command = RandomWalk(speed=(0.2, 0.9))(pos, angle, rng)
    assert command.shape == (N, 3)
    field_vel = to_field_frame(command[:, 0:2], angle)
    speed = np.linalg.norm(field_vel, axis=1)
    assert speed.min() >= 0.2 - 1e-12 and speed.max() <= 0.9 + 1e-12
    np.testing.assert_array_equal(command[:, 2], 0.0)
    direction = np.arctan2(field_vel[:, 1], field_vel[:, 0])
    assert np.histogram(direction, bins=4, range=(-np.pi, np.pi))[0].min() > N / 8  # all directions


def test_public_code_obstacle_is_still_or_random_per_episode() -> None:
    rng = np.random.default_rng(2)
    pos, angle = _frames(rng)
    behaviour = PublicCodeRandom(num_fields=N)
    behaviour.reset(np.arange(N), rng)
    command = behaviour(pos, angle, rng)
    still = np.all(command == 0.0, axis=1)
    assert 0.35 < still.mean() < 0.65  # p_still = 1/2
    moving = command[~still]
    assert np.abs(moving[:, 0:2]).max() <= 2.5 and np.abs(moving[:, 2]).max() <= np.pi
    # Still fields stay still all episode.
    np.testing.assert_array_equal(behaviour(pos, angle, rng)[still], 0.0)


def test_public_code_commands_are_numpys_uniform_draws_bit_for_bit() -> None:
    # The compiled scaling of the unit draws gives what rng.uniform gave, from the same generator state.
    pos, angle = _frames(np.random.default_rng(4))
    behaviour = PublicCodeRandom(num_fields=N, max_speed=2.5, max_spin=np.pi)
    behaviour.reset(np.arange(N), np.random.default_rng(5))
    rng, twin = np.random.default_rng(6), np.random.default_rng(6)
    for _ in range(3):
        want = np.empty((N, 3))
        want[:, 0:2] = twin.uniform(-2.5, 2.5, (N, 2))
        want[:, 2:3] = twin.uniform(-np.pi, np.pi, (N, 1))
        np.copyto(want, 0.0, where=behaviour._still[:, None])
        np.testing.assert_array_equal(behaviour(pos, angle, rng), want)
    assert rng.random() == twin.random()  # the same number of draws


def test_same_seed_same_draws() -> None:
    pos, angle = _frames(np.random.default_rng(3))
    a = RandomWalk()(pos, angle, np.random.default_rng(9))
    b = RandomWalk()(pos, angle, np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)


def test_an_exposed_obstacle_sees_itself_scaled_and_clipped() -> None:
    from hier_ssl.world.field import get_field
    from hier_ssl.world.obstacles import OBSTACLE_AGENT_OBS_DIM, obstacle_observation
    from hier_ssl.world.physics import RobotSpec, RobotState

    field, robot = get_field("hardware_challenge"), RobotSpec()
    # Field 0: robot 1 inside every limit; field 1: robot 1 beyond the speed and spin limits.
    state = RobotState(
        pos=np.array([[[0.0, 0.0], [1.0, -0.5]], [[0.0, 0.0], [-2.0, 1.0]]]),
        angle=np.array([[0.0, np.pi / 6], [0.0, -np.pi / 2]]),
        vel=np.array([[[0.0, 0.0], [1.0, 0.5]], [[0.0, 0.0], [10.0, 0.0]]]),
        ang_vel=np.array([[0.0, -2.0], [0.0, 50.0]]),
    )
    obs = obstacle_observation(state, 1, field, robot)
    assert obs.shape == (2, OBSTACLE_AGENT_OBS_DIM) and obs.dtype == np.float32
    expected = [
        1.0 / field.max_pos,
        -0.5 / field.max_pos,
        0.5,
        np.sqrt(3) / 2,
        1.0 / robot.max_speed,
        0.5 / robot.max_speed,
        -2.0 / robot.max_ang_speed,
    ]
    np.testing.assert_allclose(obs[0], expected, rtol=1e-6, atol=1e-7)
    assert obs[1, 4] == pytest.approx(1.2) and obs[1, 6] == pytest.approx(1.2)  # clipped
    assert obs[1, 2] == pytest.approx(-1.0) and obs[1, 3] == pytest.approx(0.0, abs=1e-7)
