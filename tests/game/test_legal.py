"""The nearest legal point, a straight path's clearance and the stop speed, with every number worked by hand.

Shapes used throughout: the ball's circle at the origin (a point capsule, STOP's 0.5 + 0.09 m); a ball
placement's stadium (0, 0) -> (2, 0), 0.59 m; a box (1, -1) - (2, 1) kept 0.09 m from (an own defense
area); a keep-in box (-1, -1) - (1, 1) kept 0.09 m inside (the walls). SLACK (1e-9 m) is where a moved
point lands beyond the clearance, so distances are compared to 1e-8.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.game import zones as z
from hier_ssl.game.legal import (
    cap_speed,
    distances,
    nearest_legal,
    path_clearance,
    row_rules,
    segment_clearance,
)

BALL = (z.CAPSULE, (0.0, 0.0, 0.0, 0.0), 0.59)
STADIUM = (z.CAPSULE, (0.0, 0.0, 2.0, 0.0), 0.59)
BOX = (z.BOX, (1.0, -1.0, 2.0, 1.0), 0.09)
KEEP = (z.KEEP_IN, (-1.0, -1.0, 1.0, 1.0), 0.09)
EMPTY = (z.NONE, (0.0, 0.0, 0.0, 0.0), 0.0)


def _zones(*slots: tuple[int, tuple[float, ...], float]) -> z.Zones:
    """One robot's zones (1, S)."""
    return z.Zones(
        np.array([[s[0] for s in slots]]),
        np.array([[s[1] for s in slots]], float),
        np.array([[s[2] for s in slots]], float),
    )


def _moved(zones: z.Zones, target: tuple[float, float]) -> np.ndarray:
    point = nearest_legal(zones, np.array([target]))[0]
    assert (distances(zones, point[None]) >= 0.0).all()  # no zone broken, ``violates`` False
    return point


@pytest.mark.parametrize(
    ("slot", "target", "expected"),
    [
        (BALL, (0.3, 0.0), (0.59, 0.0)),  # out along the ray from the ball
        (BALL, (0.0, -0.1), (0.0, -0.59)),
        (STADIUM, (1.0, 0.2), (1.0, 0.59)),  # out of a stadium's side, square to the segment
        (STADIUM, (2.3, 0.0), (2.59, 0.0)),  # out of its end
        (BOX, (1.05, 0.2), (0.91, 0.2)),  # inside the box: out through the nearest edge (0.05 m away)
        (BOX, (1.9, -0.5), (2.09, -0.5)),  # nearest edge x = 2
        (BOX, (0.95, 0.2), (0.91, 0.2)),  # outside the box, within the clearance of its edge
        # Off its corner (1, 1), 0.05 m each way: out along the diagonal to 0.09 m from the corner.
        (BOX, (0.95, 1.05), (1 - 0.09 / math.sqrt(2), 1 + 0.09 / math.sqrt(2))),
        (KEEP, (1.2, 0.3), (0.91, 0.3)),  # back inside, 0.09 m from the edge
        (KEEP, (1.2, 1.5), (0.91, 0.91)),  # beyond a corner: the inner corner
        (KEEP, (0.95, -0.95), (0.91, -0.91)),  # inside the box but within the clearance of two edges
    ],
)
def test_a_target_in_a_zone_moves_to_its_edge(slot, target, expected) -> None:
    zones = _zones(slot, EMPTY)
    point = _moved(zones, target)
    assert point == pytest.approx(expected, abs=1e-8)
    assert distances(zones, point[None])[0, 0] == pytest.approx(0.0, abs=1e-8)  # at the clearance


def test_a_target_outside_every_zone_is_kept_bit_for_bit() -> None:
    zones = _zones(BALL, BOX, KEEP)
    targets = np.array([[0.6, 0.0], [0.0, 0.59], [0.3 + 1 / 3, -0.1]])  # each keeps every zone
    out = nearest_legal(zones, targets)
    assert out.tobytes() == targets.tobytes()
    # Rows that keep their zones stay bit for bit beside a row that does not.
    many = z.Zones(*(np.repeat(x, 2, axis=0) for x in (zones.kind, zones.shape, zones.clearance)))
    both = nearest_legal(many, np.array([[1 / 7 + 0.6, 0.0], [0.3, 0.0]]))
    assert both[0].tobytes() == np.array([1 / 7 + 0.6, 0.0]).tobytes()
    assert both[1] == pytest.approx([0.59, 0.0], abs=1e-8)


def test_overlapping_zones_give_the_corner_they_make() -> None:
    # The ball at (-3, 0) (0.59 m) next to a defense area x <= -3.5 (0.09 m): the target (-3.3, 0) is in the
    # ball's circle; straight out of it, (-3.59, 0), is in the area's clearance (x > -3.41 is needed), and
    # straight out of that is back in the circle. The nearest legal points are where the line x = -3.41
    # meets the circle: y = +-sqrt(0.59^2 - 0.41^2) = +-sqrt(0.18), 0.4383 m from the target; the next
    # nearest, the circle's far side (-2.41, 0), is 0.89 m away.
    zones = _zones((z.CAPSULE, (-3.0, 0.0, -3.0, 0.0), 0.59), (z.BOX, (-4.5, -1.0, -3.5, 1.0), 0.09))
    point = _moved(zones, (-3.3, 0.0))
    assert point[0] == pytest.approx(-3.41, abs=1e-8)
    assert abs(point[1]) == pytest.approx(math.sqrt(0.18), abs=1e-8)
    # The ball near the keep-in edge x <= 0.91: the target (1, 0.1) breaks both; the nearest legal point
    # is on x = 0.91 and the ball's circle about (0.9, 0): y = sqrt(0.59^2 - 0.01^2) = sqrt(0.348).
    zones = _zones((z.CAPSULE, (0.9, 0.0, 0.9, 0.0), 0.59), KEEP)
    assert _moved(zones, (1.0, 0.1)) == pytest.approx((0.91, math.sqrt(0.348)), abs=1e-8)


def test_no_legal_point_gives_a_less_broken_one() -> None:
    # A circle of 2 m about the origin covers the whole keep-in box, so every point breaks a zone. The
    # target (0.5, 0.6) breaks the circle by 2 - 0.781 = 1.219 m; the box's inner corner (0.91, 0.91), by
    # 2 - 1.287 = 0.713 m. The answer is a candidate (on a zone's edge) that breaks its worst zone by less.
    zones = _zones((z.CAPSULE, (0.0, 0.0, 0.0, 0.0), 2.0), KEEP)
    point = nearest_legal(zones, np.array([[0.5, 0.6]]))[0]
    away = distances(zones, point[None])[0]
    assert away.min() > 1.287 - 2.0
    assert np.isclose(away, 0.0, atol=1e-8).any()  # on the edge of one zone


@pytest.mark.parametrize(
    ("slot", "start", "end", "expected"),
    [
        (BALL, (-1.0, 0.0), (3.0, 0.0), -0.59),  # through the ball
        (BALL, (-1.0, 1.0), (1.0, 1.0), 1.0 - 0.59),  # 1 m beside it
        (BALL, (3.0, 4.0), (6.0, 8.0), 5.0 - 0.59),  # moving away: its nearer end, 5 m
        (STADIUM, (1.0, -1.0), (1.0, 1.0), -0.59),  # across the placement segment
        (STADIUM, (3.0, -1.0), (3.0, 1.0), 1.0 - 0.59),  # past its end (2, 0), 1 m off
        (BOX, (0.0, 0.0), (3.0, 0.0), -0.09),  # through the box
        (BOX, (0.0, 1.5), (3.0, 1.5), 0.5 - 0.09),  # along it, 0.5 m above its top
        (BOX, (2.5, 0.5), (1.5, 1.5), -0.09),  # through its corner (2, 1), on the line x + y = 3
        (BOX, (3.0, 1.0), (2.0, 2.0), 1 / math.sqrt(2) - 0.09),  # the line x + y = 4: corner 0.707 m off
        (BOX, (0.0, 0.0), (0.5, 0.0), 0.5 - 0.09),  # stops 0.5 m short of it
        (KEEP, (0.0, 0.0), (0.5, 0.95), 0.05 - 0.09),  # an end 0.05 m from the top edge
        (KEEP, (-0.5, 0.0), (0.5, 0.0), 0.5 - 0.09),  # both ends 0.5 m from the side edges
        (EMPTY, (0.0, 0.0), (1.0, 0.0), math.inf),
    ],
)
def test_a_straight_path_against_each_shape(slot, start, end, expected) -> None:
    value = segment_clearance(_zones(slot), np.array([start]), np.array([end]))[0, 0]
    assert value == pytest.approx(expected, abs=1e-12)
    complex_form = path_clearance(_zones(slot), np.array([complex(*start)]), np.array([complex(*end)]))
    assert complex_form[0, 0] == value


def test_the_stop_speed_caps_a_velocity_and_keeps_its_direction() -> None:
    velocity = np.array([[3.0, 4.0], [0.3, 0.4], [3.0, 4.0], [3.0, 4.0]])
    limit = np.array([1.5, 1.5, 0.0, np.inf])  # STOP, STOP, HALT, running
    out = cap_speed(velocity, limit)
    assert out[0] == pytest.approx([0.9, 1.2])  # 5 m/s scaled by 1.5 / 5
    assert out[1].tobytes() == velocity[1].tobytes() and out[3].tobytes() == velocity[3].tobytes()
    assert out[2].tolist() == [0.0, 0.0]


def test_row_rules_are_field_major() -> None:
    n, m = 2, 3
    kind = np.arange(n * m * 4).reshape(n, m, 4) % 4
    shape = np.arange(n * m * 4 * 4, dtype=float).reshape(n, m, 4, 4)
    rules = row_rules(z.Zones(kind, shape, kind * 0.1), np.array([1.5, np.inf]))
    assert rules.zones.kind.shape == (6, 4) and rules.zones.shape.shape == (6, 4, 4)
    assert rules.zones.shape[4].tolist() == shape[1, 1].tolist()  # row 4: field 1, robot 1
    assert rules.speed.tolist() == [1.5, 1.5, 1.5, np.inf, np.inf, np.inf]
