"""Where a game scenario's reset puts our robots, the opponents, the ball and our role positions
(docs/guide/ssl-game.md, "The game scenarios"): ``GamePlaces``, the base ``GameScenario`` draws its resets
and, when the referee's command comes, the new role positions with.

Places are drawn in a frame where our goal is at negative x and mirrored into each field (the side each
team defends and the field's y are drawn per episode): the boxes below are fractions of the field's half
size less the spawn margin. Every start and role position is legal under the referee's state it is drawn
for, ``target_margin`` beyond every zone's clearance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.optimize import linear_sum_assignment

from hier_ssl.envs.scenario import Placement
from hier_ssl.envs.scenarios import FieldScenario
from hier_ssl.game import FORCE_START, Lineup, RefereeState, Zones, forbidden_zones, referee_state
from hier_ssl.game.legal import nearest_legal
from hier_ssl.game.referee import own_side
from hier_ssl.world.field import Field as FieldSpec

MARK_DISTANCE = 0.4  # m goal-side of the opponent a marking role position lies
Box = tuple[tuple[float, float], tuple[float, float]]  # (low, high) x, y in fractions of the half field


@dataclass
class GamePlacement(Placement):
    """A reset of F game fields: the robots and the ball (``Placement``), and the referee's part, always
    set by ``GameScenario.reset_world_at``: ``blue_on_positive_half`` (F,) bool, ``command_step`` (F,) the
    control step at which the scenario's command comes, ``placement_pos`` (F, 2) m."""

    blue_on_positive_half: np.ndarray | None = None
    command_step: np.ndarray | None = None
    placement_pos: np.ndarray | None = None


def rest_point(pos: np.ndarray, vel: np.ndarray, deceleration: float, field: FieldSpec) -> np.ndarray:
    """(F, 2) m where balls at ``pos`` (F, 2) rolling at ``vel`` (F, 2) m/s come to rest under a constant
    ``deceleration`` m/s^2, if nothing stops them first, held inside ``field``'s playing area."""
    rolled = pos + vel * np.linalg.norm(vel, axis=-1, keepdims=True) / (2 * deceleration)
    return np.clip(rolled, [-field.half_length, -field.half_width], [field.half_length, field.half_width])


def assign_roles(pos: np.ndarray, target: np.ndarray, keeper: int = -1) -> np.ndarray:
    """``target`` (F, M, D) with its rows handed to the robots at ``pos`` (F, M, 2) by least total distance
    per field (the assignment problem, solved exactly), robot ``keeper`` keeping its own (-1: none)."""
    out = target.copy()
    free = np.array([i for i in range(target.shape[1]) if i != keeper])
    for f in range(len(target)):
        cost = np.linalg.norm(pos[f][free][:, None] - target[f][free][None, :, :2], axis=-1)
        robots, roles = linear_sum_assignment(cost)
        out[f, free[robots]] = target[f, free[roles]]
    return out


class GamePlaces(FieldScenario):
    """The resets of the game scenarios: subclasses set the boxes of starts, targets and the ball, and
    (``GameScenario``) the teams' ``lineup`` and ``ours``, the ``command`` they play and the range of
    control steps ``command_steps`` at which it comes."""

    start_box: ClassVar[Box] = ((-1.0, -1.0), (1.0, 1.0))  # our robots' starts
    opponent_box: ClassVar[Box] = ((-1.0, -1.0), (1.0, 1.0))  # the opponents' starts
    target_box: ClassVar[Box] = ((-1.0, -1.0), (1.0, 1.0))  # our robots' role positions
    ball_box: ClassVar[Box] = ((-0.6, -0.8), (0.6, 0.8))
    placement_box: ClassVar[Box] = ((0.0, 0.0), (0.0, 0.0))  # the ball placement position (placement only)
    mark_share: ClassVar[float] = 0.0  # of our field robots, whose role position marks an opponent
    lineup: Lineup  # every robot's team and id, ours first
    ours: Lineup  # ours alone
    command: int  # the referee's command the scenario plays
    command_steps: np.ndarray  # (2,) the first and the last control step at which it may come

    def _mirror(self, referee: RefereeState, rng: np.random.Generator) -> np.ndarray:
        """(F, 1, 2) the signs that take the drawing frame (our goal at -x) into each field, y at random."""
        x = -own_side(referee, self.ours)[:, :1]
        y = np.where(rng.random((len(x), 1)) < 0.5, -1.0, 1.0)
        return np.stack([x, y], axis=-1)

    def _box(self, box: Box, count: int) -> tuple[np.ndarray, np.ndarray]:
        """A box of fractions as (low, high) m (count, 2) each."""
        low, high = np.array(box) * self.half
        return np.broadcast_to(low, (count, 2)), np.broadcast_to(high, (count, 2))

    def _spread(
        self,
        rng: np.random.Generator,
        box: tuple[np.ndarray, np.ndarray],
        mirror: np.ndarray,
        zones: Zones,
        placed: np.ndarray,
        first: np.ndarray | None = None,
    ) -> np.ndarray:
        """Points (F, C, 2) drawn in ``box`` (low, high (C, 2), drawing frame), mirrored into each field,
        moved to the nearest point ``target_margin`` beyond their zones (F, C, S), inside the field lines and
        at least ``gap`` from each other and from ``placed`` (F, P, 2): a point that is not is drawn again
        until none is. ``first`` (F, C, 2), field frame: the points to try before any draw, where not NaN."""
        f, c = zones.kind.shape[:2]
        inflated = Zones(zones.kind, zones.shape, zones.clearance + self.options.target_margin)
        earlier = np.tril(np.ones((c, c), bool), k=-1)
        pts, bad = np.zeros((f, c, 2)), np.ones((f, c), bool)
        for attempt in range(1000):
            fresh = rng.uniform(box[0], box[1], (f, c, 2)) * mirror
            if attempt == 0 and first is not None:
                fresh = np.where(np.isnan(first), fresh, first)
            pts = nearest_legal(inflated, np.where(bad[..., None], fresh, pts))
            near = np.linalg.norm(pts[:, :, None] - pts[:, None], axis=-1) < self.gap
            near_placed = np.linalg.norm(pts[:, :, None] - placed[:, None], axis=-1) < self.gap
            # A point a zone pushed beyond the box's field lines (the drawing box's bound) is drawn again.
            off = (np.abs(pts) > self.half + self.config.spawn_margin).any(axis=-1)
            bad = (near & earlier).any(axis=2) | near_placed.any(axis=2) | off
            if not bad.any():
                return pts
        raise RuntimeError(f"scenario {self.name!r}: cannot place {c} robots {self.gap} m apart, legally")

    def _marks(self, rng: np.random.Generator, referee: RefereeState, theirs: np.ndarray) -> np.ndarray:
        """(F, M, 2) m: for a share ``mark_share`` of our robots but the keeper, drawn per robot, a point
        ``MARK_DISTANCE`` goal-side of an opponent at ``theirs`` (F, K, 2) (each its own while there are
        enough), on the line to our goal's centre; NaN for the others."""
        f, m, k = len(theirs), self.num_agents, self.num_obstacles
        marked = np.argsort(rng.random((f, k)), axis=1)[:, np.arange(m) % k]
        opponent = np.take_along_axis(theirs, marked[..., None], axis=1)
        goal = np.stack([own_side(referee, self.ours)[:, 0] * self.field.half_length, np.zeros(f)], axis=-1)
        to_goal = goal[:, None] - opponent
        unit = to_goal / np.maximum(np.linalg.norm(to_goal, axis=-1, keepdims=True), 1e-9)
        marking = rng.random((f, m)) < self.mark_share
        marking[:, self.options.keeper if 0 <= self.options.keeper < m else []] = False
        return np.where(marking[..., None], opponent + MARK_DISTANCE * unit, np.nan)

    def _targets(
        self,
        rng: np.random.Generator,
        referee: RefereeState,
        ball: np.ndarray,
        mirror: np.ndarray,
        theirs: np.ndarray,
        ours: np.ndarray,
    ) -> np.ndarray:
        """Our robots' role positions (F, M, 5) under ``referee`` with the ball at ``ball`` (F, 2), the
        opponents at ``theirs`` (F, K, 2) and ours at ``ours`` (F, M, 2): the keeper before its goal, a share
        marking opponents (``_marks``), the others in ``target_box``, all legal, facing the ball, at rest;
        handed out as ``options.assign`` says."""
        m = self.num_agents
        zones = forbidden_zones(referee, ball, self.field, self.ours)
        low, high = (np.array(a) for a in self._box(self.target_box, m))
        keeper = self.options.keeper
        if 0 <= keeper < m:  # the keeper's box: 0.25 m before the goal line, within the goal's width
            edge, half_goal = self.field.half_length, self.field.goal_width / 2
            low[keeper], high[keeper] = (-edge + 0.2, -0.6 * half_goal), (-edge + 0.3, 0.6 * half_goal)
        marks = self._marks(rng, referee, theirs)
        pos = self._spread(rng, (low, high), mirror, zones, ball[:, None], marks)
        target = np.zeros(pos.shape[:2] + (5,))
        target[..., 0:2] = pos
        to_ball = ball[:, None] - pos
        target[..., 2] = np.arctan2(to_ball[..., 1], to_ball[..., 0])
        if self.options.assign == "team":
            return assign_roles(ours, target, keeper)
        return target

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> GamePlacement:
        f, m, k = num_fields, self.num_agents, self.num_obstacles
        opt = self.options
        blue_positive = rng.random(f) < 0.5
        steps = rng.integers(self.command_steps[0], self.command_steps[1] + 1, f)
        keepers = (opt.keeper, opt.opponent_keeper)
        first = np.where(steps == 0, self.command, FORCE_START)
        side = referee_state(first, self.field, keeper=keepers, blue_on_positive_half=blue_positive)
        mirror = self._mirror(side, rng)
        ball = rng.uniform(*self._box(self.ball_box, 1), (f, 1, 2)) * mirror
        heading = rng.uniform(-np.pi, np.pi, (f, 1))
        speed = rng.uniform(*opt.ball_speed, (f, 1))
        ball_vel = np.stack([np.cos(heading), np.sin(heading)], axis=-1) * speed[..., None]
        placement = self.placement_position(rng, mirror)
        start = referee_state(
            first, self.field, placement=placement, keeper=keepers, blue_on_positive_half=blue_positive
        )
        zones = forbidden_zones(start, ball[:, 0], self.field, self.lineup)
        ours = self._spread(rng, self._box(self.start_box, m), mirror, zones.take(np.s_[:, :m]), ball)
        placed = np.concatenate([ball, ours], axis=1)
        theirs = self._spread(rng, self._box(self.opponent_box, k), mirror, zones.take(np.s_[:, m:]), placed)
        played = RefereeState(
            np.full(f, self.command),
            start.placement,
            start.keeper,
            start.blue_on_positive_half,
            np.zeros(f, bool),  # the targets are for the command's restrictions: its ball not yet in play
        )
        pos = np.concatenate([ours, theirs], axis=1)
        return GamePlacement(
            pos,
            rng.uniform(-np.pi, np.pi, (f, m + k)),
            self._targets(rng, played, ball[:, 0], mirror, theirs, ours),
            ball_pos=ball,
            ball_vel=ball_vel,
            blue_on_positive_half=blue_positive,
            command_step=steps,
            placement_pos=start.placement,
        )

    def placement_position(self, rng: np.random.Generator, mirror: np.ndarray) -> np.ndarray:
        """(F, 2) m: where the ball is to be placed (read in a ball placement only)."""
        return rng.uniform(*self._box(self.placement_box, 1), (len(mirror), 1, 2))[:, 0] * mirror[:, 0]


__all__ = ["MARK_DISTANCE", "Box", "GamePlacement", "GamePlaces", "assign_roles", "rest_point"]
