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
from hier_ssl.game.segments import axis_depth
from hier_ssl.manager.sampling_rollouts import PASS, open_ends

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


def _rows(*rows: tuple[tuple[int, tuple[float, ...], float], ...]) -> z.Zones:
    """Robots' zones (R, S), one row each."""
    each = [_zones(*row) for row in rows]
    return z.Zones(*(np.concatenate([getattr(a, f) for a in each]) for f in ("kind", "shape", "clearance")))


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


def test_integer_targets_move_to_a_point_between_integers() -> None:
    # (1, 0) lies on the box's edge x = 1, inside its 0.09 m clearance: out to (0.91, 0), not rounded to 0.
    out = nearest_legal(_zones(BOX, EMPTY), [[1, 0]])
    assert out[0] == pytest.approx((0.91, 0.0), abs=1e-8)


def test_the_referees_field_by_robot_zones_give_each_robot_its_own_point() -> None:
    # N = 2 fields of M = 3 robots, S = 2 slots (M != S, so no axis can stand in for another).
    slots = [[(BALL, EMPTY)] * 3, [(BOX, EMPTY), (KEEP, BALL), (EMPTY, EMPTY)]]
    zones = z.Zones(
        np.array([[[s[0] for s in robot] for robot in field] for field in slots]),
        np.array([[[s[1] for s in robot] for robot in field] for field in slots], float),
        np.array([[[s[2] for s in robot] for robot in field] for field in slots], float),
    )
    targets = np.array([[[0.3, 0.0], [2.0, 2.0], [0.0, -0.1]], [[1.05, 0.2], [1.2, 0.3], [5.0, 5.0]]])
    out = nearest_legal(zones, targets)
    assert out.shape == (2, 3, 2)
    # Field 0: out of the ball to 0.59 m, kept (2.83 m off), out of the ball; field 1: out of the box's
    # edge x = 1, back inside the keep-in (0.91, 0.3), 0.958 m from the ball, no zones at all.
    expected = [[[0.59, 0.0], [2.0, 2.0], [0.0, -0.59]], [[0.91, 0.2], [0.91, 0.3], [5.0, 5.0]]]
    assert out.tolist() == [[pytest.approx(p, abs=1e-8) for p in field] for field in expected]
    away = distances(zones, targets)
    assert away.shape == (2, 3, 2)
    assert away[0, 0].tolist() == [pytest.approx(0.3 - 0.59), np.inf]
    assert away[1, 1].tolist() == pytest.approx([-0.2 - 0.09, math.hypot(1.2, 0.3) - 0.59])


def test_one_point_against_several_rows_of_zones() -> None:
    # The point (0.3, 0.4), 0.5 m from the origin, against three robots' zones: the ball (0.5 - 0.59); the
    # stadium, 0.4 m above its segment, and the box, 0.7 m left of it; the keep-in, 0.6 m from its top.
    zones = _rows((BALL, EMPTY), (STADIUM, BOX), (KEEP, EMPTY))
    away = distances(zones, np.array([0.3, 0.4]))
    assert away.tolist() == [
        [pytest.approx(-0.09), np.inf],
        [pytest.approx(-0.19), pytest.approx(0.61)],
        [pytest.approx(0.51), np.inf],
    ]


def test_one_row_of_zones_against_several_paths() -> None:
    # The ball and the box against three paths: 1 m beside the ball and 1 m short of the box's corner
    # (1, 1); through both; moving away, 5 m from the ball and sqrt(10) m from the box's corner (2, 1).
    value = path_clearance(
        _zones(BALL, BOX), np.array([-1 + 1j, -1 + 0j, 3 + 4j]), np.array([0 + 1j, 3 + 0j, 6 + 8j])
    )
    assert value.shape == (3, 2)
    assert value.tolist() == [
        pytest.approx([1 - 0.59, 1 - 0.09]),
        pytest.approx([-0.59, -0.09]),
        pytest.approx([5 - 0.59, math.sqrt(10) - 0.09]),
    ]


def test_zones_per_row_against_that_rows_paths() -> None:
    # Zones (2, 1, S) against paths (2, 2): row 0 the ball (1 m beside it, through it); row 1 the box and
    # the keep-in: (0, 0) -> (0.5, 0.8) ends 0.5 m from the box's edge x = 1 and 0.2 m below the keep-in's
    # top; x = 1.5 from y = -2 to 2 crosses the box, its ends 1 m beyond the keep-in's y edges.
    zones = _rows((BALL, EMPTY), (BOX, KEEP))
    zones = z.Zones(zones.kind[:, None], zones.shape[:, None], zones.clearance[:, None])
    start = np.array([[-1 + 1j, -1 + 0j], [0j, 1.5 - 2j]])
    end = np.array([[1 + 1j, 3 + 0j], [0.5 + 0.8j, 1.5 + 2j]])
    value = path_clearance(zones, start, end)
    assert value.shape == (2, 2, 2)
    assert value.tolist() == [
        [[pytest.approx(1 - 0.59), np.inf], [pytest.approx(-0.59), np.inf]],
        [pytest.approx([0.5 - 0.09, 0.2 - 0.09]), pytest.approx([-0.09, -1 - 0.09])],
    ]


# Path i against zones row j: the ball, and the box with the keep-in. (0, 0) -> (0.5, 0.8) as above; the
# path (-1, 1.5) -> (0, 1.5) passes 1.5 m above the ball, sqrt(1.25) m from the box's corner (1, 1), and
# ends 0.5 m above the keep-in's top.
SPREAD = [
    [[-0.59, np.inf], [0.5 - 0.09, 0.2 - 0.09]],
    [[1.5 - 0.59, np.inf], [math.sqrt(1.25) - 0.09, -0.5 - 0.09]],
]


@pytest.mark.parametrize("given", ["broadcast", "in full"])
def test_zones_and_paths_broadcast_like_arrays(given) -> None:
    zones = _rows((BALL, EMPTY), (BOX, KEEP))  # (2, S): rows j, against paths (2, 1): rows i
    start, end = np.array([[0j], [-1 + 1.5j]]), np.array([[0.5 + 0.8j], [1.5j]])
    if given == "in full":  # each of the (2, 2) paths with its own zones (2, 2, S)
        zones = z.Zones(*(np.stack([x, x]) for x in (zones.kind, zones.shape, zones.clearance)))
        start, end = np.repeat(start, 2, axis=1), np.repeat(end, 2, axis=1)
    value = path_clearance(zones, start, end)
    assert value.shape == (2, 2, 2)
    assert value.tolist() == [[pytest.approx(p) for p in row] for row in SPREAD]


def test_a_robot_at_rest_in_halt_stays_at_rest() -> None:
    # Speed 0 is not over a limit of 0: no 0 / 0 scale.
    assert cap_speed(np.array([[0.0, 0.0]]), np.array([0.0])).tolist() == [[0.0, 0.0]]


def test_row_rules_give_each_row_its_clearances_and_a_float_speed() -> None:
    kind = np.array([[[z.CAPSULE, z.BOX]], [[z.KEEP_IN, z.NONE]]])  # 2 fields of 1 robot
    clearance = np.array([[[0.59, 0.09]], [[0.09, 0.0]]])
    rules = row_rules(z.Zones(kind, np.zeros((2, 1, 2, 4)), clearance), [0, 1])  # HALT, then 1 m/s
    assert rules.zones.clearance.tolist() == [[0.59, 0.09], [0.09, 0.0]]
    assert rules.speed.dtype == np.float64 and rules.speed.tolist() == [0.0, 1.0]


def test_a_float32_velocity_is_capped_in_float64() -> None:
    # (1, 1) m/s at 1 m/s: scaled by 1 / sqrt(2) to 1 / sqrt(2) = 0.70710678118654752 each. Its speed taken
    # in float32 (1.4142135, 1.5e-8 short) would give 0.7071067966.
    out = cap_speed(np.array([[1.0, 1.0]], np.float32), np.array([1.0]))
    assert out[0] == pytest.approx([1 / math.sqrt(2)] * 2, abs=1e-12)


def test_zones_of_one_axis_against_square_paths_broadcast_as_numpy_does() -> None:
    # Two rows of zones (N = 2, one circle each) against a 2 x 2 grid of paths: numpy pairs zone j with
    # path [i, j], so each column of the grid is measured against one circle.
    zones = z.Zones(
        kind=np.array([[z.CAPSULE], [z.CAPSULE]]),
        shape=np.array([[[0.0, 0.0, 0.0, 0.0]], [[10.0, 0.0, 10.0, 0.0]]]),
        clearance=np.array([[1.0], [1.0]]),
    )
    start = np.array([[0.0 + 5j, 10.0 + 5j], [0.0 + 3j, 10.0 + 3j]])
    end = start + 1.0  # short paths 5 m or 3 m above their own column's circle
    got = path_clearance(zones, start, end)
    assert got.shape == (2, 2, 1)
    np.testing.assert_allclose(got[..., 0], [[4.0, 4.0], [2.0, 2.0]])


@pytest.mark.parametrize(
    ("start", "end", "ends", "expected"),
    [
        ((0.5, -1.0), (0.5, 1.0), 0, 0.5),  # across the stadium's axis 0.5 m from its first end
        ((1.5, -1.0), (1.5, 1.0), 0, 0.5),  # ... and from its second
        ((0.5, -1.0), (0.5, 1.0), 2, 1.5),  # the first end closed: round the second, 1.5 m away
        ((0.5, -1.0), (0.5, 1.0), 1, 0.5),
        ((0.5, -1.0), (1.5, 1.0), 0, 1.0),  # across its middle
        ((0.5, 0.5), (0.5, 1.0), 0, 0.0),  # not across: no depth, whatever the distance
        ((-1.0, 0.0), (3.0, 0.0), 0, 0.0),  # along the axis: no crossing either
    ],
)
def test_a_path_across_a_stadium_is_as_deep_as_its_crossing_from_the_end_round(
    start, end, ends, expected
) -> None:
    assert axis_depth(*start, *end, 0.0, 0.0, 2.0, 0.0, ends) == pytest.approx(expected, abs=1e-12)


def _slots(*slots) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    kind = np.array([s[0] for s in slots], np.int64)
    return kind, np.array([s[1] for s in slots], float), np.array([s[2] for s in slots], float)


@pytest.mark.parametrize(
    ("walls", "expected"),
    [
        ((-1.0, -3.0, 3.0, 3.0), 0),  # room past both ends
        ((-0.59 - PASS - 0.09 - 0.01, -3.0, 3.0, 3.0), 0),  # room past the first end, 0.01 m to spare
        ((-0.6, -3.0, 3.0, 3.0), 2),  # the walls 0.6 m behind the first end: only round the second
        ((-1.0, -3.0, 2.6, 3.0), 1),
        ((-0.6, -3.0, 2.6, 3.0), 0),  # neither: the nearer end, as without walls
    ],
)
def test_a_stadium_end_that_the_walls_close_is_not_gone_round(walls, expected) -> None:
    # The points tried lie 0.59 + PASS m beyond each end on the axis; the walls keep centres 0.09 m in.
    kind, shape, clearance = _slots(STADIUM, (z.KEEP_IN, walls, 0.09))
    assert open_ends(kind, shape, clearance, 0) == expected
    assert open_ends(kind, shape, clearance, 1) == 0  # not a capsule
