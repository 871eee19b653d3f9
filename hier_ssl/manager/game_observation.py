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

import numpy as np

from hier_ssl.game.legal import RowRules
from hier_ssl.game.referee import (
    HALT,
    STOP,
    Lineup,
    RefereeState,
    favoured_team,
    is_free_kick,
    is_placement,
    is_running,
    own_side,
)
from hier_ssl.game.zones import BOX, CAPSULE, KEEP_IN, NONE, SLOTS, Zones, signed_distance, speed_limit
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


def referee_flags(referee: RefereeState, robots: Lineup) -> np.ndarray:
    """(N, M, 7) bool: the ``REFEREE_FLAGS`` of each robot's team under the command of each field."""
    command = referee.command[:, None]
    ours = favoured_team(referee.command)[:, None] == robots.team
    kick, place = is_free_kick(command), is_placement(command)
    flags = (command == HALT, command == STOP, is_running(command), kick & ours, kick & ~ours)
    flags += (place & ours, place & ~ours)
    shape = (len(command), len(robots.team))
    return np.stack([np.broadcast_to(flag, shape) for flag in flags], axis=-1)


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
    s = GAME_OBS_SLICES
    out = np.zeros((n, m, GAME_OBS_DIM), np.float32)
    out[..., s["referee"]] = referee_flags(referee, robots)
    out[..., s["speed_limit"]] = (np.minimum(speed_limit(referee), max_v) / max_v)[:, None, None]
    out[..., s["own_goal_side"]] = own_side(referee, robots)[..., None]
    out[..., s["ball_pos"]] = np.clip((ball_pos[:, None] - pos) / max_pos, -clip, clip)
    out[..., s["ball_vel"]] = np.clip(ball_vel[:, None] / max_v, -clip, clip)
    placing = is_placement(referee.command)[:, None, None]
    out[..., s["placement"]] = np.clip((referee.placement[:, None] - pos) / max_pos, -clip, clip) * placing
    slots = out[..., s["zones"]].reshape(n, m, len(SLOTS), ZONE_OBS_DIM)
    z, present = ZONE_OBS_SLICES, (zones.kind != NONE)[..., None]
    slots[..., z["kind"]] = zones.kind[..., None] == np.array(ZONE_KINDS)
    relative = zones.shape - np.tile(pos, 2)[:, :, None]
    slots[..., z["shape"]] = relative / (2 * max_pos) * present
    slots[..., z["clearance"]] = zones.clearance[..., None] / max_pos * present
    away = np.where(present[..., 0], signed_distance(zones, pos), 0.0)
    slots[..., z["distance"]] = np.clip(away / max_pos, -clip, clip)[..., None]
    out[..., s["zones"]] = slots.reshape(n, m, -1)
    return out


def game_rules(columns: np.ndarray, robot_pos: np.ndarray, max_pos: float, max_v: float) -> RowRules:
    """The rules B robots read from their game columns (B, ``GAME_OBS_DIM``), the robots at ``robot_pos``
    (B, 2) m: their zones (B, S) and speed limits (B,) as a planner takes them (``RowRules``)."""
    b, s = len(columns), GAME_OBS_SLICES
    slots = columns[:, s["zones"]].reshape(b, len(SLOTS), ZONE_OBS_DIM).astype(np.float64)
    z = ZONE_OBS_SLICES
    one_hot = slots[..., z["kind"]]
    kind = np.where(one_hot.any(axis=-1), np.array(ZONE_KINDS)[one_hot.argmax(axis=-1)], NONE)
    shape = slots[..., z["shape"]] * (2 * max_pos) + np.tile(robot_pos, 2)[:, None]
    clearance = slots[..., z["clearance"]][..., 0] * max_pos
    limit = columns[:, s["speed_limit"]][:, 0].astype(np.float64)
    speed = np.where(limit >= 1.0, np.inf, limit * max_v)
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
        return base, game_rules(columns, robot_position(obs, self.max_pos), self.max_pos, self.max_v)

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
