"""The fouls of a step, as the rules define them: pure functions of arrays over N fields and M robots.

``step_fouls`` reads a step (the robots before and after it, the ball, the contacts that began in it) with the
clocks the rules' grace periods need, and returns the clocks after the step (a new value: nothing is
written in place) with what was committed, by kind: per team (N, 2, K), per robot (N, M, K), and the
increments of each team's foul counter. ``crash_verdicts`` is the crashing rule alone, per contact.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from hier_ssl.game.referee import HALT, STOP, Lineup, RefereeState, is_free_kick, is_placement
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


def _per_team(robot: np.ndarray, robots: Lineup) -> np.ndarray:
    """(N, 2) how many robots of each team have ``robot`` (N, M) set."""
    return np.einsum("nm,mt->nt", robot.astype(np.int64), robots.team_mask.astype(np.int64))


def _first_of_team(robot: np.ndarray, robots: Lineup, team_called: np.ndarray) -> np.ndarray:
    """(N, M) the lowest slot of each team with ``robot`` set, where ``team_called`` (N, 2): rules 8.4.3,
    "If multiple robots commit the same foul within 2 seconds, only the first foul counts"."""
    of_team = robot[:, :, None] & robots.team_mask[None]
    first = np.zeros_like(of_team)
    np.put_along_axis(first, np.argmax(of_team, axis=1)[:, None], True, axis=1)
    return (first & of_team & team_called[:, None, :]).any(axis=-1)


def _team_graced(robot: np.ndarray, robots: Lineup, last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rules 8.4.3's grace of 2 s per team for robots committing a foul ``robot`` (N, M), ``last`` (N, 2) s
    after the team's last: the robots whose foul counts (N, M) and the teams' clocks after them (N, 2)."""
    if not robot.any():  # the usual step: no robot of either team commits this foul
        return np.zeros_like(robot), last
    first = _first_of_team(robot, robots, last > GRACE)
    return first, np.where(_per_team(first, robots) > 0, 0.0, last)


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
    - defender too close to the ball (opponent's free kick) and stop speed: a team's next foul of the kind
      counts only 2 s after its last (8.4.3), and then only its first robot's;
    - placement interference: a robot of the other team in the stadium for more than 2 s, again every 2 s
      of the team's grace while it stays; one interference a placement goes on the foul counter (8.4.3).
    """
    n, m = referee.command.shape[0], robots.team.shape[0]
    command = referee.command
    changed = command != clocks.command
    since = np.where(changed, 0.0, clocks.since + dt)
    broken = violates(forbidden_zones(referee, ball, field, robots, radius), after.pos)
    by_robot = np.zeros((n, m, len(KINDS)), np.int64)
    collisions = np.zeros(n, np.int64)
    _crashes(before, np.asarray(contacts, np.int64).reshape(-1, 3), robots, by_robot, collisions)

    in_own = broken[..., OWN_DEFENSE]
    by_robot[..., OWN_DEFENSE_AREA] = in_own & ~clocks.in_own_defense
    outside = broken[..., BOUNDARY]
    by_robot[..., LEFT_FIELD] = outside & ~clocks.outside

    # 8.4.1: the team's grace starts with the command and again after each of its fouls.
    defense = np.where(changed[:, None], 0.0, clocks.defense + dt)
    too_near = broken[..., OPPONENT_DEFENSE]
    team_near = (_per_team(too_near, robots) > 0) & (defense > GRACE)
    by_robot[..., OPPONENT_DEFENSE_AREA] = too_near & team_near[:, robots.team]
    defense = np.where(team_near, 0.0, defense)

    first_fast, last_speed, called = _stop_speed(clocks, command, since, after.vel, robots, dt)
    by_robot[..., STOP_SPEED_FOUL] = first_fast
    # 8.4.3 Defender Too Close To Ball: the BALL zone of the other team during a free kick.
    close = broken[..., BALL] & is_free_kick(command)[:, None]
    by_robot[..., DEFENDER_TOO_CLOSE], last_close = _team_graced(close, robots, clocks.last_too_close + dt)

    placement, in_placement, last_interference, counted, interferences = _interference(
        clocks, changed, broken[..., BALL] & is_placement(command)[:, None], robots, dt
    )
    by_robot[..., PLACEMENT_INTERFERENCE] = placement

    by_team = np.einsum("nmk,mt->ntk", by_robot, robots.team_mask.astype(np.int64))
    # One foul for the team however many of its robots were too close (8.4.1).
    by_team[..., OPPONENT_DEFENSE_AREA] = team_near
    counter = by_team[..., _COUNTED].sum(axis=-1) + counted
    report = FoulReport(by_team, by_robot, counter, collisions, interferences)
    return replace(
        clocks,
        command=command.copy(),
        since=since,
        defense=defense,
        last_stop_speed=last_speed,
        last_too_close=last_close,
        last_interference=last_interference,
        speed_called=called | first_fast,
        in_placement=in_placement,
        placement_counted=(clocks.placement_counted & ~changed[:, None]) | (counted > 0),
        in_own_defense=in_own,
        outside=outside,
    ), report


def _stop_speed(
    clocks: FoulClocks, command: np.ndarray, since: np.ndarray, vel: np.ndarray, robots: Lineup, dt: float
) -> tuple[np.ndarray, ...]:
    """Rules 8.4.3 "Robot Stop Speed", above 1.5 m/s after 2 s of STOP, once per robot and stoppage: the
    robots whose foul counts (N, M), the teams' time since their last (N, 2), the robots called this
    stoppage before the step (N, M). A stoppage lasts through HALT, STOP and ball placement."""
    stopped = (command == HALT) | (command == STOP) | is_placement(command)
    called = clocks.speed_called & stopped[:, None]
    if not stopped.any():  # the game runs on every field: nobody called, nobody fast
        return called, clocks.last_stop_speed + dt, called.copy()
    fast = (np.linalg.norm(vel, axis=-1) > STOP_SPEED) & ~called
    fast &= ((command == STOP) & (since > GRACE))[:, None]
    first, last = _team_graced(fast, robots, clocks.last_stop_speed + dt)
    return first, last, called


def _interference(
    clocks: FoulClocks, changed: np.ndarray, inside: np.ndarray, robots: Lineup, dt: float
) -> tuple[np.ndarray, ...]:
    """Rules 8.4.3 "Ball Placement Interference" for robots ``inside`` (N, M) the stadium: the robots that
    interfere (N, M), each robot's time in the stadium after the step (N, M), the teams' time since their
    last interference (N, 2), each team's foul-counter increment (N, 2) and its interferences (N, 2). A robot
    that stays in the stadium interferes again once the team's 2 s of grace (8.4.3) have passed."""
    last = clocks.last_interference + dt
    if not inside.any():  # outside a ball placement, every step: nobody in, nothing counted
        nothing = np.zeros(last.shape, np.int64)
        return np.zeros_like(inside), np.zeros(inside.shape), last, nothing, nothing.copy()
    time_in = np.where(inside & ~changed[:, None], clocks.in_placement + dt, 0.0)
    first, last = _team_graced(inside & (time_in > GRACE), robots, last)
    teams = _per_team(first, robots)
    counted_before = clocks.placement_counted & ~changed[:, None]
    counted = (teams > 0) & ~counted_before
    return first, time_in, last, counted.astype(np.int64), teams
