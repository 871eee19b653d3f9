"""``trajectory``: the league's reference path finder as a scripted manager, batched over fields.

The algorithm is TIGERs Mannheim's (Sumatra, ``modules/sumatra-pathfinder``: ``PathFinder``,
``SubDestRndGenerator``, ``SubPathCollisionChecker``, ``PathCollisionChecker``, the acceptors
``MotionLessObstacleResultAcceptor`` and ``MovingObstacleResultAcceptor``, ``ConstVelocityObstacle``; the
trajectories of ``hier_ssl.manager.bangbang``), which Immortals, RoboTeam Twente and RoboJackets follow and
UBC Thunderbots (``src/software/ai/navigator/trajectory/``) extends. Written here from its description;
no code of theirs is copied. Every call, for each robot:

1. The direct trajectory: a 2-D bang-bang trajectory from the robot's position and velocity to rest on the
   target. If it is acceptable (below), the sub-goal is the target.
2. Otherwise sub-destinations: ``num_sub_destinations`` drawn at a random angle of ``min_angle``-
   ``max_angle`` either side of the robot-target line and ``min_scale``-``max_scale`` times the target
   distance, plus last call's winner, tried in order of their angle (the smallest first). Along each
   sub-path the robot switches to the target every ``step_size_on_sub_path`` s from
   ``initial_time_offset``, while the sub-path lasts; each switch gives a path: the sub-path until the
   switch, then the bang-bang trajectory from the state there to rest on the target. The first acceptable
   path (sub-destination by sub-destination, switch times in order) wins.
3. Failing all: of the rejected paths (those the still obstacles accepted), the one whose first collision
   with a moving obstacle lies closest to the target; if there is none, stop where the robot is. (Under
   the rules, first the path whose step into a zone lies closest to the target: ``TrajectoryPlanner.plan``.)

Collisions: at times ``initial_time_offset`` + k ``collision_check_step`` along a path, until it arrives,
and on the straight lines between those checks, against the obstacles predicted at constant velocity for
``t_max`` s and held there after; a collision is a centre distance under collision_distance +
``obstacle_margin``. An obstacle slower than
``motionless_speed`` is still. Still obstacles are checked first: a path is rejected by them unless its
first collision with them lies near its end (TIGERs' motionless acceptor: the collision point's distance
to the target over the start's below first-collision time / ``threshold_max_collision_time``, which lets
a robot reach a target next to an obstacle). Moving obstacles accept a path without collision, or one
whose first collision comes later than the time to brake from the current speed plus
``brake_time_offset`` (as TIGERs' moving acceptor), braking at the worker's deceleration: TIGERs' robots
brake at their acceleration limit, the paper's worker at 1 m/s^2.

The sub-goal is the point in force at the decision: the sub-destination of a path through one (its switch
comes at ``initial_time_offset`` + ``step_size_on_sub_path`` s or later, after any control step), else the
target, as Immortals' planner hands its controller an intermediate point.

Compiled: the bang-bang profiles (``hier_ssl.manager.bangbang``), and in ``hier_ssl.manager.path_search``
the collision checks of a path (``walk``) and the search of steps 2 and 3 (``search``), which, as TIGERs'
path finder, tries one robot's paths in order and stops at the first acceptable one, and walks a path only
as far as it can still win or be a fallback. A team of 11 in STOP: 0.6-1.0 ms a decision, 1.5-1.8 ms under
the rules (21-24 and 66-68 ms as numpy arrays before; ``benchmarks/team_decision.py``).

Memory: the winning sub-destination (relative to the robot-target line, as TIGERs keeps it) of every
robot. ``play`` resets it at the start of each evaluation (``forget``) and says which robots the rows of
each call are (``rows``); called without rows, a planner remembers nothing. The random draws come from a
generator seeded with ``seed`` at each ``forget``, so a seeded evaluation is reproducible.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hier_ssl.game.legal import RowRules, distances, nearest_legal
from hier_ssl.game.zones import Zones
from hier_ssl.manager.actions import action_dim
from hier_ssl.manager.bangbang import Profile2D, bang_bang_2d
from hier_ssl.manager.path_search import moving_accepts, search, still_accepts, walk_paths
from hier_ssl.manager.scene import Scene, halted, read_scene, ruled_scene, scene_action, subgoal_poses
from hier_ssl.world.field import Field
from hier_ssl.world.physics import RobotSpec


@dataclass(frozen=True)
class TrajectoryParams:
    """The path finder's settings; the names and defaults of the TIGERs sources where they have them."""

    initial_time_offset: float = 0.1  # PathFinder.initialTimeOffset (s)
    step_size_on_sub_path: float = 0.2  # SubPathCollisionChecker.stepSizeOnSubPath (s)
    collision_check_step: float = 0.1  # PathCollisionChecker.checkUntil's step (s)
    min_angle: float = 20.0  # SubDestRndGenerator.MIN_ANGLE (degrees)
    max_angle: float = 140.0  # SubDestRndGenerator.MAX_ANGLE (degrees)
    min_scale: float = 0.5  # SubDestRndGenerator.MIN_SCALE (of the target distance)
    max_scale: float = 1.5  # SubDestRndGenerator.MAX_SCALE
    num_sub_destinations: int = 5  # SubDestRndGenerator.NUM_SUB_DESTINATIONS
    brake_time_offset: float = 0.5  # MovingObstacleResultAcceptor.brakeTimeOffset (s)
    threshold_max_collision_time: float = 4.0  # MotionLessObstacleResultAcceptor (s)
    t_max: float = 1.0  # ConstVelocityObstacle.tMax: constant-velocity prediction (s)
    # hier_ssl's: m beyond the collision distance, for the obstacles' unpredicted motion (checks cover the
    # motion between them: ``first_collisions``); a wider one closes the gaps formation's robots drive
    # through (docs/research-notes.md, "The trajectory planner's settings").
    obstacle_margin: float = 0.05
    motionless_speed: float = 0.1  # hier_ssl's: m/s under which an obstacle is still
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("initial_time_offset", "step_size_on_sub_path", "collision_check_step", "t_max"):
            if not getattr(self, name) > 0:
                raise ValueError(f"TrajectoryParams.{name} must be > 0, got {getattr(self, name)!r}")
        if not 0 <= self.min_angle <= self.max_angle:
            raise ValueError(
                f"TrajectoryParams needs 0 <= min_angle <= max_angle, got {self.min_angle!r}, "
                f"{self.max_angle!r}"
            )
        if not 0 < self.min_scale <= self.max_scale or self.num_sub_destinations < 0:
            raise ValueError(f"TrajectoryParams: bad sub-destination range {self!r}")


@dataclass(frozen=True)
class Collisions:
    """First collisions along a batch of paths (all arrays of the paths' shape): time (s, inf without)
    and position (complex) of the first with a still obstacle, and with a moving one; and where the rules'
    zones were checked, the time of the first step into a zone."""

    still_time: np.ndarray
    still_pos: np.ndarray
    moving_time: np.ndarray
    moving_pos: np.ndarray
    zone_time: np.ndarray | None = None  # the first check stepping into a zone (inf: none); None: unchecked
    zone_pos: np.ndarray | None = None  # the position at that check


def check_times(total: np.ndarray, params: TrajectoryParams, checked: bool = True) -> np.ndarray:
    """(C,) the times of the collision checks of paths lasting ``total`` (s): from ``initial_time_offset``
    every ``collision_check_step``, while any path lasts; none where nothing is ``checked``."""
    offset, step = params.initial_time_offset, params.collision_check_step
    count = math.ceil((float(total.max(initial=0.0)) - offset) / step) if checked else 0
    return np.array([offset + k * step for k in range(max(count, 0))], dtype=float)


def _zone_arrays(zones: tuple[Zones, np.ndarray] | None, rows: int) -> tuple[np.ndarray, ...]:
    """The compiled walks' zones: kind, shape, clearance and which the robot breaks, (rows, S) each
    (shape (rows, S, 4)), contiguous; S = 0 without ``zones``."""
    if zones is None:
        return (
            np.zeros((rows, 0), np.int64),
            np.zeros((rows, 0, 4)),
            np.zeros((rows, 0)),
            np.zeros((rows, 0), bool),
        )
    rule, leaving = zones
    return (
        np.ascontiguousarray(rule.kind, np.int64),
        np.ascontiguousarray(rule.shape, float),
        np.ascontiguousarray(rule.clearance, float),
        np.ascontiguousarray(leaving, bool),
    )


def first_collisions(
    path_at: Callable[[float], np.ndarray] | tuple[np.ndarray, np.ndarray],
    total: np.ndarray,
    obstacles: tuple[np.ndarray, np.ndarray, np.ndarray],
    radius: float,
    params: TrajectoryParams,
    zones: tuple[Zones, np.ndarray] | None = None,
) -> Collisions:
    """Walk paths along time (``path_at(t)``: positions of the shape of ``total``, the paths' durations)
    against obstacles (position, velocity complex and a still mask, each (N, K), N the paths' first axis).

    A check at time t also covers the interval from the previous one: the closest approach of the robot
    and each obstacle moving in straight lines between the two checks (two robots closing at 4.4 m/s
    travel 0.44 m between checks, more than a collision distance).

    ``zones``: the rules' zones (arrays (N, S)) and which of them each robot already breaks (N, S), as
    still obstacles of any shape: each check's step, a straight line from the previous check's position
    (the path's start for the first), must keep clear of every zone the robot does not already break (it
    is leaving those).

    ``path_at`` may instead be the paths' positions at ``check_times(total, ...)`` (C, *shape) and at
    their start (shape), complex: a planner computes them at once."""
    total = np.asarray(total, float)
    times = check_times(total, params, bool(obstacles[0].shape[-1]) or zones is not None)
    if callable(path_at):
        positions = [np.broadcast_to(path_at(t), total.shape) for t in times]
        positions = np.stack(positions) if positions else np.zeros((0,) + total.shape, complex)
        start = path_at(0.0) if zones is not None else np.zeros(total.shape, complex)
    else:
        positions, start = path_at
    n, p = (total.shape[0] if total.ndim else 1), total.size
    out = walk_paths(
        np.ascontiguousarray(np.broadcast_to(positions, times.shape + total.shape).reshape(len(times), p).T),
        times,
        np.ascontiguousarray(np.broadcast_to(start, total.shape), complex).reshape(p),
        np.ascontiguousarray(total).reshape(p),
        np.arange(p) // max(p // max(n, 1), 1),  # each path's row of the obstacles and zones
        *(np.ascontiguousarray(x) for x in obstacles),
        radius,
        params.t_max,
        *_zone_arrays(zones, max(n, 1)),
    ).reshape((9,) + total.shape)
    hits = Collisions(out[0], out[1] + 1j * out[2], out[3], out[4] + 1j * out[5])
    if zones is None:
        return hits
    return dataclasses.replace(hits, zone_time=out[6], zone_pos=out[7] + 1j * out[8])


def accepted(
    hits: Collisions,
    start: np.ndarray,
    goal: np.ndarray,
    speed: np.ndarray,
    accel: float,
    p: TrajectoryParams,
) -> tuple[np.ndarray, np.ndarray]:
    """(still obstacles accept, moving ones accept), each of the paths' shape; ``start``, ``goal`` and
    ``speed`` (the robot's) broadcast against it."""
    still_ok = still_accepts(hits.still_time, hits.still_pos, start, goal, p.threshold_max_collision_time)
    if hits.zone_time is not None:  # no leniency near the end: the target was made legal, the path must be
        still_ok &= np.isinf(hits.zone_time)
    return still_ok, moving_accepts(hits.moving_time, speed, accel, p.brake_time_offset)


@dataclass
class TrajectoryPlanner:
    """The ``trajectory`` manager (module docstring): ``policy(obs (B, O), rows=None) -> actions (B, A)``.

    ``max_speed`` and ``max_accel`` bound the bang-bang trajectories (defaults: the robot's);
    ``brake_accel`` (default: the acceleration) is the deceleration the moving obstacles' acceptor expects
    of the worker (``make_planner``: the worker's)."""

    field: Field
    robot: RobotSpec = dataclasses.field(default_factory=RobotSpec)
    action_form: str = "pose4"
    max_pos: float | None = None
    max_speed: float | None = None
    max_accel: float | None = None
    brake_accel: float | None = None
    collision_distance: float = 0.2
    params: TrajectoryParams = dataclasses.field(default_factory=TrajectoryParams)
    observation: str = "paper"
    action_frame: str = "field"
    zone_margin: float = 0.05  # m beyond a zone's clearance where a target inside it is moved (planners')

    def __post_init__(self) -> None:
        action_dim(self.action_form)
        if not self.collision_distance > 0:
            raise ValueError(f"collision_distance must be > 0, got {self.collision_distance!r}")
        self.forget(0)

    @property
    def limits(self) -> tuple[float, float]:
        """(speed, acceleration) of the trajectories."""
        speed = min(self.max_speed or self.robot.max_speed, self.robot.max_speed)
        return speed, min(self.max_accel or self.robot.max_accel, self.robot.max_accel)

    def forget(self, count: int) -> None:
        """Start afresh for ``count`` robots: no winners remembered, the random draws from ``seed`` again."""
        self.memory = np.full(count, np.nan + 0j)
        self.rng = np.random.default_rng(self.params.seed)

    def __call__(
        self, obs: np.ndarray, rows: np.ndarray | None = None, rules: RowRules | None = None
    ) -> np.ndarray:
        """Actions (B, A) for manager observations (B, O) of the robots ``rows`` (B,) ints, indices into
        the memory ``forget`` sized; without ``rows``, nothing remembered. ``rules``: the B robots' zones
        and speed limits (``hier_ssl.manager.planners``' docstring), none without."""
        scene = read_scene(obs, self.max_pos or self.field.max_pos, self.robot.max_speed, self.observation)
        last = np.full(len(obs), np.nan + 0j) if rows is None else self.memory[rows]
        chosen, winner = self.plan(scene, last, rules)
        if rows is not None:
            self.memory[rows] = np.where(np.isnan(winner), last, winner)
        poses = halted(scene, rules, subgoal_poses(scene, chosen))
        return scene_action(
            scene, poses, self.field, self.robot.max_speed, self.action_form, self.action_frame
        )

    def plan(
        self, scene: Scene, last: np.ndarray, rules: RowRules | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Sub-goal positions (N,) complex, and the winning sub-destinations relative to the robot-target
        line (N,) complex, NaN where none won; ``last`` (N,) the previous winners (NaN: none). Under
        ``rules``: towards ``ruled_scene``'s target, at each robot's speed limit, the zones still obstacles
        (``first_collisions``), no sub-destination inside a zone, a path that cannot avoid a zone replaced
        by one that goes round it (``detour``), and where the robot stops, the nearest legal point to it."""
        scene = ruled_scene(scene, rules, self.zone_margin)
        pos = scene.robot_pos @ np.array([1.0, 1j])
        vel = scene.robot_vel @ np.array([1.0, 1j])
        goal = scene.target[:, :2] @ np.array([1.0, 1j])
        q = scene.obstacle_pos @ np.array([1.0, 1j])
        u = scene.obstacle_vel @ np.array([1.0, 1j])
        obstacles = (q, u, np.abs(u) < self.params.motionless_speed)
        (speed, accel), radius = self.limits, self.collision_distance + self.params.obstacle_margin
        zones = None
        if rules is not None:
            # A halted robot's rows keep the planner's speed: ``halted`` gives them their own position.
            speed = np.where(rules.speed > 0, np.minimum(speed, rules.speed), speed)
            zones = (rules.zones, distances(rules.zones, scene.robot_pos) < 0.0)
        draws = self.draw(len(pos))
        direct = bang_bang_2d(pos, goal, vel, speed, accel)
        times = check_times(direct.total_time, self.params, bool(q.shape[1]) or zones is not None)
        path = (direct.at(times[:, None])[0], pos)
        hits = first_collisions(path, direct.total_time, obstacles, radius, self.params, zones)
        brake = self.brake_accel or accel
        still_ok, moving_ok = accepted(hits, pos, goal, np.abs(vel), brake, self.params)
        chosen, winner = goal.copy(), np.full(len(pos), np.nan + 0j)
        rows = np.flatnonzero(~(still_ok & moving_ok))
        if len(rows):
            # The direct path's rejection competes with the sub-paths' (first in ties: TIGERs tries it first).
            direct_miss = np.where(still_ok, np.abs(hits.moving_pos - goal) ** 2, np.inf)[rows]
            normal = np.concatenate([last[rows, None], draws[rows]], axis=1)
            ruled = None
            if zones is not None:
                ruled = (zones[0].take(rows), zones[1][rows], np.broadcast_to(speed, pos.shape)[rows])
            picked, won = self.detour(
                pos[rows],
                vel[rows],
                goal[rows],
                normal,
                direct_miss,
                (q[rows], u[rows], obstacles[2][rows]),
                ruled,
            )
            chosen[rows], winner[rows] = picked, won
        return chosen, winner

    def draw(self, n: int) -> np.ndarray:
        """Random sub-destinations (n, num_sub_destinations) relative to the robot-target line: complex
        scale * exp(i angle), the angle min_angle-max_angle (degrees) either side (SubDestRndGenerator)."""
        p = self.params
        span = math.radians(p.max_angle - p.min_angle)
        angle = self.rng.uniform(-span, span, (n, p.num_sub_destinations))
        angle += np.sign(angle) * math.radians(p.min_angle)
        return self.rng.uniform(p.min_scale, p.max_scale, angle.shape) * np.exp(1j * angle)

    def detour(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        goal: np.ndarray,
        normal: np.ndarray,
        direct_miss: np.ndarray,
        obstacles: tuple[np.ndarray, np.ndarray, np.ndarray],
        rules: tuple[Zones, np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Steps 2 and 3 for R robots whose direct path was rejected: (R,) sub-goal positions and winning
        sub-destinations (NaN: none). ``normal`` (R, S) the sub-destinations relative to the robot-target
        line (NaN: no such candidate); ``direct_miss`` (R,) the direct path's rejection score (inf: not
        among the rejected). ``rules``: the robots' zones (R, Z), which they already break, and their
        speeds (R,) (``plan``)."""
        p, (speed, accel) = self.params, self.limits
        zones = None
        if rules is not None:
            zones, speed = rules[:2], rules[2]
        speed = np.broadcast_to(np.asarray(speed, float), pos.shape)
        radius = self.collision_distance + p.obstacle_margin
        order = np.argsort(
            np.where(np.isnan(normal), np.inf, np.abs(np.angle(normal))), axis=1, kind="stable"
        )
        normal = np.take_along_axis(normal, order, axis=1)
        valid = ~np.isnan(normal)
        line = (goal - pos)[:, None]
        sub = pos[:, None] + np.where(valid, normal, 0.0) * line
        half_l, half_w = self.field.half_length, self.field.half_width
        sub = np.clip(sub.real, -half_l, half_l) + 1j * np.clip(sub.imag, -half_w, half_w)
        if zones is not None:  # a sub-destination inside a zone is no candidate
            inside = distances(zones[0].take(np.s_[:, None]), np.stack([sub.real, sub.imag], axis=-1))
            valid &= (inside >= 0.0).all(-1)
        # Sub-paths (R, S); the switch times (J,) of every path through a sub-destination, the sub-path
        # until the switch, then the target: tried in the order of TIGERs, the first acceptable wins.
        first = bang_bang_2d(pos[:, None], sub, vel[:, None], speed[:, None], accel)
        last_switch = float(first.total_time.max(initial=0.0))
        count = max(math.ceil((last_switch - p.initial_time_offset) / p.step_size_on_sub_path) - 1, 1)
        switch = np.array([p.initial_time_offset + p.step_size_on_sub_path * j for j in range(1, count + 1)])
        best, found = search(
            pos,
            vel,
            goal,
            np.ascontiguousarray(speed),
            accel,
            self.brake_accel or accel,
            np.ascontiguousarray(first.packed()),
            np.ascontiguousarray(first.total_time),
            valid,
            switch,
            direct_miss,
            *(np.ascontiguousarray(x) for x in obstacles),
            radius,
            (p.initial_time_offset, p.collision_check_step, p.t_max, p.threshold_max_collision_time),
            p.brake_time_offset,
            _zone_arrays(zones, len(pos)),
        )
        index = np.maximum(best - 1, 0) // count
        via = found & (best > 0)
        stop = pos
        if zones is not None:  # stopping inside a zone is no stop: the nearest legal point to it
            legal = nearest_legal(zones[0], np.stack([pos.real, pos.imag], axis=-1))
            stop = legal[:, 0] + 1j * legal[:, 1]
        picked = np.where(via, sub[np.arange(len(pos)), index], np.where(found, goal, stop))
        won = np.where(via, normal[np.arange(len(pos)), index], np.nan + 0j)
        return picked, won


def composite(first: Profile2D, then: Profile2D, switch: np.ndarray, t: float) -> np.ndarray:
    """Positions at time ``t`` of paths that follow ``first`` until ``switch`` and ``then`` after."""
    return np.where(t < switch, first.at(t)[0], then.at(t - switch)[0])


__all__ = ["Collisions", "TrajectoryParams", "TrajectoryPlanner", "accepted", "first_collisions"]
