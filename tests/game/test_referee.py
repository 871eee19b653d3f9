"""The referee's state and the teams: the game controller's numbering, and each bad input refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.game import referee as ref
from hier_ssl.world.field import get_field

DIV_A, DIV_B = get_field("division_a"), get_field("division_b")


def test_commands_are_the_game_controllers_numbers() -> None:
    # ssl_gc_referee_message.proto, enum Referee.Command.
    assert (ref.HALT, ref.STOP, ref.NORMAL_START, ref.FORCE_START) == (0, 1, 2, 3)
    assert (ref.DIRECT_FREE_YELLOW, ref.DIRECT_FREE_BLUE) == (8, 9)
    assert (ref.INDIRECT_FREE_YELLOW, ref.INDIRECT_FREE_BLUE) == (10, 11)
    assert (ref.BALL_PLACEMENT_YELLOW, ref.BALL_PLACEMENT_BLUE) == (16, 17)
    assert ref.COMMANDS[16] == "BALL_PLACEMENT_YELLOW" and len(ref.COMMANDS) == 10


def test_what_each_command_is_and_whom_it_favours() -> None:
    command = np.array([0, 1, 2, 3, 8, 9, 10, 11, 16, 17])
    assert ref.favoured_team(command).tolist() == [-1, -1, -1, -1, 0, 1, 0, 1, 0, 1]
    assert ref.is_free_kick(command).tolist() == [False] * 4 + [True] * 4 + [False] * 2
    assert ref.is_placement(command).tolist() == [False] * 8 + [True] * 2
    assert ref.is_running(command).tolist() == [False, False, True, True] + [False] * 6


@pytest.mark.parametrize(
    ("command", "message"),
    [
        (4, r"unknown referee state 4 \(PREPARE_KICKOFF_YELLOW, not played here yet\)"),
        (13, r"unknown referee state 13 \(TIMEOUT_BLUE, not played here yet\)"),
        (99, r"unknown referee state 99 \(no referee command\)"),
        (-1, r"unknown referee state -1 \(no referee command\)"),
    ],
)
def test_an_unknown_referee_state_is_refused_by_its_value(command: int, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ref.referee_state(np.array([ref.STOP, command]), DIV_B)


def test_a_command_that_is_no_integer_is_refused() -> None:
    with pytest.raises(ValueError, match="integers, got float64"):
        ref.check_commands(np.array([1.0]))


@pytest.mark.parametrize("where", [(4.6, 0.0), (-4.51, 1.0), (0.0, 3.01), (0.0, -3.5)])
def test_a_placement_position_outside_the_field_is_refused_by_its_value(where: tuple[float, float]) -> None:
    # Division B's playing area is 9 x 6 m: |x| <= 4.5, |y| <= 3 (rules 2.1.1).
    text = f"ball placement position \\({where[0]:g}, {where[1]:g}\\) m of field 1 is outside the 9 x 6 m"
    with pytest.raises(ValueError, match=text):
        ref.referee_state(
            np.array([ref.STOP, ref.BALL_PLACEMENT_BLUE]), DIV_B, placement=np.array([(0, 0), where])
        )


def test_a_placement_on_the_field_lines_is_on_the_field_and_other_commands_do_not_read_it() -> None:
    state = ref.referee_state(ref.BALL_PLACEMENT_YELLOW, DIV_B, placement=(4.5, -3.0))
    assert state.placement.tolist() == [[4.5, -3.0]]
    assert ref.referee_state(ref.STOP, DIV_B, placement=(9.0, 9.0)).command.tolist() == [1]


def test_the_state_broadcasts_to_n_fields() -> None:
    state = ref.referee_state(ref.STOP, DIV_A, n=3, keeper=(1, 2), blue_on_positive_half=True)
    assert state.command.tolist() == [1, 1, 1] and state.command.dtype == np.int64
    assert state.keeper.tolist() == [[1, 2]] * 3 and state.blue_on_positive_half.tolist() == [True] * 3
    assert state.placement.tolist() == [[0.0, 0.0]] * 3  # none given: the centre, never read


def test_n_is_the_longest_input() -> None:
    state = ref.referee_state(ref.STOP, DIV_A, keeper=np.array([(0, 1), (1, 0), (2, 2)]))
    assert state.command.tolist() == [1, 1, 1] and state.keeper[:, 0].tolist() == [0, 1, 2]
    state = ref.referee_state(ref.BALL_PLACEMENT_BLUE, DIV_A, placement=np.array([(1, 2), (3, 4), (5, -4)]))
    assert state.placement.dtype == float and state.placement[2].tolist() == [5.0, -4.0]
    assert ref.referee_state(ref.STOP, DIV_A, blue_on_positive_half=np.ones(4, bool)).command.shape == (4,)


@pytest.mark.parametrize(("field", "limit"), [(DIV_B, 6), (DIV_A, 11)])
def test_a_team_larger_than_its_division_allows_is_refused(field, limit: int) -> None:
    # Rules 3.1: not more than 11 robots a team in Division A, 6 in Division B.
    ids = np.arange(limit + 1)
    assert len(ref.lineup(np.zeros(limit, int), ids[:limit], field).team) == limit
    with pytest.raises(
        ValueError, match=f"the blue team has {limit + 1} robots; {field.name} allows at most {limit}"
    ):
        ref.lineup(np.ones(limit + 1, int), ids, field)


def test_the_papers_field_is_no_division_and_has_no_limit() -> None:
    assert len(ref.lineup(np.zeros(12, int), np.arange(12), get_field("hardware_challenge")).team) == 12


@pytest.mark.parametrize(
    ("team", "ids", "message"),
    [
        ([0, 2], [0, 1], "team 2 is neither YELLOW"),
        ([0, 1], [0, -3], "robot id -3 is negative"),
        ([1, 1, 0], [4, 4, 4], r"the blue team uses a robot id twice: \[4, 4\]"),
        ([[0, 1]], [[0, 1]], "must be one"),
    ],
)
def test_a_bad_lineup_is_refused_by_its_value(team, ids, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ref.lineup(np.array(team), np.array(ids))


def test_a_keeper_that_is_not_on_the_team_is_refused_by_its_id() -> None:
    robots = ref.lineup(np.array([0, 0, 1, 1]), np.array([0, 3, 0, 5]), DIV_B)
    ref.check_keepers(ref.referee_state(ref.STOP, DIV_B, keeper=(3, 5)), robots)
    ref.check_keepers(ref.referee_state(ref.STOP, DIV_B, keeper=(ref.NO_KEEPER, 0)), robots)
    with pytest.raises(
        ValueError, match=r"keeper id 5 of the yellow team \(field 1\) is not on the team; .*\[0, 3\]"
    ):
        ref.check_keepers(ref.referee_state(ref.STOP, DIV_B, keeper=np.array([(0, 0), (5, 0)])), robots)
    with pytest.raises(ValueError, match=r"keeper id 3 of the blue team \(field 0\)"):
        ref.check_keepers(ref.referee_state(ref.STOP, DIV_B, keeper=(0, 3)), robots)


def test_keepers_and_the_side_each_robot_defends() -> None:
    robots = ref.lineup(np.array([0, 0, 1, 1]), np.array([0, 3, 0, 5]))
    state = ref.referee_state(np.array([1, 1]), DIV_B, keeper=np.array([(3, 0), (0, 5)]),
                              blue_on_positive_half=np.array([True, False]))  # fmt: skip
    assert ref.is_keeper(state, robots).tolist() == [[False, True, True, False], [True, False, False, True]]
    # Blue on positive x in field 0: yellow defends the goal at -x there, and the other way round in field 1.
    assert ref.own_side(state, robots).tolist() == [[-1, -1, 1, 1], [1, 1, -1, -1]]


def test_the_state_holds_integer_keepers_and_boolean_sides() -> None:
    # The message's goalkeeper is a pattern number and blue_team_on_positive_half a flag: whatever the
    # caller's array types, the state keeps them as such.
    state = ref.referee_state(ref.STOP, DIV_B, keeper=np.array([3.0, 5.0]), blue_on_positive_half=1)
    assert state.keeper.dtype == np.int64 and state.keeper.tolist() == [[3, 5]]
    assert state.blue_on_positive_half.dtype == bool and state.blue_on_positive_half.tolist() == [True]


# -- rules 5.4: a free kick's ball in play --------------------------------------------------------------


def test_a_free_kicks_ball_is_in_play_once_it_moved_5_cm() -> None:
    at = np.zeros((3, 2))
    ball = np.array([(0.04, 0.0), (0.0, 0.06), (0.03, 0.04)])  # 0.04, 0.06 and 0.05 m from where it was
    since = np.zeros(3)
    kick = np.full(3, ref.DIRECT_FREE_BLUE)
    assert ref.ball_in_play(kick, since, ball, at).tolist() == [False, True, True]
    indirect = np.full(3, ref.INDIRECT_FREE_YELLOW)
    assert ref.ball_in_play(indirect, since, ball, at).tolist() == [False, True, True]


def test_a_free_kicks_ball_is_in_play_after_10_s_in_division_b_5_s_in_division_a() -> None:
    kick, ball = np.full(4, ref.DIRECT_FREE_YELLOW), np.ones((4, 2))  # a ball that never moved
    since = np.array([4.9, 5.0, 9.9, 10.1])
    assert ref.ball_in_play(kick, since, ball, ball).tolist() == [False, False, False, True]
    assert ref.ball_in_play(kick, since, ball, ball, division_a=True).tolist() == [False, True, True, True]
    per_field = np.array([True, False, True, False])
    assert ref.ball_in_play(kick, since, ball, ball, per_field).tolist() == [False, False, True, True]


@pytest.mark.parametrize(
    "command",
    [
        ref.HALT,
        ref.STOP,
        ref.NORMAL_START,
        ref.FORCE_START,
        ref.BALL_PLACEMENT_YELLOW,
        ref.BALL_PLACEMENT_BLUE,
    ],
)
def test_only_a_free_kick_puts_the_ball_in_play(command: int) -> None:
    moved = ref.ball_in_play(np.array([command]), np.array([60.0]), np.array([(1.0, 0.0)]), np.zeros((1, 2)))
    assert moved.tolist() == [False]


def test_in_play_is_kept_per_field_and_false_unless_given() -> None:
    state = ref.referee_state(ref.DIRECT_FREE_BLUE, DIV_B, n=3)
    assert state.in_play.tolist() == [False] * 3 and state.in_play.dtype == bool
    state = ref.referee_state(ref.DIRECT_FREE_BLUE, DIV_B, in_play=np.array([True, False, True]))
    assert state.command.shape == (3,) and state.fields([2, 1]).in_play.tolist() == [True, False]
