from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.manager.metrics import cpad, cpad_increment, min_time_to_pose, summarize

# A unit square walked once: four 1 m steps.
SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])


def test_cpad_of_a_square() -> None:
    assert cpad(SQUARE) == pytest.approx(4.0)
    # public code: sqrt(1 + 1 + 1 + 1) = 2
    assert cpad(SQUARE, variant="public_code") == pytest.approx(2.0)


def test_held_subgoals_add_nothing() -> None:
    assert cpad(np.repeat(SQUARE, 16, axis=0)) == pytest.approx(4.0)
    assert cpad(SQUARE[:1]) == 0.0
    assert cpad(np.zeros((0, 2))) == 0.0


def test_streaming_matches_episode_cpad() -> None:
    rng = np.random.default_rng(3)
    episodes = rng.uniform(-3, 3, (20, 4, 2))  # (T, N, 2)
    total = np.zeros(4)
    prev = episodes[0]  # first step: no previous sub-goal, adds 0
    for subgoals in episodes:
        total += cpad_increment(prev, subgoals)
        prev = subgoals
    np.testing.assert_allclose(total, [cpad(episodes[:, i]) for i in range(4)])


def test_summarize() -> None:
    # linear percentiles of 1..4: q1 at position 0.75 -> 1.75, median 2.5, q3 at 2.25 -> 3.25
    assert summarize([4.0, 1.0, 3.0, 2.0]) == {"median": 2.5, "q1": 1.75, "q3": 3.25, "min": 1.0, "max": 4.0}
    with pytest.raises(ValueError, match="values"):
        summarize([])


def test_min_time_to_pose() -> None:
    # v_max = 2.5, a_max = 3: reaching v_max and braking from it takes 2.5^2 / 3 = 2.083 m.
    # d = 2 m < 2.083 m: triangular, t = 2 sqrt(2 / 3) = 1.63299 s (peak speed sqrt(2 * 3) = 2.449 m/s).
    # d = 4 m: trapezoidal, t = 4 / 2.5 + 2.5 / 3 = 1.6 + 0.8333 = 2.43333 s.
    # d = 2.5^2 / 3: both give 2 * 2.5 / 3 = 1.66667 s.
    got = min_time_to_pose([0.0, 2.0, 4.0, 2.5**2 / 3], v_max=2.5, a_max=3.0)
    np.testing.assert_allclose(got, [0.0, 2 * math.sqrt(2 / 3), 1.6 + 2.5 / 3, 5 / 3])
    with pytest.raises(ValueError, match="distance"):
        min_time_to_pose([-1.0], 2.5, 3.0)
    with pytest.raises(ValueError, match="a_max"):
        min_time_to_pose([1.0], 2.5, 0.0)
