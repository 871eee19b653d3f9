"""The second team: BLUE robots that play as a team plays, driven by the project's own planners.

Each opponent takes a role per episode (drawn from ``ROLE_SHARE`` with the generator ``reset`` is given,
so a seed replays it) and every ``decide_every`` control steps turns it into a target pose from the
state at hand:

- ``mark``: goal-side of one of our robots (each marker its own, while there are ours to go round),
  0.3-0.5 m from it on the line to BLUE's goal, facing it;
- ``cover``: a point on the segment from BLUE's goal to the ball (a fraction of the way drawn per
  episode), facing the ball;
- ``ball``: the ball, facing it from where the robot is;
- ``free``: the emptiest of a few random spots, in the half BLUE attacks or anywhere, drawn afresh about
  every ``FREE_HOLD`` seconds, facing the ball.

BLUE defends the goal on positive x where ``RefereeState.blue_on_positive_half``. A decision hands every
deciding opponent of every field to one planner call (``trajectory`` or ``sampling``, the manager layer's,
the nearest ``NEIGHBOURS`` other robots its obstacles), which picks a sub-goal towards the target; between
decisions only the worker runs, from the sub-goal held. ``random`` is the world's random walk
(``hier_ssl.world.obstacles.RandomWalk``) a step at a time; targets are still kept, for render.

Obeying the rules (the default): the planner gets BLUE's zones (``forbidden_zones``: their keeper may enter
its defense area) and the speed limit as ``RowRules``, and every command is capped at the limit: 1.5 m/s
in STOP, zero in HALT (the worker drives at its own cap whatever the sub-goal). The random walk obeys the
limits only: it has no sub-goal to keep out of a zone. ``obey_rules=False`` ignores zones and limits.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hier_ssl.config import TaskSettings
from hier_ssl.envs.planners import make_planner
from hier_ssl.game.legal import RowRules, cap_speed, row_rules
from hier_ssl.game.referee import BLUE, Lineup, RefereeState
from hier_ssl.game.zones import forbidden_zones, speed_limit
from hier_ssl.manager.neighbours import nearest
from hier_ssl.manager.planners import TrajectoryPlanner
from hier_ssl.manager.scene import Scene, halted, subgoal_poses
from hier_ssl.worker import resolve_worker
from hier_ssl.world.field import Field
from hier_ssl.world.obstacles import RandomWalk
from hier_ssl.world.physics import RobotSpec, RobotState

ROLES = ("mark", "cover", "ball", "free")
PLANNERS = ("trajectory", "sampling", "random")
# How often a team's robots take each role: most mark, one in five covers the goal, fewer chase the ball
# (one is enough; more crowd it) and the rest get free. Over the roles a team is given, renormalised.
ROLE_SHARE = {"mark": 0.4, "cover": 0.2, "ball": 0.15, "free": 0.25}
MARK_DISTANCE = (0.3, 0.5)  # m from the marked robot towards BLUE's goal, drawn per episode
COVER_SPAN = (0.2, 0.8)  # of the way from BLUE's goal to the ball, drawn per episode
FREE_HOLD = 3.0  # s a free robot keeps its spot, on average, before it draws another
FREE_SPOTS = 8  # random spots a free robot draws, keeping the one farthest from every robot
FREE_ATTACK = 0.5  # chance a free robot looks for its spot in the half BLUE attacks rather than anywhere
# Other robots each opponent's planner avoids, nearest first: its neighbourhood, not all 21 others, as the
# planners' work grows with the obstacles they are given.
NEIGHBOURS = 5


def _check(name: str, value: np.ndarray, shape: tuple[int, ...]) -> None:
    if np.shape(value) != shape:
        raise ValueError(f"OpponentTeam.commands: {name} must have shape {shape}, got {np.shape(value)}")


class OpponentTeam:
    """``count`` BLUE robots on each of ``num_fields`` fields, slots ``num_ours``.. of the world's robots
    (ours, YELLOW, first), driven towards their roles' targets (module docstring).

    ``planner``: "trajectory", "sampling" or "random"; ``decide_every``: control steps between decisions;
    ``roles``: those the team draws from; ``worker``: the goToPoint worker that drives them between
    decisions, a spec or object as ``hier_ssl.worker.resolve_worker`` takes ("paper": as fast as ours by
    default)."""

    def __init__(
        self,
        field: Field,
        robot: RobotSpec,
        num_fields: int,
        num_ours: int,
        count: int,
        planner: str = "trajectory",
        decide_every: int = 16,
        obey_rules: bool = True,
        dt: float = 0.025,
        roles: tuple[str, ...] = ROLES,
        worker: object = "paper",
    ) -> None:
        if planner not in PLANNERS:
            raise ValueError(f"unknown opponent planner {planner!r}; known: {list(PLANNERS)}")
        unknown = [r for r in roles if r not in ROLES]
        if unknown:
            raise ValueError(f"unknown opponent role {unknown[0]!r}; known: {list(ROLES)}")
        if not roles:
            raise ValueError(f"OpponentTeam roles must name at least one of {list(ROLES)}, got {roles!r}")
        for name, value, least in (
            ("num_fields", num_fields, 1),
            ("num_ours", num_ours, 0),
            ("count", count, 1),
            ("decide_every", decide_every, 1),
        ):
            if not value >= least:
                raise ValueError(f"OpponentTeam {name} must be >= {least}, got {value!r}")
        if "mark" in roles and num_ours < 1:
            raise ValueError(f"the role 'mark' needs robots of ours to mark, got num_ours={num_ours!r}")
        self.field, self.robot, self.num_ours, self.count = field, robot, num_ours, count
        self.decide_every, self.obey_rules, self.roles = decide_every, obey_rules, tuple(roles)
        share = np.array([ROLE_SHARE[r] for r in self.roles])
        self._share = share / share.sum()
        self._redraw = min(1.0, decide_every * dt / FREE_HOLD)  # a free robot's chance per decision
        self.worker = resolve_worker(worker, robot, dt)
        self.walk = RandomWalk() if planner == "random" else None
        self.planner = None
        if planner != "random":
            settings = TaskSettings(field=field.name, dt=dt, frame_skip=decide_every)
            made = make_planner(planner, settings, self.worker)
            self.planner = dataclasses.replace(made, field=field, robot=robot)
        # Every opponent's other robots: the world's slots but its own, for its planner's obstacles.
        total = num_ours + count
        self._others = np.array([[j for j in range(total) if j != num_ours + k] for k in range(count)])
        n, k = num_fields, count
        self.role = np.zeros((n, k), np.int64)  # index into ``roles``
        self.marked = np.zeros((n, k), np.int64)  # the robot of ours each marks
        self.gap = np.zeros((n, k))  # m, mark distance
        self.cover = np.zeros((n, k))  # fraction of the way goal -> ball
        self.spot = np.zeros((n, k, 2))  # a free robot's spot
        self.stale = np.ones((n, k), bool)  # a free robot's spot is to be drawn at the next decision
        self.memory = np.full(n * k, np.nan + 0j)  # ``trajectory``'s winning sub-destinations, row n * K + k
        self.fresh = np.ones(n, bool)  # reset since the last decision
        self._targets = np.zeros((n, k, 3))
        self.subgoal = np.zeros((n, k, 5))

    @property
    def targets(self) -> np.ndarray:
        """(N, K, 3) each opponent's current role target x, y, theta (m, rad), field frame."""
        return self._targets

    def reset(self, fields: np.ndarray, rng: np.random.Generator) -> None:
        """New episodes on ``fields`` (F,): each opponent's role and its episode's draws from ``rng`` (the
        same draws whatever the roles, so a seed replays them), and a decision at their next step."""
        fields = np.asarray(fields, np.int64)
        f, k = len(fields), self.count
        self.role[fields] = rng.choice(len(self.roles), size=(f, k), p=self._share)
        # A permutation of ours per field, so markers mark different robots while there are enough.
        order = np.argsort(rng.random((f, max(self.num_ours, 1))), axis=1)
        self.marked[fields] = order[:, np.arange(k) % order.shape[1]]
        self.gap[fields] = rng.uniform(*MARK_DISTANCE, (f, k))
        self.cover[fields] = rng.uniform(*COVER_SPAN, (f, k))
        self.stale[fields] = True
        self.memory.reshape(-1, k)[fields] = np.nan
        self.fresh[fields] = True
        self.worker.reset(fields)

    def commands(
        self,
        state: RobotState,
        ball: np.ndarray,
        referee: RefereeState,
        lineup: Lineup,
        steps: np.ndarray,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """(N, K, 3) the opponents' velocity commands, each in its own frame (m/s, rad/s), for the world's
        robots ``state`` (N, M + K), the ball (N, 2) m, the referee's state and ``lineup`` of the M + K slots
        (the opponents BLUE), ``steps`` (N,) control steps since each field's reset. Fields whose step is a
        multiple of ``decide_every``, or that were reset since, decide first (one planner call for all)."""
        n, m, k = len(self.fresh), self.num_ours, self.count
        _check("state.pos", state.pos, (n, m + k, 2))
        _check("ball", ball, (n, 2))
        _check("steps", steps, (n,))
        _check("lineup.team", lineup.team, (m + k,))
        if (lineup.team[m:] != BLUE).any():
            raise ValueError(
                f"the opponents (slots {m}..{m + k - 1}) must be BLUE, lineup.team is {lineup.team}"
            )
        deciding = np.flatnonzero(self.fresh | (np.asarray(steps) % self.decide_every == 0))
        if len(deciding):
            self._decide(deciding, state, np.asarray(ball, float), referee, lineup, rng)
        team = state.robots(slice(m, m + k))
        if self.walk is None:
            command = self.worker(team, self.subgoal)
        else:
            command = self.walk(team.pos.reshape(-1, 2), team.angle.ravel(), rng).reshape(n, k, 3)
        if not self.obey_rules:
            return command
        limit = speed_limit(referee)
        command[..., :2] = cap_speed(command[..., :2], limit[:, None])
        command[limit <= 0] = 0.0  # HALT: no spin either
        return command

    def _decide(
        self,
        rows: np.ndarray,
        state: RobotState,
        ball: np.ndarray,
        referee: RefereeState,
        lineup: Lineup,
        rng: np.random.Generator,
    ) -> None:
        """New targets and sub-goals for the opponents of fields ``rows`` (D,)."""
        m, k = self.num_ours, self.count
        pos = state.pos[rows]
        self.fresh[rows] = False
        side = np.where(referee.blue_on_positive_half[rows], 1.0, -1.0)
        self._targets[rows] = self.role_targets(pos, ball[rows], side, self.role[rows], rows, rng)
        if self.planner is None:
            return
        own, vel = pos[:, m:].reshape(-1, 2), state.vel[rows, m:].reshape(-1, 2)
        others = pos[:, self._others].reshape(len(own), -1, 2)
        index, _ = nearest(own, others, min(NEIGHBOURS, others.shape[1]))
        near = np.take_along_axis(others, index[..., None], axis=1)
        near_vel = np.take_along_axis(
            state.vel[rows][:, self._others].reshape(len(own), -1, 2), index[..., None], axis=1
        )
        target = np.zeros((len(own), 5))
        target[:, :3] = self._targets[rows].reshape(-1, 3)
        scene = Scene(target, own, vel, near, near_vel)
        rules = None
        if self.obey_rules:
            ref = referee.fields(rows)
            team = Lineup(lineup.team[m:], lineup.robot_id[m:])
            rules = row_rules(forbidden_zones(ref, ball[rows], self.field, team), speed_limit(ref))
        self.subgoal[rows] = self._plan(scene, rows, rules, rng).reshape(len(rows), k, 5)

    def _plan(
        self, scene: Scene, rows: np.ndarray, rules: RowRules | None, rng: np.random.Generator
    ) -> np.ndarray:
        """Sub-goal poses (D K, 5) of the planner for ``scene``'s rows, the opponents of fields ``rows``."""
        if not isinstance(self.planner, TrajectoryPlanner):
            return self.planner.plan(scene, rules)
        # ``trajectory`` remembers each robot's winner (here, per field and opponent) and draws its
        # sub-destinations from its generator: the caller's, so that a seeded episode replays.
        self.planner.rng = rng
        slots = (rows[:, None] * self.count + np.arange(self.count)).ravel()
        last = self.memory[slots]
        chosen, winner = self.planner.plan(scene, last, rules)
        self.memory[slots] = np.where(np.isnan(winner), last, winner)
        return halted(scene, rules, subgoal_poses(scene, chosen))

    def role_targets(
        self,
        pos: np.ndarray,
        ball: np.ndarray,
        side: np.ndarray,
        role: np.ndarray,
        rows: np.ndarray,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """(D, K, 3) the role targets of the opponents of fields ``rows`` (D,): the robots at ``pos``
        (D, M + K, 2), the ball (D, 2), BLUE's goal at x sign ``side`` (D,), roles ``role`` (D, K) indices
        into ``roles``. Draws a free robot's new spot where it is due."""
        m = self.num_ours
        own = pos[:, m:]
        goal = np.stack([side * self.field.half_length, np.zeros_like(side)], axis=-1)[:, None]  # (D, 1, 2)
        ball = ball[:, None]
        targets = np.empty(own.shape[:2] + (3,))
        name = np.array(self.roles)[role]
        # mark: goal-side of the marked robot, facing it (a team without ours has no markers: slot 0
        # stands in, its target never chosen)
        marked = np.take_along_axis(pos[:, : max(m, 1)], self.marked[rows][..., None], axis=1)
        away = goal - marked
        unit = away / np.maximum(np.linalg.norm(away, axis=-1, keepdims=True), 1e-9)
        xy = marked + self.gap[rows][..., None] * unit
        face = marked - xy
        # cover: on the segment goal -> ball, facing the ball
        covering = goal + self.cover[rows][..., None] * (ball - goal)
        xy = np.where((name == "cover")[..., None], covering, xy)
        face = np.where((name == "cover")[..., None], ball - covering, face)
        # ball: at it, facing it from the robot
        xy = np.where((name == "ball")[..., None], ball, xy)
        face = np.where((name == "ball")[..., None], ball - own, face)
        # free: the spot, drawn afresh where due, facing the ball
        free = name == "free"
        due = free & (self.stale[rows] | (rng.random(free.shape) < self._redraw))
        if due.any():
            self.spot[rows] = np.where(due[..., None], self._free_spots(pos, side, rng), self.spot[rows])
            self.stale[rows] &= ~due
        xy = np.where(free[..., None], self.spot[rows], xy)
        face = np.where(free[..., None], ball - self.spot[rows], face)
        targets[..., :2] = xy
        targets[..., 2] = np.arctan2(face[..., 1], face[..., 0])
        return targets

    def _free_spots(self, pos: np.ndarray, side: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(D, K, 2) for each opponent the emptiest of ``FREE_SPOTS`` random spots (the farthest from every
        robot ``pos`` (D, R, 2)), in the half BLUE attacks (x sign ``-side`` (D,)) or, by a coin per
        opponent, anywhere on the field."""
        d, k = len(pos), self.count
        hl, hw = self.field.half_length, self.field.half_width
        draw = rng.random((d, k, FREE_SPOTS, 2))
        x = -hl + 2 * hl * draw[..., 0]
        attack = rng.random((d, k, 1)) < FREE_ATTACK
        x = np.where(attack, -side[:, None, None] * np.abs(x), x)
        spots = np.stack([x, -hw + 2 * hw * draw[..., 1]], axis=-1)  # (D, K, S, 2)
        gaps = np.linalg.norm(spots[:, :, :, None] - pos[:, None, None], axis=-1).min(axis=-1)
        best = np.argmax(gaps, axis=-1)
        return np.take_along_axis(spots, best[..., None, None], axis=2)[:, :, 0]


__all__ = ["COVER_SPAN", "MARK_DISTANCE", "NEIGHBOURS", "PLANNERS", "ROLES", "ROLE_SHARE", "OpponentTeam"]
