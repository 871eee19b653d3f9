"""Where each robot may not be, and how fast it may go, as the referee's state has it: pure functions of
arrays over N fields and M robots.

A zone is a shape the robot's centre must keep a clearance from: the rules measure distances "from its
nearest side ... with an assumed radius of 0.09 m" (rules 2.1.3), so each clearance is the rule's distance
plus that radius. Every robot has one slot per rule (``SLOTS``), empty where its rule does not apply, so a
planner can treat the zones as obstacles of fixed count. Shapes are:

- ``CAPSULE``: the segment (x0, y0) -> (x1, y1) (a circle where they coincide); the clearance makes it a
  stadium.
- ``BOX``: the axis-aligned rectangle (xmin, ymin, xmax, ymax); the clearance inflates it.
- ``KEEP_IN``: the same rectangle, but the robot must stay inside it, the clearance away from its edges.

Lines count at their centres: the rules give the field's dimensions between line centres (2.1.1) and so
do these shapes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from hier_ssl.game.referee import (
    BALL_PLACEMENT_BLUE,
    BALL_PLACEMENT_YELLOW,
    BLUE,
    DIRECT_FREE_YELLOW,
    HALT,
    INDIRECT_FREE_BLUE,
    STOP,
    Lineup,
    RefereeState,
)
from hier_ssl.world.field import Field

ROBOT_RADIUS = 0.09  # m, rules 2.1.3 "Field Markings": the radius distances from a robot are measured with
STOP_SPEED = 1.5  # m/s, rules 5.1.1 "Stop"
BALL_DISTANCE = 0.5  # m, rules 5.1.1 "Stop" and 5.3.3 "Free Kick" (the defending team)
DEFENSE_AREA_DISTANCE = 0.2  # m, rules 8.4.1 "Robot Too Close To Opponent Defense Area"
PLACEMENT_DISTANCE = 0.5  # m, rules 8.4.3 "Ball Placement Interference"

NONE, CAPSULE, BOX, KEEP_IN = 0, 1, 2, 3
# One slot per rule: the walled area (2.1.2), the own defense area (8.4.1 "Multiple Defenders"), the
# opponent's defense area (8.4.1), the ball or the ball placement's stadium (5.1.1, 5.3.3, 8.4.3).
BOUNDARY, OWN_DEFENSE, OPPONENT_DEFENSE, BALL = 0, 1, 2, 3
SLOTS = ("boundary", "own_defense", "opponent_defense", "ball")


@dataclass(frozen=True)
class Zones:
    """The forbidden shapes of M robots on N fields, ``len(SLOTS)`` slots each: ``kind`` (N, M, S) int
    (``NONE``, ``CAPSULE``, ``BOX``, ``KEEP_IN``), ``shape`` (N, M, S, 4) m (a capsule's two ends, a box's
    corners) and ``clearance`` (N, M, S) m, what the robot's centre must keep from the shape."""

    kind: np.ndarray
    shape: np.ndarray
    clearance: np.ndarray

    def take(self, index: object) -> Zones:
        """The zones of the robots ``index`` picks on the leading axes (any numpy index: rows, a mask,
        ``np.s_[:, None]`` for an axis more), every slot kept."""
        return Zones(self.kind[index], self.shape[index], self.clearance[index])


def defense_box(field: Field, side: np.ndarray) -> np.ndarray:
    """(..., 4) the defense area in front of the goal at x sign ``side`` (...): rules 2.1.3 "Defense Area",
    a rectangle touching the goal line, ``penalty_area_width`` along it and ``penalty_area_depth`` deep."""
    goal_line = side * field.half_length
    inner = side * (field.half_length - field.penalty_area_depth)
    half = field.penalty_area_width / 2
    return np.stack(
        np.broadcast_arrays(np.minimum(goal_line, inner), -half, np.maximum(goal_line, inner), half), axis=-1
    )


def forbidden_zones(
    referee: RefereeState, ball: np.ndarray, field: Field, robots: Lineup, radius: float = ROBOT_RADIUS
) -> Zones:
    """Each robot's forbidden zones under ``referee``'s command, the ball at ``ball`` (N, 2) m.

    - always: the walled area (the field and its margins, rules 2.1.2), which the robot may not leave;
    - every robot but its keeper, except during a ball placement (rules 5.2 allows entering the defense area
      then): its own defense area ("Multiple Defenders": fully outside);
    - STOP and free kicks: 0.2 m from the opponent's defense area (8.4.1), for every robot;
    - STOP: 0.5 m from the ball (5.1.1), every robot; a free kick: 0.5 m from the ball for the other team
      (5.3.3); a ball placement: 0.5 m from the segment ball -> placement position for the other team
      (8.4.3, a stadium).

    HALT forbids motion (``speed_limit``), not places. A free kick's zones hold until the ball is in play
    (rules 5.4, ``referee.in_play``): from then on the kick is the running game's, as FORCE_START's, though
    the game controller still sends it.
    """
    n, m = referee.command.shape[0], robots.team.shape[0]
    kind = np.empty((n, m, len(SLOTS)), np.int64)
    shape = np.empty((n, m, len(SLOTS), 4))
    clearance = np.empty((n, m, len(SLOTS)))
    _fill_zones(
        referee.command,
        referee.placement,
        referee.keeper,
        referee.blue_on_positive_half,
        referee.in_play,
        np.ascontiguousarray(ball, np.float64),
        robots.team,
        robots.robot_id,
        field.wall_half_extent,
        (field.half_length, field.penalty_area_depth, field.penalty_area_width / 2),
        radius,
        kind,
        shape,
        clearance,
    )
    return Zones(kind, shape, clearance)


# One compiled loop over fields and robots, not some 60 numpy calls: the game reads the zones two or three
# times a control step. Each value is the same expression as ``defense_box``'s, ``own_side``'s,
# ``is_keeper``'s and ``favoured_team``'s, so the zones are bit for bit theirs (held equal by
# tests/game/test_zones.py).
@numba.njit(cache=True)
def _fill_zones(
    command: np.ndarray,
    placement: np.ndarray,
    keeper: np.ndarray,
    blue_positive: np.ndarray,
    in_play: np.ndarray,
    ball: np.ndarray,
    team: np.ndarray,
    robot_id: np.ndarray,
    wall: tuple[float, float],
    defense: tuple[float, float, float],
    radius: float,
    kind: np.ndarray,
    shape: np.ndarray,
    clearance: np.ndarray,
) -> None:
    """Writes ``forbidden_zones``'s ``kind``, ``shape`` and ``clearance`` (N, M, S) of the referee's
    arrays (N, ...) (``in_play``: the free kicks whose ball is in play), the ball (N, 2) and the lineup's
    ``team`` and ``robot_id`` (M,); ``wall``: the walled area's half extent, ``defense``: (half length,
    defense area depth, half its width) m."""
    hx, hy = wall
    half_length, depth, half = defense
    for n in range(command.shape[0]):
        c = command[n]
        # A free kick whose ball is in play restricts no more than the running game (rules 5.4).
        free_kick = DIRECT_FREE_YELLOW <= c <= INDIRECT_FREE_BLUE and not in_play[n]
        placing = BALL_PLACEMENT_YELLOW <= c <= BALL_PLACEMENT_BLUE
        favoured = c % 2 if free_kick or placing else -1
        blue_side = 1.0 if blue_positive[n] else -1.0
        end_x, end_y = (placement[n, 0], placement[n, 1]) if placing else (ball[n, 0], ball[n, 1])
        for i in range(team.shape[0]):
            kind[n, i, BOUNDARY] = KEEP_IN
            shape[n, i, BOUNDARY, 0], shape[n, i, BOUNDARY, 1] = -hx, -hy
            shape[n, i, BOUNDARY, 2], shape[n, i, BOUNDARY, 3] = hx, hy
            clearance[n, i, BOUNDARY] = radius
            side = blue_side if team[i] == BLUE else -blue_side
            own = keeper[n, team[i]] != robot_id[i] and not placing
            kind[n, i, OWN_DEFENSE] = BOX if own else NONE
            _defense_box(side, half_length, depth, half, shape[n, i, OWN_DEFENSE])
            clearance[n, i, OWN_DEFENSE] = radius
            kind[n, i, OPPONENT_DEFENSE] = BOX if c == STOP or free_kick else NONE
            _defense_box(-side, half_length, depth, half, shape[n, i, OPPONENT_DEFENSE])
            clearance[n, i, OPPONENT_DEFENSE] = DEFENSE_AREA_DISTANCE + radius
            keep_off = c == STOP or ((free_kick or placing) and team[i] != favoured)
            kind[n, i, BALL] = CAPSULE if keep_off else NONE
            shape[n, i, BALL, 0], shape[n, i, BALL, 1] = ball[n, 0], ball[n, 1]
            shape[n, i, BALL, 2], shape[n, i, BALL, 3] = end_x, end_y
            clearance[n, i, BALL] = (PLACEMENT_DISTANCE if placing else BALL_DISTANCE) + radius


@numba.njit(cache=True)
def _defense_box(side: float, half_length: float, depth: float, half: float, out: np.ndarray) -> None:
    """``defense_box`` of one goal, x sign ``side``, written into ``out`` (4,)."""
    goal_line, inner = side * half_length, side * (half_length - depth)
    out[0], out[1], out[2], out[3] = min(goal_line, inner), -half, max(goal_line, inner), half


def speed_limit(referee: RefereeState) -> np.ndarray:
    """(N,) the fastest a robot may move, m/s: 0 in HALT (rules 5.1.2), 1.5 in STOP (5.1.1), unlimited
    otherwise (the STOP limit does not apply to ball placement, 8.4.3 "Robot Stop Speed")."""
    command = referee.command
    return np.where(command == HALT, 0.0, np.where(command == STOP, STOP_SPEED, np.inf))


@numba.njit(cache=True)
def point_segment(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    """Distance of the point p from the segment a -> b; a point segment is a point. Lengths here are
    sqrt(x^2 + y^2), as ``np.linalg.norm`` computes them."""
    ux, uy, wx, wy = bx - ax, by - ay, px - ax, py - ay
    length2 = ux * ux + uy * uy
    t = 0.0 if length2 <= 0.0 else min(max((wx * ux + wy * uy) / length2, 0.0), 1.0)
    dx, dy = wx - t * ux, wy - t * uy
    return math.sqrt(dx * dx + dy * dy)


@numba.njit(cache=True)
def zone_distance(x: float, y: float, kind: int, shape: np.ndarray, clearance: float) -> float:
    """How far the point (x, y) is from breaking one zone (``kind``, its ``shape`` (4,), ``clearance``):
    positive while it keeps the clearance, +inf for an empty slot."""
    x0, y0, x1, y1 = shape[0], shape[1], shape[2], shape[3]
    if kind == CAPSULE:
        return point_segment(x, y, x0, y0, x1, y1) - clearance
    if kind == BOX or kind == KEEP_IN:
        qx = abs(x - (x0 + x1) / 2) - (x1 - x0) / 2
        qy = abs(y - (y0 + y1) / 2) - (y1 - y0) / 2
        ox, oy = max(qx, 0.0), max(qy, 0.0)
        box = math.sqrt(ox * ox + oy * oy) + min(max(qx, qy), 0.0)
        return (box if kind == BOX else -box) - clearance
    return math.inf


@numba.njit(cache=True)
def _distances(points: np.ndarray, kind: np.ndarray, shape: np.ndarray, clearance: np.ndarray) -> np.ndarray:
    """(P, S) ``zone_distance`` of points (P, 2) from their zones (P, S)."""
    out = np.empty(kind.shape)
    for i in range(kind.shape[0]):
        for k in range(kind.shape[1]):
            out[i, k] = zone_distance(points[i, 0], points[i, 1], kind[i, k], shape[i, k], clearance[i, k])
    return out


def signed_distance(zones: Zones, points: np.ndarray) -> np.ndarray:
    """(N, M, S) how far each robot centre ``points`` (N, M, 2) is from breaking each of its zones, m:
    positive while it keeps the clearance, negative by how much it breaks it, +inf for an empty slot."""
    lead, s = zones.kind.shape[:-1], zones.kind.shape[-1]
    flat = int(np.prod(lead, dtype=np.int64))
    if np.shape(points) != lead + (2,):  # broadcast only where needed: the game calls this every step
        points = np.broadcast_to(points, lead + (2,))
    out = _distances(
        np.ascontiguousarray(points, np.float64).reshape(flat, 2),
        np.ascontiguousarray(zones.kind, np.int64).reshape(flat, s),
        np.ascontiguousarray(zones.shape, np.float64).reshape(flat, s, 4),
        np.ascontiguousarray(zones.clearance, np.float64).reshape(flat, s),
    )
    return out.reshape(lead + (s,))


def violates(zones: Zones, points: np.ndarray) -> np.ndarray:
    """(N, M, S) bool: the robot breaks the zone. A robot exactly at the clearance keeps it ("at least")."""
    return signed_distance(zones, points) < 0.0
