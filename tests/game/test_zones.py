"""Every zone, a robot just inside and just outside it, in each referee state, with distances worked by hand.

Division B throughout: a 9 x 6 m playing area (|x| <= 4.5, |y| <= 3), walls 0.3 m beyond the field lines
(|x| <= 4.8, |y| <= 3.3), defense areas 2 m along the goal line and 1 m deep (4.5 - 1 = 3.5 <= |x| <= 4.5,
|y| <= 1), robots of radius 0.09 m whose distances count from their side (rules 2.1.3). Blue defends -x,
yellow +x (``blue_on_positive_half`` False). A point 0.01 m either side of each edge: signed distance +0.01
(kept) or -0.01 (broken).
"""

from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.game import referee as ref
from hier_ssl.game import zones as z
from hier_ssl.world.field import get_field

FIELD = get_field("division_b")
ALL = list(ref.COMMANDS)
FREE_KICKS = [ref.DIRECT_FREE_YELLOW, ref.DIRECT_FREE_BLUE, ref.INDIRECT_FREE_YELLOW, ref.INDIRECT_FREE_BLUE]
PLACEMENTS = [ref.BALL_PLACEMENT_YELLOW, ref.BALL_PLACEMENT_BLUE]
# Slot 0 a yellow robot (id 0), slot 1 a blue one (id 0); yellow's keeper is id 7, on no slot.
ROBOTS = ref.lineup(np.array([ref.YELLOW, ref.BLUE]), np.array([0, 0]), FIELD)
BALL, PLACE = np.array([0.0, 0.0]), np.array([2.0, 0.0])


def _distance(command: int, points: list[tuple[float, float]], keeper=(7, 7)) -> np.ndarray:
    """(2 robots, slots) signed distances of the yellow robot at points[0] and the blue one at points[1]."""
    state = ref.referee_state(command, FIELD, placement=PLACE, keeper=keeper)
    zones = z.forbidden_zones(state, BALL[None], FIELD, ROBOTS)
    return z.signed_distance(zones, np.array(points, float)[None])[0]


@pytest.mark.parametrize("command", ALL)
@pytest.mark.parametrize(("x", "kept"), [(4.70, True), (4.72, False), (-4.70, True), (-4.72, False)])
def test_the_walls_in_every_state(command: int, x: float, kept: bool) -> None:
    # The wall at |x| = 4.8; a robot's side reaches it with its centre at 4.8 - 0.09 = 4.71.
    away = _distance(command, [(x, 0.0), (0.0, 3.2 if kept else 3.22)])[:, z.BOUNDARY]
    assert away == pytest.approx([0.01, 0.01] if kept else [-0.01, -0.01])


@pytest.mark.parametrize("command", [c for c in ALL if c not in PLACEMENTS])
@pytest.mark.parametrize(("x", "kept"), [(3.40, True), (3.42, False)])
def test_the_own_defense_area_outside_ball_placement(command: int, x: float, kept: bool) -> None:
    # Yellow's area begins at x = 3.5; fully outside means the centre at most 3.5 - 0.09 = 3.41. Blue's
    # mirrored at x = -3.5.
    away = _distance(command, [(x, 0.0), (-x, 0.5)])[:, z.OWN_DEFENSE]
    assert away == pytest.approx([0.01, 0.01] if kept else [-0.01, -0.01])


def test_the_own_defense_area_from_its_corner_and_from_deep_inside() -> None:
    # Centre 0.06 m beyond the corner (3.5, 1) in x and in y: sqrt(2) * 0.06 = 0.0849 < 0.09 m away, so the
    # robot's side overlaps the area by 0.09 - 0.0849 = 0.0051 m. Deep inside, at the area's centre (4, 0):
    # 0.5 m from its inner edge, so -0.5 - 0.09 = -0.59.
    away = _distance(ref.STOP, [(3.44, 1.06), (-4.0, 0.0)])[:, z.OWN_DEFENSE]
    assert away == pytest.approx([np.hypot(0.06, 0.06) - 0.09, -0.59])


@pytest.mark.parametrize("command", PLACEMENTS)
def test_ball_placement_lets_robots_into_the_defense_areas(command: int) -> None:
    # Rules 5.2: "It is allowed to enter the defense area during ball placement."
    away = _distance(command, [(4.0, 0.0), (-4.0, 0.0)])
    assert np.isinf(away[:, z.OWN_DEFENSE]).all() and np.isinf(away[:, z.OPPONENT_DEFENSE]).all()


def test_the_keeper_may_be_in_its_defense_area() -> None:
    away = _distance(ref.FORCE_START, [(4.0, 0.0), (-4.0, 0.0)], keeper=(0, 7))[:, z.OWN_DEFENSE]
    assert away[0] == np.inf and away[1] == pytest.approx(-0.59)


@pytest.mark.parametrize("command", [ref.STOP, *FREE_KICKS])
@pytest.mark.parametrize(("x", "kept"), [(3.20, True), (3.22, False)])
def test_the_opponent_defense_area_in_stop_and_free_kicks(command: int, x: float, kept: bool) -> None:
    # 0.2 m from the opponent's area (8.4.1), measured from the side: yellow's opponent area (blue's) ends at
    # x = -3.5, so the centre at least 3.5 - 0.2 - 0.09 = 3.21 from the middle. For every robot, kicker too.
    away = _distance(command, [(-x, 0.0), (x, 0.0)])[:, z.OPPONENT_DEFENSE]
    assert away == pytest.approx([0.01, 0.01] if kept else [-0.01, -0.01])


@pytest.mark.parametrize("command", [ref.HALT, ref.NORMAL_START, ref.FORCE_START, *PLACEMENTS])
def test_no_opponent_defense_zone_outside_stop_and_free_kicks(command: int) -> None:
    assert np.isinf(_distance(command, [(-3.3, 0.0), (3.3, 0.0)])[:, z.OPPONENT_DEFENSE]).all()


@pytest.mark.parametrize(("x", "kept"), [(0.60, True), (0.58, False)])
def test_the_ball_in_stop_for_both_teams(x: float, kept: bool) -> None:
    # 0.5 m from the ball (5.1.1) from the side: the centre at least 0.59 m from the ball's centre.
    away = _distance(ref.STOP, [(x, 0.0), (0.0, -x)])[:, z.BALL]
    assert away == pytest.approx([0.01, 0.01] if kept else [-0.01, -0.01])


@pytest.mark.parametrize(("command", "defender"), [(ref.DIRECT_FREE_BLUE, 0), (ref.DIRECT_FREE_YELLOW, 1)])
@pytest.mark.parametrize(("x", "kept"), [(0.60, True), (0.58, False)])
def test_the_ball_at_a_free_kick_for_the_defending_team_only(
    command: int, defender: int, x: float, kept
) -> None:
    away = _distance(command, [(x, 0.0), (x, 0.0)])[:, z.BALL]
    assert away[defender] == pytest.approx(0.01 if kept else -0.01)
    assert away[1 - defender] == np.inf  # the kicking team may approach the ball (5.3.3)


@pytest.mark.parametrize(("command", "other"), [(ref.BALL_PLACEMENT_BLUE, 0), (ref.BALL_PLACEMENT_YELLOW, 1)])
@pytest.mark.parametrize(
    ("point", "kept"),
    [
        ((1.0, 0.60), True),  # beside the segment (0, 0) -> (2, 0): 0.60 - 0.5 - 0.09 = +0.01
        ((1.0, -0.58), False),
        ((2.60, 0.0), True),  # beyond the placement position: 2.60 - 2 - 0.59
        ((2.58, 0.0), False),
        ((-0.60, 0.0), True),  # behind the ball
        ((-0.58, 0.0), False),
    ],
)
def test_the_placement_stadium_for_the_other_team_only(command: int, other: int, point, kept: bool) -> None:
    away = _distance(command, [point, point])[:, z.BALL]
    assert away[other] == pytest.approx(0.01 if kept else -0.01)
    assert away[1 - other] == np.inf  # the placing team fetches the ball


@pytest.mark.parametrize("command", [ref.HALT, ref.NORMAL_START, ref.FORCE_START])
def test_no_ball_zone_while_halted_or_running(command: int) -> None:
    assert np.isinf(_distance(command, [(0.1, 0.0), (-0.1, 0.0)])[:, z.BALL]).all()


def test_violates_is_strict_and_fields_are_independent() -> None:
    # Field 0 in STOP, field 1 running: the same robots, 0.59 m from the ball exactly (kept: "at least"),
    # and 0.58 m.
    state = ref.referee_state(np.array([ref.STOP, ref.FORCE_START]), FIELD)
    zones = z.forbidden_zones(state, np.zeros((2, 2)), FIELD, ROBOTS)
    points = np.array([[(0.59, 0.0), (0.58, 0.0)]] * 2)
    assert z.violates(zones, points)[..., z.BALL].tolist() == [[False, True], [False, False]]
    assert (
        zones.kind[..., z.BALL].tolist() == [[z.CAPSULE] * 2, [z.NONE] * 2] and zones.kind.dtype.kind == "i"
    )


def test_the_ball_zones_away_from_the_centre_and_a_short_placement() -> None:
    # STOP with the ball at (1, -1): a robot at (1.6, -1) is 0.6 - 0.59 = +0.01. Blue places the ball from
    # (-1, 0.5) to (-0.5, 0.5), a 0.5 m segment: a yellow robot at (-0.75, 1.08), beside its middle, is
    # 0.58 - 0.59 = -0.01; one at (-1.3, 0.5), behind the ball, 0.3 - 0.59 = -0.29.
    state = ref.referee_state(np.array([ref.STOP, ref.BALL_PLACEMENT_BLUE]), FIELD, placement=(-0.5, 0.5))
    zones = z.forbidden_zones(state, np.array([(1.0, -1.0), (-1.0, 0.5)]), FIELD, ROBOTS)
    points = np.array([[(1.6, -1.0), (0.0, 0.0)], [(-0.75, 1.08), (-1.3, 0.5)]])
    away = z.signed_distance(zones, points)[..., z.BALL]
    assert away[0, 0] == pytest.approx(0.01) and away[1, 0] == pytest.approx(-0.01)
    zones = z.forbidden_zones(
        state, np.array([(1.0, -1.0), (-1.0, 0.5)]), FIELD, ref.lineup(np.zeros(2, int), np.arange(2))
    )
    assert z.signed_distance(zones, points)[1, 1, z.BALL] == pytest.approx(-0.29)


def test_blue_on_the_positive_half_swaps_the_defense_areas() -> None:
    state = ref.referee_state(ref.STOP, FIELD, keeper=(7, 7), blue_on_positive_half=True)
    zones = z.forbidden_zones(state, BALL[None], FIELD, ROBOTS)
    assert zones.shape[0, :, z.OWN_DEFENSE].tolist() == [[-4.5, -1, -3.5, 1], [3.5, -1, 4.5, 1]]
    assert zones.shape[0, :, z.OPPONENT_DEFENSE].tolist() == [[3.5, -1, 4.5, 1], [-4.5, -1, -3.5, 1]]


def test_division_a_defense_area() -> None:
    # 3.6 m along the goal line, 1.8 m deep: 6 - 1.8 = 4.2 <= x <= 6, |y| <= 1.8.
    assert z.defense_box(get_field("division_a"), np.array(1.0)).tolist() == [4.2, -1.8, 6.0, 1.8]


def test_speed_limits() -> None:
    state = ref.referee_state(np.array(ALL), FIELD, placement=PLACE)
    expected = {ref.HALT: 0.0, ref.STOP: 1.5}  # rules 5.1.2, 5.1.1; none otherwise, ball placement included
    assert z.speed_limit(state).tolist() == [expected.get(c, np.inf) for c in ALL]


def test_the_compiled_zones_agree_with_the_referee_functions() -> None:
    # forbidden_zones is one compiled loop: its slots must be what the referee's own functions say.
    rng = np.random.default_rng(0)
    robots = ref.lineup(np.repeat([ref.YELLOW, ref.BLUE], 6), np.tile(np.arange(6), 2), FIELD)
    n = 64
    state = ref.referee_state(
        rng.choice(ALL, n),
        FIELD,
        placement=rng.uniform(-1.0, 1.0, (n, 2)),
        keeper=rng.integers(-1, 6, (n, 2)),
        blue_on_positive_half=rng.random(n) < 0.5,
    )
    ball = rng.uniform(-4.0, 4.0, (n, 2))
    zones = z.forbidden_zones(state, ball, FIELD, robots)
    side, command = ref.own_side(state, robots), state.command
    assert np.array_equal(zones.shape[..., z.OWN_DEFENSE, :], z.defense_box(FIELD, side))
    assert np.array_equal(zones.shape[..., z.OPPONENT_DEFENSE, :], z.defense_box(FIELD, -side))
    own = ~ref.is_keeper(state, robots) & ~ref.is_placement(command)[:, None]
    assert np.array_equal(zones.kind[..., z.OWN_DEFENSE] == z.BOX, own)
    other = robots.team != ref.favoured_team(command)[:, None]
    either = ref.is_free_kick(command) | ref.is_placement(command)
    keep_off = (command == ref.STOP)[:, None] | (either[:, None] & other)
    assert np.array_equal(zones.kind[..., z.BALL] == z.CAPSULE, keep_off)
    end = np.where(ref.is_placement(command)[:, None], state.placement, ball)
    assert np.array_equal(zones.shape[..., z.BALL, :], np.broadcast_to(np.c_[ball, end][:, None], (n, 12, 4)))


@pytest.mark.parametrize("command", FREE_KICKS)
def test_a_free_kick_whose_ball_is_in_play_keeps_the_running_games_zones(command: int) -> None:
    # Rules 5.4: once the ball is in play no robot owes the ball 0.5 m or the opponent's defense area
    # 0.2 m, as in FORCE_START; its own defense area and the walls stay.
    state = ref.referee_state(
        np.array([command, command, ref.FORCE_START]), FIELD, in_play=[False, True, False]
    )
    zones = z.forbidden_zones(state, np.zeros((3, 2)), FIELD, ROBOTS)
    assert (zones.kind[1] == zones.kind[2]).all() and (zones.kind[0] != zones.kind[2]).any()
    assert (zones.kind[1, :, z.OWN_DEFENSE] == z.BOX).all() and (
        zones.kind[1, :, z.BOUNDARY] == z.KEEP_IN
    ).all()
