"""What a manager of the SSL game sees of the rules: the columns the game scenarios append to the
"neighbours" observation, and the rules read back from them.

Layout, ``GAME_OBS_DIM`` values after the 13 + 6K of ``hier_ssl.manager.neighbours`` (whose neighbour slots
mark each robot a teammate, 1, or an opponent, 0)::

    0-6     referee: one-hot HALT, STOP, running (NORMAL_START, FORCE_START), our free kick, their free
            kick, our ball placement, their ball placement
    7       speed limit / max_v, 1 where there is none (0 in HALT, 1.5 m/s / max_v in STOP)
    8       the x sign of the goal the robot defends (+1 or -1)
    9-10    ball x, y relative to the robot / max_pos
    11-12   ball vx, vy / max_v
    13-14   ball placement position relative to the robot / max_pos (0 outside a ball placement)
    15+9s   zone slot s (``hier_ssl.game.zones.SLOTS``: boundary, own defense area, opponent's defense
            area, ball): one-hot capsule, box, keep-in (all 0: the rule does not apply now), its shape
            (x0, y0, x1, y1) relative to the robot / (2 max_pos), its clearance / max_pos, the robot's
            signed distance from breaking it / max_pos

Relative values are in the field frame, as the neighbours' are. Positions, velocities and distances are
clipped to [-clip, clip]; a shape / (2 max_pos) never needs it, so ``game_rules`` reads the zones back whole
(to float32's precision, about 1e-6 m). Read the columns through ``GAME_OBS_SLICES`` and
``ZONE_OBS_SLICES``.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from hier_ssl.game.legal import RowRules
from hier_ssl.game.referee import (
    BALL_PLACEMENT_BLUE,
    BALL_PLACEMENT_YELLOW,
    DIRECT_FREE_YELLOW,
    FORCE_START,
    HALT,
    INDIRECT_FREE_BLUE,
    NORMAL_START,
    STOP,
    Lineup,
    RefereeState,
    own_side,
)
from hier_ssl.game.zones import (
    BOX,
    CAPSULE,
    KEEP_IN,
    NONE,
    SLOTS,
    STOP_SPEED,
    Zones,
    speed_limit,
    zone_distance,
)
from hier_ssl.manager.observation import MANAGER_OBS_SLICES
from hier_ssl.manager.scene import Scene, ruled_scene

REFEREE_FLAGS = (
    "halt",
    "stop",
    "running",
    "our_free_kick",
    "their_free_kick",
    "our_placement",
    "their_placement",
)
ZONE_KINDS = (CAPSULE, BOX, KEEP_IN)  # the order of a slot's one-hot
ZONE_OBS_DIM = 9
ZONE_OBS_SLICES: dict[str, slice] = {
    "kind": slice(0, 3),
    "shape": slice(3, 7),
    "clearance": slice(7, 8),
    "distance": slice(8, 9),
}
GAME_OBS_SLICES: dict[str, slice] = {
    "referee": slice(0, 7),
    "speed_limit": slice(7, 8),
    "own_goal_side": slice(8, 9),
    "ball_pos": slice(9, 11),
    "ball_vel": slice(11, 13),
    "placement": slice(13, 15),
    "zones": slice(15, 15 + ZONE_OBS_DIM * len(SLOTS)),
}
GAME_OBS_DIM = GAME_OBS_SLICES["zones"].stop
GAME_ZONES_START = GAME_OBS_SLICES["zones"].start


def referee_flags(referee: RefereeState, robots: Lineup) -> np.ndarray:
    """(N, M, 7) bool: the ``REFEREE_FLAGS`` of each robot's team under the command of each field."""
    out = np.empty((len(referee.command), len(robots.team), len(REFEREE_FLAGS)), bool)
    _referee_flags(referee.command, robots.team, out)
    return out


@numba.njit(cache=True)
def _referee_flags(command: np.ndarray, team: np.ndarray, out: np.ndarray) -> None:
    """Writes ``referee_flags`` (N, M, 7) of the commands (N,) and the robots' teams (M,) into ``out``."""
    for n in range(command.shape[0]):
        for i in range(team.shape[0]):
            _flags(command[n], team[i], out[n, i])


@numba.njit(cache=True)
def _flags(command: int, team: int, out: np.ndarray) -> None:
    """Writes the ``REFEREE_FLAGS`` of a robot of ``team`` under ``command`` into ``out`` (7,), bool or
    float. A free kick or placement is ours where its command's parity is our team (``favoured_team``)."""
    kick = DIRECT_FREE_YELLOW <= command <= INDIRECT_FREE_BLUE
    place = BALL_PLACEMENT_YELLOW <= command <= BALL_PLACEMENT_BLUE
    ours = command % 2 == team
    out[0], out[1] = command == HALT, command == STOP
    out[2] = command == NORMAL_START or command == FORCE_START
    out[3], out[4] = kick and ours, kick and not ours
    out[5], out[6] = place and ours, place and not ours


def game_columns(
    referee: RefereeState,
    robots: Lineup,
    zones: Zones,
    pos: np.ndarray,
    ball_pos: np.ndarray,
    ball_vel: np.ndarray,
    max_pos: float,
    max_v: float,
    clip: float = 1.2,
) -> np.ndarray:
    """The game columns (N, M, ``GAME_OBS_DIM``) float32 of M robots ``robots`` at ``pos`` (N, M, 2) with
    their ``zones`` (``forbidden_zones``, (N, M, S)), the ball at ``ball_pos`` (N, 2) moving at ``ball_vel``
    (N, 2), under ``referee``; the layout of the module docstring."""
    n, m = pos.shape[:2]
    out = np.empty((n, m, GAME_OBS_DIM), np.float32)
    _game_columns(
        referee.command,
        robots.team,
        speed_limit(referee),
        own_side(referee, robots),
        referee.placement,
        ball_pos,
        ball_vel,
        pos,
        (zones.kind, zones.shape, zones.clearance),
        (float(max_pos), float(max_v), float(clip)),
        out,
    )
    return out


# Every column in one compiled loop, not some 40 numpy calls a control step. Each value is the numpy
# expression the layout describes, in float64, rounded to float32 once on writing, as the numpy code this
# replaced did (its columns and these were byte for byte equal over 300 random referee states, and the game
# scenarios' seeded episodes kept their observations bit for bit).
@numba.njit(cache=True)
def _game_columns(
    command: np.ndarray,
    team: np.ndarray,
    limit: np.ndarray,
    side: np.ndarray,
    placement: np.ndarray,
    ball_pos: np.ndarray,
    ball_vel: np.ndarray,
    pos: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray],
    scales: tuple[float, float, float],
    out: np.ndarray,
) -> None:
    """Writes ``out`` (N, M, ``GAME_OBS_DIM``): the commands (N,), the teams (M,), ``speed_limit`` (N,),
    ``own_side`` (N, M), the placement positions, the ball's and the robots' positions and velocities, the
    zones' kind, shape and clearance (N, M, S), and (max_pos, max_v, clip)."""
    kind, shape, clearance = zones
    max_pos, max_v, clip = scales
    first, two = GAME_ZONES_START, 2 * max_pos
    for n in range(kind.shape[0]):
        c = command[n]
        placing = 1.0 if BALL_PLACEMENT_YELLOW <= c <= BALL_PLACEMENT_BLUE else 0.0
        speed = min(limit[n], max_v) / max_v
        vx = min(max(ball_vel[n, 0] / max_v, -clip), clip)
        vy = min(max(ball_vel[n, 1] / max_v, -clip), clip)
        for i in range(kind.shape[1]):
            x, y = pos[n, i, 0], pos[n, i, 1]
            row = out[n, i]
            _flags(c, team[i], row)
            row[7], row[8] = speed, side[n, i]
            row[9] = min(max((ball_pos[n, 0] - x) / max_pos, -clip), clip)
            row[10] = min(max((ball_pos[n, 1] - y) / max_pos, -clip), clip)
            row[11], row[12] = vx, vy
            row[13] = min(max((placement[n, 0] - x) / max_pos, -clip), clip) * placing
            row[14] = min(max((placement[n, 1] - y) / max_pos, -clip), clip) * placing
            for slot in range(kind.shape[2]):
                k, col = kind[n, i, slot], first + slot * ZONE_OBS_DIM
                present = 1.0 if k != NONE else 0.0
                for j in range(len(ZONE_KINDS)):
                    row[col + j] = 1.0 if k == ZONE_KINDS[j] else 0.0
                for j in range(4):
                    row[col + 3 + j] = (shape[n, i, slot, j] - (x if j % 2 == 0 else y)) / two * present
                row[col + 7] = clearance[n, i, slot] / max_pos * present
                away = zone_distance(x, y, k, shape[n, i, slot], clearance[n, i, slot]) if present else 0.0
                row[col + 8] = min(max(away / max_pos, -clip), clip)


def game_rules(columns: np.ndarray, robot_pos: np.ndarray, max_pos: float) -> RowRules:
    """The rules B robots read from their game columns (B, ``GAME_OBS_DIM``), the robots at ``robot_pos``
    (B, 2) m: their zones (B, S) and speed limits (B,) as a planner takes them (``RowRules``)."""
    b, s = len(columns), GAME_OBS_SLICES
    slots = columns[:, s["zones"]].reshape(b, len(SLOTS), ZONE_OBS_DIM).astype(np.float64)
    z = ZONE_OBS_SLICES
    one_hot = slots[..., z["kind"]]
    kind = np.where(one_hot.any(axis=-1), np.array(ZONE_KINDS)[one_hot.argmax(axis=-1)], NONE)
    shape = slots[..., z["shape"]] * (2 * max_pos) + np.tile(robot_pos, 2)[:, None]
    clearance = slots[..., z["clearance"]][..., 0] * max_pos
    # The limit from the referee's one-hot, not from column 7: that one is capped at max_v and float32,
    # so a robot no faster than STOP's limit would read "no limit", and 1.5 m/s would come back above it.
    halt, stop = (columns[:, s["referee"]][:, k] > 0.5 for k in (0, 1))
    speed = np.where(halt, 0.0, np.where(stop, STOP_SPEED, np.inf))
    return RowRules(Zones(kind, shape, clearance), speed)


def robot_position(obs: np.ndarray, max_pos: float) -> np.ndarray:
    """(B, 2) m: the robots' own positions read from their manager observations (B, O)."""
    return obs[:, MANAGER_OBS_SLICES["robot_pos"]].astype(np.float64) * max_pos


class RuledPlanner:
    """A scripted planner (``hier_ssl.manager.planners``) playing a game scenario: it reads each robot's
    rules from the game columns of its observation (``game_rules``) and plans on the rest, the "neighbours"
    layout, under them. Observations are normalised by ``max_pos`` m and ``max_v`` m/s; ``forget`` and
    every other attribute are the planner's."""

    def __init__(self, planner: Any, max_pos: float, max_v: float) -> None:
        self.planner, self.max_pos, self.max_v = planner, max_pos, max_v

    def __getattr__(self, name: str) -> Any:
        return getattr(self.planner, name)

    def rules(self, obs: np.ndarray) -> tuple[np.ndarray, RowRules]:
        """Observations (B, O) split into the "neighbours" layout the planner reads (B, O - ``GAME_OBS_DIM``)
        and the rules of their robots."""
        base, columns = obs[:, :-GAME_OBS_DIM], obs[:, -GAME_OBS_DIM:]
        return base, game_rules(columns, robot_position(obs, self.max_pos), self.max_pos)

    def read_ruled(self, obs: np.ndarray) -> tuple[Scene, RowRules]:
        """The scene the planner ranks its candidates in for observations (B, O), its target where the rules
        let the robot go (``ruled_scene``, as ``plan`` moves it), and the rules it ranks them under."""
        base, rules = self.rules(obs)
        return ruled_scene(self.planner.read(base), rules, self.planner.zone_margin), rules

    def __call__(self, obs: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Actions (B, A) for observations (B, O) (of the robots ``rows``, for a planner that remembers)."""
        base, rules = self.rules(obs)
        if rows is None:
            return self.planner(base, rules=rules)
        return self.planner(base, rows=rows, rules=rules)


def ruled_read(planner: Any, obs: np.ndarray) -> tuple[Scene, RowRules | None]:
    """The scene a ``sampling`` or ``RuledPlanner`` ``planner`` ranks its candidates in for observations
    (B, O), and the rules it ranks them under (None: a planner outside the game)."""
    if isinstance(planner, RuledPlanner):
        return planner.read_ruled(obs)
    return planner.read(obs), None


__all__ = [
    "RuledPlanner",
    "GAME_OBS_DIM",
    "GAME_OBS_SLICES",
    "REFEREE_FLAGS",
    "ZONE_OBS_DIM",
    "ZONE_OBS_SLICES",
    "game_columns",
    "game_rules",
    "referee_flags",
    "robot_position",
    "ruled_read",
]
