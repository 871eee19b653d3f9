"""The fouls of a step, as the rules define them: pure functions of arrays over N fields and M robots.

``step_fouls`` reads a step (the robots before and after it, the ball, the contacts that began in it) with the
clocks the rules' grace periods need, and returns the clocks after the step (a new value: nothing is
written in place) with what was committed, by kind: per team (N, 2, K), per robot (N, M, K), and the
increments of each team's foul counter. ``crash_verdicts`` is the crashing rule alone, per contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from hier_ssl.game.referee import (
    BALL_PLACEMENT_BLUE,
    BALL_PLACEMENT_YELLOW,
    DIRECT_FREE_YELLOW,
    HALT,
    INDIRECT_FREE_BLUE,
    STOP,
    Lineup,
    RefereeState,
)
from hier_ssl.game.zones import (
    BALL,
    BOUNDARY,
    OPPONENT_DEFENSE,
    OWN_DEFENSE,
    ROBOT_RADIUS,
    STOP_SPEED,  # rules 5.1.1's limit is the one 8.4.3 "Robot Stop Speed" calls a foul above
    forbidden_zones,
    violates,
)
from hier_ssl.world.field import Field

CRASH_SPEED = 1.5  # m/s, rules 8.4.2 "Crashing": the projected speed difference above which it is a crash
CRASH_DRAWN_SPEED = 0.3  # m/s, rules 8.4.2: a crash with speeds this close is both robots' foul
GRACE = 2.0  # s, rules 8.4.1 and 8.4.3: every grace period of the fouls played here

KINDS = (
    "crash_unique",  # 8.4.2 Crashing, the faster robot's
    "crash_drawn",  # 8.4.2 Crashing, both robots'
    "own_defense_area",  # 8.4.1 Multiple Defenders: a robot other than the keeper enters its defense area
    "opponent_defense_area",  # 8.4.1 Robot Too Close To Opponent Defense Area
    "stop_speed",  # 8.4.3 Robot Stop Speed
    "defender_too_close",  # 8.4.3 Defender Too Close To Ball
    "placement_interference",  # 8.4.3 Ball Placement Interference
    "left_field",  # a robot leaves the walled area (2.1.2); no rule of the league, the world's own
)
(CRASH_UNIQUE, CRASH_DRAWN, OWN_DEFENSE_AREA, OPPONENT_DEFENSE_AREA, STOP_SPEED_FOUL, DEFENDER_TOO_CLOSE,
 PLACEMENT_INTERFERENCE, LEFT_FIELD) = range(len(KINDS))  # fmt: skip
# Kinds that raise the foul counter (rules appendix C, "Increments Foul Counter"): not Multiple Defenders
# (8.4.1: "The foul counter is not increased"), not the world's own kind; placement interference once per
# placement (8.4.3), counted apart.
_COUNTED = np.array([CRASH_UNIQUE, CRASH_DRAWN, OPPONENT_DEFENSE_AREA, STOP_SPEED_FOUL, DEFENDER_TOO_CLOSE])


class Motion(NamedTuple):
    """Robot centres ``pos`` (N, M, 2) m and velocities ``vel`` (N, M, 2) m/s at one instant."""

    pos: np.ndarray
    vel: np.ndarray


@dataclass(frozen=True)
class FoulClocks:
    """What the grace periods remember between steps, N fields and M robots (``new_clocks``).

    ``command`` (N,) the command of the last step; ``since`` (N,) s since it was issued; ``defense`` (N, 2)
    s since each team's grace for the opponent's defense area began; ``last_stop_speed``,
    ``last_too_close``, ``last_interference`` (N, 2) s since the team's last foul of that kind;
    ``speed_called`` (N, M) whether the robot's stop-speed foul was called this stoppage; ``in_placement``
    (N, M) s the robot has been in the placement's stadium; ``placement_counted`` (N, 2) whether the team's
    interference foul of this placement went on its counter; ``in_own_defense``, ``outside`` (N, M) where the
    robot was after the last step."""

    command: np.ndarray
    since: np.ndarray
    defense: np.ndarray
    last_stop_speed: np.ndarray
    last_too_close: np.ndarray
    last_interference: np.ndarray
    speed_called: np.ndarray
    in_placement: np.ndarray
    placement_counted: np.ndarray
    in_own_defense: np.ndarray
    outside: np.ndarray


def new_clocks(n: int, m: int) -> FoulClocks:
    """The clocks before the first step: no command seen, no foul ever committed."""
    never = np.full((n, 2), np.inf)
    return FoulClocks(
        command=np.full(n, -1, np.int64),
        since=np.zeros(n),
        defense=np.zeros((n, 2)),
        last_stop_speed=never,
        last_too_close=never.copy(),
        last_interference=never.copy(),
        speed_called=np.zeros((n, m), bool),
        in_placement=np.zeros((n, m)),
        placement_counted=np.zeros((n, 2), bool),
        in_own_defense=np.zeros((n, m), bool),
        outside=np.zeros((n, m), bool),
    )


class FoulReport(NamedTuple):
    """A step's fouls: ``by_team`` (N, 2, K) and ``by_robot`` (N, M, K) counts by kind (``KINDS``),
    ``counter`` (N, 2) the increments of each team's foul counter, ``collisions`` (N,) contacts that were
    no crash (of one team, or below the crash speed), ``interferences`` (N, 2) placement interferences,
    each of which adds 10 s to the placement's time (8.4.3), counted on the foul counter or not."""

    by_team: np.ndarray
    by_robot: np.ndarray
    counter: np.ndarray
    collisions: np.ndarray
    interferences: np.ndarray


def crash_verdicts(
    pos_a: np.ndarray, pos_b: np.ndarray, vel_a: np.ndarray, vel_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rules 8.4.2 "Crashing" for contacts between robots a and b of different teams, positions and
    velocities (..., 2) each: whether a, and whether b, committed the foul (...) bool each.

    The difference of the velocities, projected on the line through the centres: above 1.5 m/s, the faster
    robot's foul; if then their speeds differ by less than 0.3 m/s, both robots'."""
    line = pos_b - pos_a
    line = line / np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), 1e-12)
    crash = np.abs(np.sum((vel_a - vel_b) * line, axis=-1)) > CRASH_SPEED
    speed_a, speed_b = np.linalg.norm(vel_a, axis=-1), np.linalg.norm(vel_b, axis=-1)
    drawn = np.abs(speed_a - speed_b) < CRASH_DRAWN_SPEED
    return crash & (drawn | (speed_a > speed_b)), crash & (drawn | (speed_b > speed_a))


def _crashes(
    before: Motion, contacts: np.ndarray, robots: Lineup, by_robot: np.ndarray, collisions: np.ndarray
) -> None:
    """Adds the crashes among ``contacts`` (C, 3) [field, slot a, slot b] to ``by_robot``, the rest to
    ``collisions``. The moment of collision is the step's start: ``before``."""
    if not len(contacts):
        return
    f, a, b = contacts[:, 0], contacts[:, 1], contacts[:, 2]
    apart = robots.team[a] != robots.team[b]
    fault_a, fault_b = crash_verdicts(before.pos[f, a], before.pos[f, b], before.vel[f, a], before.vel[f, b])
    fault_a, fault_b = fault_a & apart, fault_b & apart
    kind = np.where(fault_a & fault_b, CRASH_DRAWN, CRASH_UNIQUE)
    np.add.at(by_robot, (f[fault_a], a[fault_a], kind[fault_a]), 1)
    np.add.at(by_robot, (f[fault_b], b[fault_b], kind[fault_b]), 1)
    np.add.at(collisions, f[~(fault_a | fault_b)], 1)


def step_fouls(
    clocks: FoulClocks,
    referee: RefereeState,
    robots: Lineup,
    field: Field,
    before: Motion,
    after: Motion,
    ball: np.ndarray,
    contacts: np.ndarray,
    dt: float,
    radius: float = ROBOT_RADIUS,
) -> tuple[FoulClocks, FoulReport]:
    """The fouls of one step of ``dt`` s that ends at ``after`` (the ball at ``ball`` (N, 2)), the contacts
    between robots that began in it ``contacts`` (C, 3) int [field, slot a, slot b], and the clocks after it.

    A grace period is "more than 2 s": a foul is called once a clock passes 2.0 s, not at 2.0 s.
    - own defense area, leaving the walled area: once each time the robot enters the zone;
    - opponent defense area (STOP, free kicks): a team's foul once any of its robots is too close after 2 s
      of grace from the command; the grace restarts after the foul (8.4.1, one foul per team, not robot);
    - stop speed (STOP, after 2 s): above 1.5 m/s, once per robot and stoppage (a stoppage ends when the
      game runs or a free kick is taken);
    - defender too close to the ball (opponent's free kick, until its ball is in play: ``in_play``) and stop
      speed: a team's next foul of the kind
      counts only 2 s after its last (8.4.3), and then only its first robot's;
    - placement interference: a robot of the other team in the stadium for more than 2 s, again every 2 s
      of the team's grace while it stays; one interference a placement goes on the foul counter (8.4.3).
    """
    n, m = referee.command.shape[0], robots.team.shape[0]
    broken = violates(forbidden_zones(referee, ball, field, robots, radius), after.pos)
    by_robot = np.zeros((n, m, len(KINDS)), np.int64)
    collisions = np.zeros(n, np.int64)
    _crashes(before, np.asarray(contacts, np.int64).reshape(-1, 3), robots, by_robot, collisions)
    old = tuple(getattr(clocks, name) for name in _CLOCKS)
    new = tuple(np.empty_like(value) for value in old)
    by_team = np.zeros((n, 2, len(KINDS)), np.int64)
    counter, interferences = np.zeros((n, 2), np.int64), np.zeros((n, 2), np.int64)
    _rule_fouls(
        referee.command,
        referee.in_play,
        old,
        new,
        broken,
        after.vel,
        robots.team,
        dt,
        by_robot,
        by_team,
        counter,
        interferences,
    )
    return FoulClocks(*new), FoulReport(by_team, by_robot, counter, collisions, interferences)


_CLOCKS = tuple(FoulClocks.__dataclass_fields__)  # the clocks in the order ``_rule_fouls`` unpacks them


# One compiled loop over fields and robots in place of a numpy call or more per rule: the game calls the
# fouls every control step. Each field's clocks and fouls depend on that field alone.
@numba.njit(cache=True)
def _rule_fouls(
    command: np.ndarray,
    in_play: np.ndarray,
    old: tuple[np.ndarray, ...],
    new: tuple[np.ndarray, ...],
    broken: np.ndarray,
    vel: np.ndarray,
    team: np.ndarray,
    dt: float,
    by_robot: np.ndarray,
    by_team: np.ndarray,
    counter: np.ndarray,
    interferences: np.ndarray,
) -> None:
    """``step_fouls`` after the crashes, the commands (N,) with ``in_play`` (N,) their free kicks' ball in
    play: writes the clocks ``new`` (``FoulClocks``'s fields, in order) after
    ``old``, every kind but the crashes into ``by_robot`` (N, M, K), and ``by_team`` (N, 2, K), ``counter``
    and ``interferences`` (N, 2), for the zones each robot ``broken`` (N, M, S) and its velocity (N, M, 2)."""
    (last_command, since0, defense0, speed0, close0, interference0, called0, in_placement0, counted0, own0,
     outside0) = old  # fmt: skip
    (command1, since, defense, last_speed, last_close, last_interference, speed_called, in_placement,
     placement_counted, in_own, outside) = new  # fmt: skip
    flags = np.zeros((4, team.shape[0]), np.bool_)  # a field's robots: each row, one rule's
    near, fast, close, inside = flags[0], flags[1], flags[2], flags[3]
    for n in range(command.shape[0]):
        c = command[n]
        changed = c != last_command[n]
        command1[n] = c
        since[n] = 0.0 if changed else since0[n] + dt
        placing = BALL_PLACEMENT_YELLOW <= c <= BALL_PLACEMENT_BLUE
        stopped = c == HALT or c == STOP or placing
        # 8.4.3's defender too close holds until the kick's ball is in play (rules 5.4), then the game runs.
        free_kick = DIRECT_FREE_YELLOW <= c <= INDIRECT_FREE_BLUE and not in_play[n]
        # 8.4.1: the team's grace starts with the command and again after each of its fouls.
        team_near = np.zeros(2, np.bool_)
        for t in range(2):
            defense[n, t] = 0.0 if changed else defense0[n, t] + dt
            last_speed[n, t], last_close[n, t] = speed0[n, t] + dt, close0[n, t] + dt
            last_interference[n, t] = interference0[n, t] + dt
        for i in range(team.shape[0]):
            in_own[n, i], outside[n, i] = broken[n, i, OWN_DEFENSE], broken[n, i, BOUNDARY]
            by_robot[n, i, OWN_DEFENSE_AREA] = in_own[n, i] and not own0[n, i]
            by_robot[n, i, LEFT_FIELD] = outside[n, i] and not outside0[n, i]
            near[i] = broken[n, i, OPPONENT_DEFENSE]
            team_near[team[i]] |= near[i] and defense[n, team[i]] > GRACE
            speed_called[n, i] = called0[n, i] and stopped
            speed = math.sqrt(vel[n, i, 0] * vel[n, i, 0] + vel[n, i, 1] * vel[n, i, 1])
            fast[i] = speed > STOP_SPEED and not speed_called[n, i] and c == STOP and since[n] > GRACE
            close[i] = broken[n, i, BALL] and free_kick
            inside[i] = broken[n, i, BALL] and placing
            in_placement[n, i] = in_placement0[n, i] + dt if inside[i] and not changed else 0.0
            inside[i] &= in_placement[n, i] > GRACE
        for i in range(team.shape[0]):
            by_robot[n, i, OPPONENT_DEFENSE_AREA] = near[i] and team_near[team[i]]
        _first_of_team(fast, team, last_speed[n], by_robot[n, :, STOP_SPEED_FOUL])
        _first_of_team(close, team, last_close[n], by_robot[n, :, DEFENDER_TOO_CLOSE])
        _first_of_team(inside, team, last_interference[n], by_robot[n, :, PLACEMENT_INTERFERENCE])
        for i in range(team.shape[0]):
            speed_called[n, i] |= by_robot[n, i, STOP_SPEED_FOUL] > 0
            for k in range(by_robot.shape[2]):
                by_team[n, team[i], k] += by_robot[n, i, k]
        for t in range(2):
            if team_near[t]:
                defense[n, t] = 0.0
            # One foul for the team however many of its robots were too close (8.4.1).
            by_team[n, t, OPPONENT_DEFENSE_AREA] = team_near[t]
            interferences[n, t] = by_team[n, t, PLACEMENT_INTERFERENCE]
            before = counted0[n, t] and not changed
            counted = interferences[n, t] > 0 and not before
            placement_counted[n, t] = before or counted
            counter[n, t] = counted
            for k in _COUNTED:
                counter[n, t] += by_team[n, t, k]


@numba.njit(cache=True)
def _first_of_team(robot: np.ndarray, team: np.ndarray, last: np.ndarray, out: np.ndarray) -> None:
    """Rules 8.4.3's grace of 2 s per team for robots committing a foul ``robot`` (M,), ``last`` (2,) s after
    the team's last: "if multiple robots commit the same foul within 2 seconds, only the first foul counts".
    Marks the lowest slot of each team past its grace in ``out`` (M,) and restarts its clock in ``last``."""
    for t in range(2):
        if last[t] > GRACE:
            for i in range(team.shape[0]):
                if robot[i] and team[i] == t:
                    out[i], last[t] = 1, 0.0
                    break
