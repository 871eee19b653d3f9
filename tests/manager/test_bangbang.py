from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.manager.bangbang import bang_bang_1d, bang_bang_2d


def _limits_hold(profile, v_max: float, a_max: float, end: float | complex, dt: float = 1e-3) -> None:
    """Sampled every ``dt`` s: speed within v_max, acceleration (finite differences) within a_max, at rest
    on ``end`` after the total time."""
    t = np.arange(0.0, float(profile.total_time) + 0.5, dt)
    pos, vel = profile.at(t)
    assert np.abs(vel).max() <= v_max + 1e-9
    assert np.abs(np.diff(vel)).max() / dt <= a_max + 1e-6
    assert abs(pos[-1] - end) < 1e-9 and abs(vel[-1]) < 1e-9


def test_1d_rest_to_rest_cruises() -> None:
    # 2 m, v_max 2, a_max 3: 2/3 s to 2 m/s (2/3 m), 2/3 s to brake (2/3 m), 2/3 m at 2 m/s in 1/3 s.
    p = bang_bang_1d(0.0, 2.0, 0.0, 2.0, 3.0)
    np.testing.assert_allclose([p.t1, p.t2, p.t3, p.total_time], [2 / 3, 1 / 3, 2 / 3, 5 / 3])
    np.testing.assert_allclose(p.at(2 / 3), (2 / 3, 2.0))
    _limits_hold(p, 2.0, 3.0, 2.0)


def test_1d_start_velocity_pointing_away() -> None:
    # 1 m ahead at -1 m/s, v_max 2, a_max 2: 0.5 s to stop 0.25 m behind, then 1.25 m rest to rest without
    # reaching v_max: 2 sqrt(1.25 / 2) = 1.5811 s; 2.0811 s in all.
    p = bang_bang_1d(0.0, 1.0, -1.0, 2.0, 2.0)
    assert float(p.total_time) == pytest.approx(0.5 + 2 * math.sqrt(0.625))
    assert float(p.at(0.5)[0]) == pytest.approx(-0.25) and float(p.at(0.5)[1]) == pytest.approx(0.0)
    _limits_hold(p, 2.0, 2.0, 1.0)


def test_1d_overshoot_and_start_above_v_max() -> None:
    # 0.1 m ahead at 2 m/s, a_max 2: it stops 1 m on (1 s), then comes back 0.9 m: 2 sqrt(0.45) s.
    p = bang_bang_1d(0.0, 0.1, 2.0, 2.0, 2.0)
    assert float(p.total_time) == pytest.approx(1.0 + 2 * math.sqrt(0.45))
    _limits_hold(p, 2.0, 2.0, 0.1)
    # 10 m ahead at 3 m/s over a 2 m/s cap: 0.5 s down to 2 m/s (1.25 m), 1 s to brake (1 m), 3.875 s cruise.
    p = bang_bang_1d(0.0, 10.0, 3.0, 2.0, 2.0)
    assert float(p.total_time) == pytest.approx(5.375)
    assert np.abs(p.at(np.linspace(0.5, 5.375, 50))[1]).max() <= 2.0 + 1e-9


def test_2d_rest_to_rest_splits_along_the_line() -> None:
    # To (3, 4), v_max 2, a_max 3: the straight 5 m profile, 2/3 + 11/6 + 2/3 = 19/6 s, alpha = atan2(4, 3)
    # (x gets 3/5 of both limits): both axes arrive together and the path is the straight line.
    p = bang_bang_2d(0j, 3 + 4j, 0j, 2.0, 3.0)
    assert float(p.alpha) == pytest.approx(math.atan2(4, 3), abs=1e-6)
    assert float(p.x.total_time) == pytest.approx(19 / 6, abs=1e-5)
    assert float(p.y.total_time) == pytest.approx(19 / 6, abs=1e-5)
    pos = p.at(np.linspace(0.1, 3.0, 30))[0]
    np.testing.assert_allclose(pos.imag / pos.real, 4 / 3, rtol=1e-4)
    _limits_hold(p, 2.0, 3.0, 3 + 4j)


def test_2d_start_velocity_pointing_away() -> None:
    # At 1 m/s straight away from (3, 4), v_max 2, a_max 3: 1/3 s to stop 1/6 m back, then 31/6 m rest to
    # rest: 2/3 + 23/12 + 2/3; 3.5833 s in all, both axes together.
    p = bang_bang_2d(0j, 3 + 4j, -0.6 - 0.8j, 2.0, 3.0)
    assert float(p.x.total_time) == pytest.approx(43 / 12, abs=1e-5)
    assert float(p.y.total_time) == pytest.approx(43 / 12, abs=1e-5)
    _limits_hold(p, 2.0, 3.0, 3 + 4j)
    # Across the line, both axes still arrive together and no limit is exceeded; longer than from rest.
    p = bang_bang_2d(0j, 2 + 0j, -1.0 + 1.5j, 2.0, 3.0)
    assert float(p.x.total_time) == pytest.approx(float(p.y.total_time), abs=1e-5)
    assert float(p.total_time) > float(bang_bang_2d(0j, 2 + 0j, 0j, 2.0, 3.0).total_time)
    _limits_hold(p, 2.0, 3.0, 2 + 0j)


def test_2d_batches_and_checks_limits() -> None:
    start = np.array([[0j, 1 + 1j], [-2j, 3 - 1j]])
    p = bang_bang_2d(start, 0j, 0.5 + 0j, 2.0, 3.0)
    assert p.total_time.shape == (2, 2)
    one = bang_bang_2d(start[1, 0], 0j, 0.5 + 0j, 2.0, 3.0)
    assert float(p.total_time[1, 0]) == pytest.approx(float(one.total_time))
    with pytest.raises(ValueError, match="v_max and a_max must be > 0"):
        bang_bang_2d(0j, 1j, 0j, 0.0, 3.0)


def test_1d_a_move_starting_away_from_zero_arrives() -> None:
    # From 1 m to 3 m: the 2 m of the first case shifted, 5/3 s, at rest on 3 m (not on 2 m).
    p = bang_bang_1d(1.0, 3.0, 0.0, 2.0, 3.0)
    assert float(p.total_time) == pytest.approx(5 / 3)
    _limits_hold(p, 2.0, 3.0, 3.0)


def test_1d_a_start_that_would_overshoot_stops_beyond_and_comes_back() -> None:
    # At 2 m/s braking at 2 m/s^2 the robot stops 2^2 / (2 * 2) = 1 m on; a target 0.9 m ahead is passed:
    # 1 s to stop on 1 m, then 0.1 m back from rest, 2 sqrt(0.1 / 2) s.
    p = bang_bang_1d(0.0, 0.9, 2.0, 3.0, 2.0)
    assert float(p.total_time) == pytest.approx(1.0 + 2 * math.sqrt(0.05))
    assert float(p.at(1.0)[0]) == pytest.approx(1.0)
    _limits_hold(p, 3.0, 2.0, 0.9)


def test_1d_a_start_that_can_brake_in_time_does_not_overshoot() -> None:
    # 1.5 m ahead at 2 m/s, a_max 2 (braking takes 1 m): speed up to the peak sqrt(2 * 1.5 + 2^2 / 2) =
    # sqrt(5), then brake: (sqrt(5) - 2) / 2 + sqrt(5) / 2 = sqrt(5) - 1 s, never behind the start.
    p = bang_bang_1d(0.0, 1.5, 2.0, 3.0, 2.0)
    assert float(p.total_time) == pytest.approx(math.sqrt(5) - 1)
    assert float(p.vp) == pytest.approx(math.sqrt(5))
    _limits_hold(p, 3.0, 2.0, 1.5)


def test_1d_a_short_move_peaks_below_one_metre_per_second() -> None:
    # 0.5 m at a_max 1.5 from rest: the peak sqrt(1.5 * 0.5) = 0.866 m/s, 2 sqrt(0.5 / 1.5) s.
    p = bang_bang_1d(0.0, 0.5, 0.0, 2.0, 1.5)
    assert float(p.vp) == pytest.approx(math.sqrt(0.75))
    assert float(p.total_time) == pytest.approx(2 * math.sqrt(0.5 / 1.5))
    _limits_hold(p, 2.0, 1.5, 0.5)


def test_1d_cruise_below_one_metre_per_second() -> None:
    # 1 m at v_max 0.5, a_max 1: 0.5 s up (0.125 m), 0.5 s down (0.125 m), 0.75 m at 0.5 m/s: 1.5 s.
    p = bang_bang_1d(0.0, 1.0, 0.0, 0.5, 1.0)
    np.testing.assert_allclose([p.t1, p.t2, p.t3], [0.5, 1.5, 0.5])
    np.testing.assert_allclose(p.at(1.0), (0.375, 0.5))
    _limits_hold(p, 0.5, 1.0, 1.0)


def test_1d_a_robot_at_rest_on_its_target_takes_no_time() -> None:
    assert float(bang_bang_1d(2.0, 2.0, 0.0, 2.0, 3.0).total_time) == 0.0


def test_1d_a_start_above_v_max_decelerates_first() -> None:
    # 3 m/s over a 2 m/s cap, a_max 2: at 0.25 s it has slowed to 2.5 m/s after 3 * 0.25 - 0.25^2 m.
    p = bang_bang_1d(0.0, 10.0, 3.0, 2.0, 2.0)
    np.testing.assert_allclose(p.at(0.25), (0.6875, 2.5))


def test_1d_single_precision_inputs_are_computed_in_double() -> None:
    # From 0.1 to 0.6 as float32 (0.10000000149 and 0.60000002384): the distance is 0.50000002235 m, which
    # float32 arithmetic would round to 0.5; from rest at a_max 3 the time is 2 sqrt(d / 3).
    p = bang_bang_1d(*(np.array([x], np.float32) for x in (0.1, 0.6, 0.0, 2.0, 3.0)))
    d = float(np.float32(0.6)) - float(np.float32(0.1))
    assert abs(float(p.total_time[0]) - 2 * math.sqrt(d / 3)) < 1e-12  # float32 is off by 2e-8


def test_2d_velocity_points_along_the_move() -> None:
    # To (3, 4) at 3 m/s^2: 0.5 s in, 1.5 m/s along (0.6, 0.8).
    p = bang_bang_2d(0j, 3 + 4j, 0j, 2.0, 3.0)
    assert complex(p.at(0.5)[1]) == pytest.approx(0.9 + 1.2j, abs=1e-6)


def test_2d_a_pure_axis_move_takes_the_1d_time_within_unit_limits() -> None:
    # 1 m along x at v_max 1, a_max 1: all of both limits go to x; 1 s up, 1 s down, as in 1-D.
    p = bang_bang_2d(0j, 1 + 0j, 0j, 1.0, 1.0)
    assert float(p.total_time) == pytest.approx(float(bang_bang_1d(0.0, 1.0, 0.0, 1.0, 1.0).total_time))
    assert float(p.total_time) == pytest.approx(2.0)
    _limits_hold(p, 1.0, 1.0, 1 + 0j)


def test_2d_a_zero_acceleration_limit_is_refused() -> None:
    with pytest.raises(ValueError, match="v_max and a_max must be > 0"):
        bang_bang_2d(0j, 1j, 0j, 2.0, 0.0)


def test_1d_a_start_whose_braking_lands_on_the_target_just_brakes() -> None:
    # At -2.1 m/s towards -0.735 m, a_max 3: braking at once stops on it, 2.1^2 / 6 = 0.735 m in 0.7 s;
    # no cruise, not even the rounding of 0.735 m divided by a zero peak speed.
    p = bang_bang_1d(0.0, -0.735, -2.1, 3.0, 3.0)
    assert float(p.t2) == 0.0
    assert float(p.total_time) == pytest.approx(0.7, abs=1e-12)
    _limits_hold(p, 3.0, 3.0, -0.735)
