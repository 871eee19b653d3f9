"""Every foul, with numbers worked by hand from the rules' wording (sections in docs/guide/ssl-game.md).

Division B, robots of radius 0.09 m, blue defends -x (its defense area 3.5 <= -x <= 4.5, |y| <= 1), yellow
+x. Steps of 0.5 s, exact in binary, so "more than 2 s" falls between the fifth step after a command
(2.0 s: not yet) and the sixth (2.5 s: the foul).
"""

from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.game import fouls as fl
from hier_ssl.game import referee as ref
from hier_ssl.world.field import get_field

FIELD = get_field("division_b")
DT = 0.5
Y0, Y1, B0, B1 = 0, 1, 2, 3  # two yellow robots (ids 0, 1), two blue (ids 0, 1)
ROBOTS = ref.lineup(np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1]), FIELD)
# Parked where no zone of any state reaches: 0.6 m apart on y = 2, far from the ball at the centre.
PARKED = np.array([(-0.9, 2.0), (-0.3, 2.0), (0.3, 2.0), (0.9, 2.0)])
NO_CONTACTS = np.zeros((0, 3), int)


def _motion(moves: dict[int, tuple[float, float]] | None = None, vel: dict[int, tuple] | None = None):
    pos, v = PARKED.copy()[None], np.zeros((1, 4, 2))
    for slot, xy in (moves or {}).items():
        pos[0, slot] = xy
    for slot, xy in (vel or {}).items():
        v[0, slot] = xy
    return fl.Motion(pos, v)


def _play(commands: list[int], motion: fl.Motion, keeper=(7, 7), placement=(2.0, 0.0), clocks=None):
    """Steps of DT through ``commands`` with the robots held at ``motion``: each step's report."""
    clocks = clocks or fl.new_clocks(1, 4)
    reports = []
    for command in commands:
        state = ref.referee_state(command, FIELD, keeper=keeper, placement=placement)
        clocks, report = fl.step_fouls(
            clocks, state, ROBOTS, FIELD, motion, motion, np.zeros((1, 2)), NO_CONTACTS, DT
        )
        reports.append(report)
    return reports, clocks


def _kind(reports, kind: int, team: int) -> list[int]:
    return [int(r.by_team[0, team, kind]) for r in reports]


# -- crashing (8.4.2) ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("vel_a", "vel_b", "fault"),
    [
        ((2.0, 0.0), (0.0, 0.0), (True, False)),  # projection 2.0 > 1.5, speeds 2.0 and 0: a's foul
        ((0.0, 0.0), (-2.0, 0.0), (False, True)),  # b runs into a still: b's
        ((1.5, 0.0), (0.0, 0.0), (False, False)),  # projection 1.5 is not "greater than 1.5"
        ((1.4, 0.0), (0.0, 0.0), (False, False)),  # a contact below the crash speed: a collision
        ((1.0, 0.0), (-1.0, 0.0), (True, True)),  # projection 2.0, equal speeds: both robots' foul
        ((0.875, 0.0), (-0.75, 0.0), (True, True)),  # projection 1.625, speeds differ by 0.125 < 0.3: both
        ((1.0, 0.0), (-0.625, 0.0), (True, False)),  # projection 1.625, speeds differ by 0.375: the faster
        ((0.0, 3.0), (0.0, 0.0), (False, False)),  # 3 m/s across the line through the centres: projection 0
        ((1.0, 0.5), (-1.0, -0.5), (True, True)),  # projection |2.0| only; speeds equal
        ((1.0, 0.0), (1.0, 0.0) , (False, False)),  # same velocity: difference 0
    ],
)  # fmt: skip
def test_crash_verdicts_on_a_line_along_x(vel_a, vel_b, fault) -> None:
    # a at the origin, b 0.18 m along +x: the line through the centres is the x axis.
    got = fl.crash_verdicts(np.zeros((1, 2)), np.array([[0.18, 0.0]]), np.array([vel_a]), np.array([vel_b]))
    assert (bool(got[0][0]), bool(got[1][0])) == fault


def test_crash_verdicts_anywhere_on_the_field_and_over_any_leading_axes() -> None:
    # The first case of the table moved to a = (3, -2), b = (3.18, -2): the line is still x. Laid out (2, 3):
    # field 0 holds a's foul, a collision and b's foul; field 1 a drawn crash and two collisions.
    pos_a = np.full((2, 3, 2), (3.0, -2.0))
    vel_a = np.array([[(2.0, 0.0), (1.4, 0.0), (0.0, 0.0)], [(1.0, 0.0), (0.0, 3.0), (1.0, 0.0)]])
    vel_b = np.array([[(0.0, 0.0), (0.0, 0.0), (-2.0, 0.0)], [(-1.0, 0.0), (0.0, 0.0), (1.0, 0.0)]])
    fault_a, fault_b = fl.crash_verdicts(pos_a, pos_a + (0.18, 0.0), vel_a, vel_b)
    assert fault_a.tolist() == [[True, False, False], [True, False, False]]
    assert fault_b.tolist() == [[False, False, True], [True, False, False]]


def test_crash_verdicts_on_a_diagonal_line() -> None:
    # b at 45 degrees: a's 2.0 m/s along x projects to 2 cos 45 = 1.414 (no crash), 2.25 m/s to 1.591.
    pos_b = np.array([[0.1273, 0.1273]] * 2)
    vel_a = np.array([(2.0, 0.0), (2.25, 0.0)])
    fault_a, fault_b = fl.crash_verdicts(np.zeros((2, 2)), pos_b, vel_a, np.zeros((2, 2)))
    assert fault_a.tolist() == [False, True] and fault_b.tolist() == [False, False]


def test_contacts_become_crashes_of_teams_or_collisions() -> None:
    # Y0 at 2.0 m/s hits B0 (still): Y0's foul. Y1 and B1 at 1 m/s head-on: both teams' drawn foul. Y0 and
    # Y1 (one team): a collision, whatever their speeds; so are B0 with B1 and B0 with Y1 (1.0 m/s apart
    # along x, below the crash speed).
    pos = np.array([[(0.0, 0.0), (1.0, 0.0), (0.18, 0.0), (1.18, 0.0)]])
    vel = np.array([[(2.0, 0.0), (1.0, 0.0), (0.0, 0.0), (-1.0, 0.0)]])
    before = fl.Motion(pos, vel)
    contacts = np.array([(0, Y0, B0), (0, Y1, B1), (0, Y0, Y1), (0, B0, B1), (0, B0, Y1)])
    state = ref.referee_state(ref.FORCE_START, FIELD)
    _, report = fl.step_fouls(
        fl.new_clocks(1, 4), state, ROBOTS, FIELD, before, _motion(), np.zeros((1, 2)), contacts, DT
    )
    assert report.by_robot[0, :, fl.CRASH_UNIQUE].tolist() == [1, 0, 0, 0]
    assert report.by_robot[0, :, fl.CRASH_DRAWN].tolist() == [0, 1, 0, 1]
    assert report.by_team[0, :, fl.CRASH_UNIQUE].tolist() == [1, 0]
    assert report.by_team[0, :, fl.CRASH_DRAWN].tolist() == [1, 1]
    assert report.counter.tolist() == [[2, 1]] and report.collisions.tolist() == [3]
    # Counts are integers.
    assert all(a.dtype.kind == "i" for a in report)


def test_no_contacts_as_an_empty_list_and_another_robot_radius() -> None:
    # Blue's free kick, Y0 0.6 m from the ball: with 0.09 m robots its side is 0.51 m away (kept); with
    # 0.11 m robots 0.49 m (too close).
    motion = _motion({Y0: (0.6, 0.0)})
    state = ref.referee_state(ref.DIRECT_FREE_BLUE, FIELD)
    for radius, fouled in ((0.09, 0), (0.11, 1)):
        clocks = fl.new_clocks(1, 4)
        _, r = fl.step_fouls(clocks, state, ROBOTS, FIELD, motion, motion, np.zeros((1, 2)), [], DT, radius)
        assert r.by_team[0, ref.YELLOW, fl.DEFENDER_TOO_CLOSE] == fouled


# -- the own defense area and the walls: once each time a robot enters ------------------------------------


def test_a_robot_entering_its_own_defense_area() -> None:
    # B0's side enters blue's area (edge x = -3.5) with its centre at -3.45 (0.04 m < 0.09 m away).
    clocks = fl.new_clocks(1, 4)
    counts = []
    for x in (-3.0, -3.45, -3.45, -3.0, -3.45):
        state = ref.referee_state(ref.FORCE_START, FIELD, keeper=(7, 7))
        motion = _motion({B0: (x, 0.0)})
        clocks, r = fl.step_fouls(
            clocks, state, ROBOTS, FIELD, motion, motion, np.zeros((1, 2)), NO_CONTACTS, DT
        )
        counts.append(int(r.by_robot[0, B0, fl.OWN_DEFENSE_AREA]))
        assert r.counter.sum() == 0  # Multiple Defenders: "The foul counter is not increased"
    assert counts == [0, 1, 0, 0, 1]


def test_the_keeper_and_ball_placement_may_enter_the_defense_area() -> None:
    inside = _motion({B0: (-4.0, 0.0)})
    reports, _ = _play([ref.FORCE_START], inside, keeper=(7, 0))
    assert _kind(reports, fl.OWN_DEFENSE_AREA, ref.BLUE) == [0]
    reports, _ = _play([ref.BALL_PLACEMENT_BLUE, ref.BALL_PLACEMENT_YELLOW], inside)
    assert _kind(reports, fl.OWN_DEFENSE_AREA, ref.BLUE) == [0, 0]


def test_a_robot_leaving_the_walled_area() -> None:
    # The wall at x = 4.8: a centre at 4.75 has the robot's side 0.04 m beyond it.
    reports, _ = _play([ref.FORCE_START] * 2, _motion({Y0: (4.75, 2.0)}))
    assert _kind(reports, fl.LEFT_FIELD, ref.YELLOW) == [1, 0]
    assert reports[0].by_robot[0, Y0, fl.LEFT_FIELD] == 1 and reports[0].counter.sum() == 0


# -- too close to the opponent defense area (8.4.1) ------------------------------------------------------


@pytest.mark.parametrize("command", [ref.STOP, ref.DIRECT_FREE_YELLOW, ref.DIRECT_FREE_BLUE])
def test_too_close_to_the_opponent_defense_area_after_its_grace(command: int) -> None:
    # Y0 and Y1 with centres at x = -3.3: their sides at -3.39, 0.11 m from blue's area (edge x = -3.5),
    # closer than 0.2 m. The team's foul at 2.5 s, one for the team however many robots; the grace restarts:
    # again at 5.0 s.
    motion = _motion({Y0: (-3.3, 0.0), Y1: (-3.3, 0.6)})
    reports, _ = _play([command] * 11, motion)
    assert _kind(reports, fl.OPPONENT_DEFENSE_AREA, ref.YELLOW) == [0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    assert reports[5].by_robot[0, :, fl.OPPONENT_DEFENSE_AREA].tolist() == [1, 1, 0, 0]
    assert reports[5].counter.tolist() == [[1, 0]]


def test_the_defense_grace_restarts_with_a_new_command_and_running_play_has_none() -> None:
    motion = _motion({Y0: (-3.3, 0.0)})
    reports, _ = _play([ref.STOP] * 4 + [ref.DIRECT_FREE_YELLOW] * 6 + [ref.FORCE_START] * 6, motion)
    assert _kind(reports, fl.OPPONENT_DEFENSE_AREA, ref.YELLOW) == [0] * 9 + [1] + [0] * 6
    assert reports[9].by_robot[0, :, fl.OPPONENT_DEFENSE_AREA].tolist() == [1, 0, 0, 0]  # Y1 kept away


def test_just_outside_the_opponent_defense_distance_is_no_foul() -> None:
    # Centre at -3.2: side at -3.29, 0.21 m from the area's edge at -3.5.
    reports, _ = _play([ref.STOP] * 7, _motion({Y0: (-3.2, 0.0)}))
    assert sum(_kind(reports, fl.OPPONENT_DEFENSE_AREA, ref.YELLOW)) == 0


# -- robot stop speed (8.4.3) ----------------------------------------------------------------------------


def test_stop_speed_after_its_grace_once_per_robot_and_stoppage() -> None:
    # Y0 at 1.6 m/s throughout STOP: its foul at 2.5 s, never again in this stoppage. B0 at exactly 1.5 m/s
    # is not faster than 1.5.
    reports, clocks = _play([ref.STOP] * 12, _motion(vel={Y0: (1.6, 0.0), B0: (0.0, 1.5)}))
    assert _kind(reports, fl.STOP_SPEED_FOUL, ref.YELLOW) == [0] * 5 + [1] + [0] * 6
    assert _kind(reports, fl.STOP_SPEED_FOUL, ref.BLUE) == [0] * 12
    assert reports[5].counter.tolist() == [[1, 0]]
    # HALT and a ball placement keep the stoppage; a free kick ends it, and the next STOP counts afresh.
    fast = _motion(vel={Y0: (1.6, 0.0)})
    reports, clocks = _play([ref.HALT, ref.BALL_PLACEMENT_YELLOW] + [ref.STOP] * 6, fast, clocks=clocks)
    assert sum(_kind(reports, fl.STOP_SPEED_FOUL, ref.YELLOW)) == 0
    reports, _ = _play([ref.DIRECT_FREE_BLUE] + [ref.STOP] * 6, fast, clocks=clocks)
    assert _kind(reports, fl.STOP_SPEED_FOUL, ref.YELLOW) == [0] * 6 + [1]


def test_stop_speed_of_two_robots_of_a_team_counts_the_first_then_the_other_after_two_seconds() -> None:
    # Y0 and Y1 both too fast: Y0 (the first slot) at 2.5 s; Y1 2 s of the team's grace later, not at
    # 4.5 s (2.0 s after) but at 5.0 s.
    reports, _ = _play([ref.STOP] * 12, _motion(vel={Y0: (2.0, 0.0), Y1: (0.0, -2.0)}))
    assert [int(r.by_robot[0, Y0, fl.STOP_SPEED_FOUL]) for r in reports] == [0] * 5 + [1] + [0] * 6
    assert [int(r.by_robot[0, Y1, fl.STOP_SPEED_FOUL]) for r in reports] == [0] * 10 + [1, 0]


def test_no_stop_speed_outside_stop() -> None:
    fast = _motion(vel={Y0: (3.0, 0.0)})
    for command in (ref.FORCE_START, ref.BALL_PLACEMENT_YELLOW, ref.DIRECT_FREE_YELLOW, ref.HALT):
        reports, _ = _play([command] * 7, fast)
        assert sum(_kind(reports, fl.STOP_SPEED_FOUL, ref.YELLOW)) == 0


# -- defender too close to the ball (8.4.3) --------------------------------------------------------------


def test_too_close_to_the_ball_at_the_opponents_free_kick() -> None:
    # Blue's free kick, ball at the centre: Y0 0.5 m from it (side 0.41 m) at once, then again only after
    # the team's 2 s: at 2.5 s. B0 as close is the kicking team's. Y1 0.59 m away keeps the distance.
    motion = _motion({Y0: (0.5, 0.0), B0: (-0.5, 0.0), Y1: (0.0, 0.59)})
    reports, _ = _play([ref.DIRECT_FREE_BLUE] * 7, motion)
    assert _kind(reports, fl.DEFENDER_TOO_CLOSE, ref.YELLOW) == [1, 0, 0, 0, 0, 1, 0]
    assert _kind(reports, fl.DEFENDER_TOO_CLOSE, ref.BLUE) == [0] * 7
    assert reports[0].by_robot[0, :, fl.DEFENDER_TOO_CLOSE].tolist() == [1, 0, 0, 0]
    assert reports[0].counter.tolist() == [[1, 0]]


def test_no_defender_foul_in_stop() -> None:
    # 5.1.1/8.4.3: "During stop, there is no automatic sanction for being too close to the ball."
    reports, _ = _play([ref.STOP] * 3, _motion({Y0: (0.3, 0.0)}))
    assert sum(_kind(reports, fl.DEFENDER_TOO_CLOSE, ref.YELLOW)) == 0


# -- ball placement interference (8.4.3) ----------------------------------------------------------------


def test_placement_interference_over_two_seconds_once_on_the_counter_per_placement() -> None:
    # Blue places the ball from the centre to (2, 0); Y0 beside the segment at (1, 0.3), 0.3 - 0.09 = 0.21 m
    # from it. Its time: 0 at the command, more than 2 s at 2.5 s: an interference; its time restarts and
    # the next comes at 5.0 s, which adds to the placement's time but not to the counter.
    reports, clocks = _play([ref.BALL_PLACEMENT_BLUE] * 11, _motion({Y0: (1.0, 0.3)}))
    assert [int(r.interferences[0, 0]) for r in reports] == [0] * 5 + [1] + [0] * 4 + [1]
    assert _kind(reports, fl.PLACEMENT_INTERFERENCE, ref.YELLOW) == [0] * 5 + [1] + [0] * 4 + [1]
    assert [int(r.counter[0, 0]) for r in reports] == [0] * 5 + [1] + [0] * 5
    # A new placement is a new phase: its first interference counts again.
    reports, _ = _play([ref.STOP] + [ref.BALL_PLACEMENT_BLUE] * 6, _motion({Y0: (1.0, 0.3)}), clocks=clocks)
    assert [int(r.counter[0, 0]) for r in reports] == [0] * 6 + [1]


def test_two_robots_interfering_count_once_every_two_seconds_for_their_team() -> None:
    # Y0 and Y1 in the stadium from the start: both past 2 s at step 5, but only the first (Y0) interferes;
    # the team's next comes 2 s of grace later, at step 10, Y0's again (the lowest slot).
    reports, _ = _play([ref.BALL_PLACEMENT_BLUE] * 11, _motion({Y0: (1.0, 0.3), Y1: (1.2, -0.3)}))
    assert [r.by_robot[0, :2, fl.PLACEMENT_INTERFERENCE].tolist() for r in reports] == (
        [[0, 0]] * 5 + [[1, 0]] + [[0, 0]] * 4 + [[1, 0]]
    )


def test_leaving_the_stadium_restarts_the_robots_time_and_the_placing_team_is_free() -> None:
    inside, outside = _motion({Y0: (1.0, 0.3), B0: (1.0, 0.0)}), _motion({Y0: (1.0, 0.6), B0: (1.0, 0.0)})
    clocks = fl.new_clocks(1, 4)
    interferences = []
    for motion in [inside] * 4 + [outside] + [inside] * 6:
        state = ref.referee_state(ref.BALL_PLACEMENT_BLUE, FIELD, placement=(2.0, 0.0))
        clocks, r = fl.step_fouls(
            clocks, state, ROBOTS, FIELD, motion, motion, np.zeros((1, 2)), NO_CONTACTS, DT
        )
        interferences.append(r.interferences[0].tolist())
    # Inside 0 .. 1.5 s at steps 0-3 (the placement begins at step 0), out at step 4 (its time back to 0),
    # in again from step 5, 0.5 s a step: 2.0 s at step 8, more at step 9. Blue's B0, the placing team's,
    # is never counted.
    assert interferences == [[0, 0]] * 9 + [[1, 0], [0, 0]]


# -- the function is pure -------------------------------------------------------------------------------


def test_step_fouls_writes_nothing_it_is_given() -> None:
    clocks = fl.new_clocks(1, 4)
    copies = {k: v.copy() for k, v in vars(clocks).items()}
    motion = _motion({Y0: (-3.3, 0.0), B0: (-3.45, 0.0)}, vel={Y0: (2.0, 0.0)})
    state = ref.referee_state(ref.STOP, FIELD)
    after, _ = fl.step_fouls(clocks, state, ROBOTS, FIELD, motion, motion, np.zeros((1, 2)), NO_CONTACTS, DT)
    assert all(np.array_equal(getattr(clocks, k), v) for k, v in copies.items())
    assert after.command.tolist() == [ref.STOP] and after.in_own_defense[0, B0]


def test_fields_are_independent() -> None:
    # Field 0 in STOP, field 1 running, the same robot too close to blue's area: only field 0 calls it.
    state = ref.referee_state(np.array([ref.STOP, ref.FORCE_START]), FIELD)
    pos = np.repeat(_motion({Y0: (-3.3, 0.0)}).pos, 2, axis=0)
    motion = fl.Motion(pos, np.zeros_like(pos))
    clocks = fl.new_clocks(2, 4)
    for _ in range(6):
        clocks, r = fl.step_fouls(
            clocks, state, ROBOTS, FIELD, motion, motion, np.zeros((2, 2)), NO_CONTACTS, DT
        )
    assert r.by_team[:, ref.YELLOW, fl.OPPONENT_DEFENSE_AREA].tolist() == [1, 0]


def test_no_defender_too_close_once_the_free_kicks_ball_is_in_play() -> None:
    # Y0 0.3 m from the ball at blue's free kick: too close while the ball lies where it was, not once it
    # is in play (rules 5.4).
    motion = _motion({Y0: (0.3, 0.0)})
    for in_play, fouled in ((False, 1), (True, 0)):
        state = ref.referee_state(ref.DIRECT_FREE_BLUE, FIELD, keeper=(7, 7), in_play=in_play)
        _, r = fl.step_fouls(
            fl.new_clocks(1, 4), state, ROBOTS, FIELD, motion, motion, np.zeros((1, 2)), [], DT
        )
        assert r.by_team[0, ref.YELLOW, fl.DEFENDER_TOO_CLOSE] == fouled
        assert r.by_robot[0, Y0, fl.DEFENDER_TOO_CLOSE] == fouled and r.counter[0, ref.YELLOW] == fouled
