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
