"""The referee's state of N fields as arrays, the teams on them, and the checks of both.

A command is the game controller's ``Referee.Command`` number (``ssl_gc_referee_message.proto``), so that a
referee message maps onto this state one to one. The game played here knows HALT, STOP, the two starts
(NORMAL_START, FORCE_START: the game runs), a free kick and a ball placement for either team; any other
command is refused by name. Teams are indices into the per-team arrays (N, 2): yellow 0, blue 1 (the
protocol's ``Team`` enum numbers them 1 and 2). Robots are the M slots of the world, each with its team
and its vision id.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hier_ssl.world.field import Field

HALT, STOP, NORMAL_START, FORCE_START = 0, 1, 2, 3
DIRECT_FREE_YELLOW, DIRECT_FREE_BLUE = 8, 9
# Deprecated by the game controller, which no longer sends them; the rules (5.3.3) know one free kick, so an
# older controller's indirect free kick is played as one.
INDIRECT_FREE_YELLOW, INDIRECT_FREE_BLUE = 10, 11
BALL_PLACEMENT_YELLOW, BALL_PLACEMENT_BLUE = 16, 17

COMMANDS: dict[int, str] = {
    HALT: "HALT",
    STOP: "STOP",
    NORMAL_START: "NORMAL_START",
    FORCE_START: "FORCE_START",
    DIRECT_FREE_YELLOW: "DIRECT_FREE_YELLOW",
    DIRECT_FREE_BLUE: "DIRECT_FREE_BLUE",
    INDIRECT_FREE_YELLOW: "INDIRECT_FREE_YELLOW",
    INDIRECT_FREE_BLUE: "INDIRECT_FREE_BLUE",
    BALL_PLACEMENT_YELLOW: "BALL_PLACEMENT_YELLOW",
    BALL_PLACEMENT_BLUE: "BALL_PLACEMENT_BLUE",
}
# Commands of the protocol this game does not play yet, named in the error that refuses them.
_NOT_PLAYED = {
    4: "PREPARE_KICKOFF_YELLOW",
    5: "PREPARE_KICKOFF_BLUE",
    6: "PREPARE_PENALTY_YELLOW",
    7: "PREPARE_PENALTY_BLUE",
    12: "TIMEOUT_YELLOW",
    13: "TIMEOUT_BLUE",
    14: "GOAL_YELLOW",
    15: "GOAL_BLUE",
}

YELLOW, BLUE = 0, 1
TEAM_NAMES = ("yellow", "blue")
NO_KEEPER = -1  # rules 4.3.6: a team without a keeper names an id that is not on the field

# Rules 3.1 "Number Of Robots": at most 11 robots a team in Division A, 6 in Division B. Fields that are no
# division (the paper's hardware challenge) have no league limit.
MAX_ROBOTS: dict[str, int] = {"division_a": 11, "division_b": 6}

# Rules 5.4 "Ball In And Out Of Play": after a free kick the game runs again, the defenders' distance to
# the ball no longer owed, once the ball has moved this far from where it lay when the command came, or once
# this long has passed since the command (Division A's teams get less time than Division B's). The game
# controller keeps sending the free kick: each team tells "in play" itself.
IN_PLAY_DISTANCE = 0.05  # m
IN_PLAY_TIME_B = 10.0  # s, Division B (and fields of no division)
IN_PLAY_TIME_A = 5.0  # s, Division A


def check_commands(command: np.ndarray) -> np.ndarray:
    """``command`` as an int array; a ValueError names the first command the game does not play."""
    command = np.asarray(command)
    if command.dtype.kind not in "iu":
        raise ValueError(f"referee commands are the protocol's integers, got {command.dtype} {command!r}")
    unknown = ~np.isin(command, list(COMMANDS))
    if unknown.any():
        value = int(command[unknown][0])
        what = f"{_NOT_PLAYED[value]}, not played here yet" if value in _NOT_PLAYED else "no referee command"
        raise ValueError(f"unknown referee state {value} ({what}); known: {COMMANDS}")
    return command.astype(np.int64)


def is_free_kick(command: np.ndarray) -> np.ndarray:
    """Whether each command is a free kick, for either team (bool, the shape of ``command``)."""
    # Two comparisons, not ``np.isin``: the free kicks are numbered 8-11 in a row, and the game asks this
    # several times a control step (``np.isin`` cost 20-40 us a call).
    command = np.asarray(command)
    return (command >= DIRECT_FREE_YELLOW) & (command <= INDIRECT_FREE_BLUE)


def is_placement(command: np.ndarray) -> np.ndarray:
    """Whether each command is a ball placement, for either team."""
    command = np.asarray(command)  # numbered 16-17 in a row, as the free kicks are
    return (command >= BALL_PLACEMENT_YELLOW) & (command <= BALL_PLACEMENT_BLUE)


def is_running(command: np.ndarray) -> np.ndarray:
    """Whether the game runs: NORMAL_START or FORCE_START (rules 5.3.1, 5.3.4)."""
    return (command == NORMAL_START) | (command == FORCE_START)


def ball_in_play(
    command: np.ndarray,
    since: np.ndarray,
    ball: np.ndarray,
    ball_at_command: np.ndarray,
    division_a: bool | np.ndarray = False,
) -> np.ndarray:
    """(N,) bool: the free kick ``command`` (N,) has put the ball in play (rules 5.4): the ball at ``ball``
    (N, 2) m has moved at least ``IN_PLAY_DISTANCE`` from ``ball_at_command`` (N, 2), or ``since`` (N,) s
    have passed since the command, at least ``IN_PLAY_TIME_A`` in Division A (``division_a``), else
    ``IN_PLAY_TIME_B``. False for every other command: a running game has no restriction to lift, a
    stoppage never ends by the ball."""
    moved = np.linalg.norm(np.asarray(ball, float) - np.asarray(ball_at_command, float), axis=-1)
    limit = np.where(division_a, IN_PLAY_TIME_A, IN_PLAY_TIME_B)
    return is_free_kick(command) & ((moved >= IN_PLAY_DISTANCE) | (np.asarray(since) >= limit))


def favoured_team(command: np.ndarray) -> np.ndarray:
    """The team a free kick or ball placement is for (YELLOW or BLUE), -1 where the command favours none.

    The protocol numbers each such pair yellow first, so the command's parity is the team."""
    return np.where(is_free_kick(command) | is_placement(command), command % 2, -1)


@dataclass(frozen=True)
class RefereeState:
    """What the referee has said on N fields: the command (N,) int, the ball placement position (N, 2) m
    (read during a ball placement), each team's keeper id (N, 2) (``NO_KEEPER`` for none) and whether blue
    defends the goal on positive x (N,) bool (the message's ``blue_team_on_positive_half``), and whether a
    free kick's ball is in play (N,) bool (``ball_in_play``: the kick is then played as the running game,
    its restrictions lifted, though the command stays the free kick).

    Build it with ``referee_state``, which checks it against a field."""

    command: np.ndarray
    placement: np.ndarray
    keeper: np.ndarray
    blue_on_positive_half: np.ndarray
    in_play: np.ndarray

    def fields(self, idx: np.ndarray | list[int]) -> RefereeState:
        """The state of the fields ``idx`` (F,) ints alone (copies)."""
        return RefereeState(
            self.command[idx],
            self.placement[idx],
            self.keeper[idx],
            self.blue_on_positive_half[idx],
            self.in_play[idx],
        )


def referee_state(
    command: np.ndarray | int,
    field: Field,
    *,
    n: int = 1,
    placement: np.ndarray | None = None,
    keeper: np.ndarray | tuple[int, int] = (NO_KEEPER, NO_KEEPER),
    blue_on_positive_half: np.ndarray | bool = False,
    in_play: np.ndarray | bool = False,
) -> RefereeState:
    """The referee's state of ``n`` fields (or as many as ``command`` has), every input broadcast to (N, ...).

    A ValueError names an unknown command, or a ball placement position outside ``field``'s playing area
    (rules 2.1.1: the ball is placed on the field)."""
    command = check_commands(command)
    # N is the longest leading axis among the inputs that have one.
    leading = [np.ndim(a) and np.shape(a)[0] for a in (command, blue_on_positive_half, in_play)]
    leading += [np.ndim(a) == 2 and np.shape(a)[0] for a in (placement, keeper)]
    n = max(n, *leading)
    command = np.broadcast_to(command, (n,)).copy()
    place = np.zeros((n, 2)) if placement is None else np.broadcast_to(np.asarray(placement, float), (n, 2))
    outside = is_placement(command) & (
        (np.abs(place[:, 0]) > field.half_length) | (np.abs(place[:, 1]) > field.half_width)
    )
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise ValueError(
            f"ball placement position ({place[i, 0]:g}, {place[i, 1]:g}) m of field {i} is outside the "
            f"{field.field_length:g} x {field.field_width:g} m playing area of {field.name!r}"
        )
    return RefereeState(
        command=command,
        placement=place.copy(),
        keeper=np.broadcast_to(np.asarray(keeper, np.int64), (n, 2)).copy(),
        blue_on_positive_half=np.broadcast_to(np.asarray(blue_on_positive_half, bool), (n,)).copy(),
        in_play=np.broadcast_to(np.asarray(in_play, bool), (n,)).copy(),
    )


@dataclass(frozen=True)
class Lineup:
    """The M robot slots of a world: each one's team (M,) (YELLOW or BLUE) and vision id (M,).

    Build it with ``lineup``, which checks it."""

    team: np.ndarray
    robot_id: np.ndarray


def lineup(team: np.ndarray, robot_id: np.ndarray, field: Field | None = None) -> Lineup:
    """The checked lineup: teams are YELLOW or BLUE, ids are ids (>= 0, one robot each within a team) and,
    given a division's ``field``, no team has more robots than rules 3.1 allow. A ValueError names the value
    at fault."""
    team, robot_id = np.asarray(team), np.asarray(robot_id)
    if team.shape != robot_id.shape or team.ndim != 1:
        raise ValueError(f"team {team.shape} and robot_id {robot_id.shape} must be one (M,) array each")
    wrong = ~np.isin(team, (YELLOW, BLUE))
    if wrong.any():
        raise ValueError(f"team {int(team[wrong][0])} is neither YELLOW ({YELLOW}) nor BLUE ({BLUE})")
    if (robot_id < 0).any():
        raise ValueError(f"robot id {robot_id[robot_id < 0][0]} is negative")
    for t, name in enumerate(TEAM_NAMES):
        ids = robot_id[team == t]
        if len(np.unique(ids)) < len(ids):
            raise ValueError(f"the {name} team uses a robot id twice: {sorted(ids.tolist())}")
        limit = MAX_ROBOTS.get(field.name) if field is not None else None
        if limit is not None and len(ids) > limit:
            raise ValueError(
                f"the {name} team has {len(ids)} robots; {field.name} allows at most {limit} (rules 3.1)"
            )
    return Lineup(team.astype(np.int64), robot_id.astype(np.int64))


def check_keepers(referee: RefereeState, robots: Lineup) -> None:
    """A ValueError names a keeper id that is no robot of its team (``NO_KEEPER`` is allowed)."""
    for t, name in enumerate(TEAM_NAMES):
        ids = robots.robot_id[robots.team == t]
        keeper = referee.keeper[:, t]
        stray = (keeper != NO_KEEPER) & ~np.isin(keeper, ids)
        if stray.any():
            i = int(np.flatnonzero(stray)[0])
            raise ValueError(
                f"keeper id {keeper[i]} of the {name} team (field {i}) is not on the team; its robot ids: "
                f"{sorted(ids.tolist())} ({NO_KEEPER}: no keeper)"
            )


def is_keeper(referee: RefereeState, robots: Lineup) -> np.ndarray:
    """(N, M) bool: the robot in slot i is its team's keeper on field n."""
    return referee.keeper[:, robots.team] == robots.robot_id


def own_side(referee: RefereeState, robots: Lineup) -> np.ndarray:
    """(N, M) +1 or -1: the sign of x of the goal each robot defends."""
    blue_positive = np.where(referee.blue_on_positive_half[:, None], 1.0, -1.0)
    return np.where(robots.team == BLUE, blue_positive, -blue_positive)
