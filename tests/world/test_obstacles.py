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


def test_same_seed_same_draws() -> None:
    pos, angle = _frames(np.random.default_rng(3))
    a = RandomWalk()(pos, angle, np.random.default_rng(9))
    b = RandomWalk()(pos, angle, np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)
