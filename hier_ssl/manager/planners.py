"""Scripted reference managers: numpy policies over manager observations, usable wherever a learned
manager is (``policy(obs (N, O)) -> actions (N, A)`` in [-1, 1]).

- ``direct``: the sub-goal is the target. In an empty field this is the natural lower bound on planning
  effort (CPAD 0) and, with a time-optimal worker, on episode length.
- ``sampling``: a classical obstacle-avoiding planner as SSL teams run it. Every manager step it samples
  intermediate sub-goals, predicts the obstacles at constant velocity, rolls out the robot's bang-bang
  trajectory "to the sub-goal, then to the target" for every candidate, and keeps the candidate that
  reaches the target soonest without coming within the collision distance (plus a safety margin that
  grows with the prediction time). Nothing is remembered between calls: the same observation always gives
  the same action, so a seeded evaluation is reproducible and the policy may be called on any subset of
  fields.

Everything a planner knows about the world comes from the observation (docs/paper.md "Observations", or the
"neighbours" layout, whose neighbours it treats as obstacles) and from constants given at construction: the
field, the robot's limits, the action form and frame.

The rules (docs/guide/ssl-game.md "Planners and the rules"): every planner, ``trajectory`` included, takes
``rules=`` beside the observations, a ``hier_ssl.game.legal.RowRules``: the zones of each row's robot
(arrays (B, S), ``forbidden_zones`` flattened field by field by ``row_rules``) and its speed limit (B,).
Without it (the default) a planner does exactly what it did before the rules. With it: the target becomes
its nearest point ``zone_margin`` beyond every zone's clearance (``ruled_scene``: ``nearest_legal``) and its
velocity is capped at the limit; ``direct`` hands that target; ``sampling`` rolls out at the limit and ranks
only legal candidates whose straight legs keep clear of the zones (``SamplingPlanner.zone_detour``);
``trajectory`` plans at the limit with the zones as still obstacles (``first_collisions``) and no
sub-destination inside one, going round a zone it cannot pass in one sub-path (``plan``'s fallback). A
sub-goal inside a zone is never handed. A robot in HALT (limit 0) is handed its own position, at rest.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hier_ssl.game.legal import RowRules
from hier_ssl.manager.actions import action_dim, encode_subgoal
from hier_ssl.manager.candidate_points import candidate_points, candidate_weights
from hier_ssl.manager.sampling_rollouts import rollouts, zone_detours
from hier_ssl.manager.scene import Scene, halted, read_scene, ruled_scene, scene_action, subgoal_poses
from hier_ssl.manager.trajectory import TrajectoryParams, TrajectoryPlanner
from hier_ssl.world.field import Field, get_field
from hier_ssl.world.frames import as_complex
from hier_ssl.world.physics import RobotSpec

if TYPE_CHECKING:
    from hier_ssl.config import TaskSettings

PLANNERS = ("direct", "sampling", "trajectory")
TRAPPED = ("evade", "brake")  # what ``SamplingPlanner`` does where no candidate keeps clear
# m beyond a zone's clearance where the planners move a target inside it: a path may then reach it from the
# side without grazing the zone (a target on a ball's circle is reachable only from outside its tangent).
ZONE_MARGIN = 0.05


@dataclass(frozen=True)
class DirectPlanner:
    """The sub-goal is the target pose (its velocity too, where the action form carries one)."""

    field: Field
    action_form: str = "pose4"
    max_pos: float | None = None  # observation normaliser; default field.max_pos
    max_v: float = 2.5
    observation: str = "paper"  # layout of the observations read (``read_scene``)
    action_frame: str = "field"  # frame of the actions written (``decode_subgoal``)
    zone_margin: float = ZONE_MARGIN  # m beyond a zone's clearance where a target inside it is moved

    def __call__(self, obs: np.ndarray, rules: RowRules | None = None) -> np.ndarray:
        """Actions (N, A) for manager observations (N, O), under the rules of the N robots (module
        docstring) where given."""
        max_pos = self.max_pos or self.field.max_pos
        scene = read_scene(obs, max_pos, self.max_v, self.observation)
        ruled = ruled_scene(scene, rules, self.zone_margin)
        fld = self.field
        # The action frame's target is the observation's (the environment's), not the one made legal.
        return encode_subgoal(
            halted(scene, rules, ruled.target),
            self.action_form,
            fld.half_length,
            fld.half_width,
            self.max_v,
            frame=self.action_frame,
            target=scene.target,
        )


@dataclass(frozen=True)
class SamplingPlanner:
    """Sample sub-goals, roll out each "robot -> sub-goal -> target" bang-bang trajectory against
    obstacles moving at constant velocity, keep the fastest collision-free one; replan every call.

    Rollout: a point mass at ``dt`` resolution whose velocity follows the braking curve
    min(speed, sqrt(2 brake_accel d), d / dt) towards its current aim, changing by at most
    ``robot.max_accel * dt`` per step. It aims at the sub-goal while the sub-goal is held (``hold`` =
    frame_skip * dt: the worker drives to it, stopping there if it gets there) and until within
    ``switch_radius`` of it, then at the target; it "arrives" within ``arrive_radius`` of the target.

    Obstacles: predicted at their observed constant velocity for ``predict_horizon`` seconds, then held
    where that leaves them. An obstacle robot that moves at random drifts from the prediction by roughly
    0.2 m (1 sigma) after 1 s, growing like t^1.5 (its velocity is a random walk), so the safety distance
    is collision_distance + margin + margin_growth * min(t, predict_horizon)^1.5. Clearances count
    until arrival, over the whole rollout.

    Choice: the soonest arrival among candidates clear of the growing safety distance (ties to the earlier
    candidate: the target first, so an empty field gives ``direct`` unless a sub-goal is faster); if none
    is, the soonest among those clear of collision_distance + margin (e.g. a target next to an obstacle);
    if none is, the candidate farthest from the obstacles over the prediction window (evasion). With
    ``trapped="brake"``, a robot whose every candidate meets a predicted obstacle within the prediction
    window (the evasion's best too) stops where it is instead: where the robots that trap it brake as
    well (teammates planning alike), that keeps more of them than the evasion does (their ball placement;
    on STOP and the match, where opponents come at our robots, it keeps fewer).

    Candidates, per field: the target; the robot's own position (stop); two rings of ``ring_points``
    around each obstacle; ``num_samples`` points drawn once (seeded) in the frame of the robot-target line
    (a fraction 0.1-0.9 of the way, up to ``across`` metres to the side); a ring of radius ``escape``
    around the robot. All are clipped to the field, where a sub-goal can be.

    The rollouts are one compiled loop (``hier_ssl.manager.sampling_rollouts.rollouts``): a row's
    candidates step together, as vector instructions, each until it arrives; a choice (``plan``) ends a
    row's rollouts the step after a candidate arrives clear, every other being later. About 0.04 ms per
    field and call (1000 fields, one obstacle, 50 candidates: 36 ms of CPU; 255 ms as numpy arrays
    before); a team of 11 in STOP, 114 candidates each, 1.2 ms, 1.7-1.8 ms under the rules (13-21 and
    15-16 ms before; ``benchmarks/team_decision.py``).
    """

    field: Field
    robot: RobotSpec = dataclasses.field(default_factory=RobotSpec)
    action_form: str = "pose4"
    max_pos: float | None = None
    max_speed: float | None = None  # default robot.max_speed; the worker's cap where it is lower
    brake_accel: float | None = None  # default robot.max_accel
    collision_distance: float = 0.2
    margin: float = 0.08
    margin_growth: float = 0.25  # m of extra clearance per s^1.5 of prediction
    predict_horizon: float = 1.5  # s of constant-velocity motion; obstacles then hold their place
    horizon: float = 5.0
    dt: float = 0.05
    switch_radius: float = 0.2
    hold: float = 0.0  # s the sub-goal is held (frame_skip * dt): no switching to the target before
    arrive_radius: float = 0.05
    rings: tuple[float, ...] = (0.4, 0.65)
    ring_points: int = 8
    num_samples: int = 24
    escape: float = 0.6  # radius of the ring of candidates around the robot (m)
    across: float = 1.5
    seed: int = 0
    observation: str = "paper"  # as DirectPlanner's
    action_frame: str = "field"
    zone_margin: float = ZONE_MARGIN  # as DirectPlanner's
    trapped: str = "evade"  # or "brake" (above)

    def __post_init__(self) -> None:
        action_dim(self.action_form)
        if self.trapped not in TRAPPED:
            raise ValueError(f"SamplingPlanner.trapped must be one of {TRAPPED}, got {self.trapped!r}")
        for name in ("horizon", "dt", "collision_distance", "switch_radius", "arrive_radius"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SamplingPlanner.{name} must be > 0, got {getattr(self, name)!r}")
        rng = np.random.default_rng(self.seed)
        along = rng.uniform(0.1, 0.9, self.num_samples)
        across = rng.uniform(-self.across, self.across, self.num_samples)
        turns = np.exp(2j * np.pi * np.arange(self.ring_points) / self.ring_points)
        # The frozen samples, rings and escapes; ``candidate_maps`` turns them into the candidates' maps.
        ring = (np.asarray(self.rings)[:, None] * turns).ravel()
        object.__setattr__(self, "_offsets", (ring, along, across, self.escape * turns))
        object.__setattr__(self, "_maps", {})

    @property
    def speed(self) -> float:
        return min(self.max_speed or self.robot.max_speed, self.robot.max_speed)

    def candidate_maps(self, num_obstacles: int) -> tuple[np.ndarray, np.ndarray]:
        """The maps (M, 2 + K), (M, 2, 2) of ``candidate_points`` with ``num_obstacles`` obstacles."""
        if num_obstacles not in self._maps:
            self._maps[num_obstacles] = candidate_weights(*self._offsets, num_obstacles)
        return self._maps[num_obstacles]

    def candidates(self, scene: Scene) -> np.ndarray:
        """Sub-goal positions (N, M) complex, clipped to the field; column 0 is the target
        (``hier_ssl.manager.candidate_points``)."""
        points = np.concatenate(
            [scene.target[:, None, 0:2], scene.robot_pos[:, None], scene.obstacle_pos], axis=1
        )
        half = np.array([self.field.half_length, self.field.half_width])
        cand = candidate_points(points, *self.candidate_maps(scene.obstacle_pos.shape[1]), -half, half)
        return as_complex(cand)

    def rollout(
        self,
        scene: Scene,
        cand: np.ndarray,
        speed: np.ndarray | None = None,
        choosable: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Each candidate's trajectory scored, all (N, M): arrival time in s (horizon + remaining distance
        / speed when it does not arrive); the smallest clearance in m to the nearest predicted obstacle
        beyond the growing safety distance; the same beyond the fixed one (collision distance + margin);
        the same within the prediction window. Clearances are +inf without obstacles and only count before
        arrival. ``speed`` (N,) m/s caps each row's speed below the planner's (the rules' limit).

        ``choosable`` (N, M) bool, for a choice only (``plan``): candidates are rolled out in order, and one
        is dropped (arrival +inf, clearances -inf) once it is later than the soonest choosable candidate
        clear of the growing safety distance so far, which it can no longer beat."""
        n, m = cand.shape
        limit = np.full(n, self.speed) if speed is None else np.minimum(self.speed, speed)
        out = rollouts(
            np.ascontiguousarray(scene.robot_pos, float),
            np.ascontiguousarray(scene.robot_vel, float),
            np.ascontiguousarray(scene.target[:, 0:2], float),
            np.stack([cand.real, cand.imag], axis=-1),
            limit,
            np.ascontiguousarray(scene.obstacle_pos, float),
            np.ascontiguousarray(scene.obstacle_vel, float),
            np.ones((n, m), bool) if choosable is None else np.ascontiguousarray(choosable),
            choosable is not None,
            (self.dt, self.horizon, self.hold, self.switch_radius, self.arrive_radius),
            (self.robot.max_accel * self.dt, 2.0 * (self.brake_accel or self.robot.max_accel)),
            (self.collision_distance + self.margin, self.margin_growth, self.predict_horizon),
        )
        return out[0], out[1], out[2], out[3]

    def score(
        self, scene: Scene, cand: np.ndarray, rules: RowRules | None = None, choice: bool = False
    ) -> np.ndarray:
        """How the planner ranks the candidates (N, M): the highest is its choice. Within the best tier it
        can choose from, minus the arrival time (the candidates clear of the growing safety distance;
        failing those, the ones clear of the fixed one), -inf outside it; failing both, the distance kept
        from the obstacles over the prediction window (1e3 without obstacles). Under ``rules``, only the
        candidates clear of the zones are ranked so; a row without any ranks by ``zone_detour``.
        ``choice``: only the highest is right (``rollout``'s ``choosable``), the rest may be -inf."""
        return self.ranking(scene, cand, rules, choice)[0]

    def ranking(
        self, scene: Scene, cand: np.ndarray, rules: RowRules | None = None, choice: bool = False
    ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
        """``score`` and what it ranked by, all (N, M): ``rollout``'s four (arrival, clearance, hard and
        near clearance) and whether each candidate is clear of the zones (True without ``rules``); a
        learned ranking reads them (``hier_ssl.policies.candidate_residual``)."""
        # A halted robot's row keeps the planner's speed: ``halted`` gives it its own position anyway.
        limit = None if rules is None else np.where(rules.speed > 0, rules.speed, np.inf)
        clear = None
        if rules is not None:
            clear, detour = self.zone_detour(scene, cand, rules)
        choosable = (np.ones(cand.shape, bool) if clear is None else clear) if choice else None
        rolled = self.rollout(scene, cand, limit, choosable)
        arrival, clearance, hard, near = rolled
        safe, close = clearance >= 0.0, hard >= 0.0
        score = np.where(np.isfinite(near), near, 1e3)
        if clear is not None:
            safe, close = safe & clear, close & clear
            score = np.where(clear, score, -np.inf)
        score = np.where(close.any(1, keepdims=True), np.where(close, -arrival, -np.inf), score)
        score = np.where(safe.any(1, keepdims=True), np.where(safe, -arrival, -np.inf), score)
        if clear is not None:
            score = np.where(clear.any(1, keepdims=True), score, detour)
        if self.trapped == "brake":
            # The choice meets an obstacle over the whole rollout and within the prediction window (where
            # it is the evasion's, every candidate does): the robot's own position (column 1) ranks first,
            # the rest keep their order behind it.
            best = score.argmax(1)[:, None]
            stuck = (np.take_along_axis(hard, best, 1) < 0.0) & (np.take_along_axis(near, best, 1) < 0.0)
            score[stuck[:, 0], 1] = score[stuck[:, 0]].max(1) + 1.0
        return score, rolled, np.ones(cand.shape, bool) if clear is None else clear

    @staticmethod
    def zone_detour(scene: Scene, cand: np.ndarray, rules: RowRules) -> tuple[np.ndarray, np.ndarray]:
        """(N, M) bool, the candidates the rules let the planner rank as usual, and (N, M) the ranking of a
        row that has none. A sub-goal inside a zone is never chosen. Clear: a legal sub-goal whose legs
        (robot -> sub-goal, sub-goal -> target, straight) both keep clear of every zone, as the rollout's
        obstacles. A row without one (a target behind a zone, out of reach of one sub-goal) takes, of the
        sub-goals whose first leg is clear (the leg the robot drives before it replans), the one whose
        second leg comes least into the zones, to go round them over the next decisions; a leg across a
        capsule's segment (a ball placement's corridor) is as deep as it crosses it from the end a robot
        can pass round (``hier_ssl.game.segments.axis_depth``), so that a way round an end wins; failing
        those, the target, legal (``ruled_scene``). A zone the robot already breaks does not bar its first
        leg: it is leaving it."""
        zones = rules.zones
        clear, detour = zone_detours(
            scene.robot_pos @ np.array([1.0, 1j]),
            scene.target[:, 0:2] @ np.array([1.0, 1j]),
            np.ascontiguousarray(cand, complex),
            np.ascontiguousarray(zones.kind, np.int64),
            np.ascontiguousarray(zones.shape, float),
            np.ascontiguousarray(zones.clearance, float),
        )
        return clear, detour

    def plan(self, scene: Scene, rules: RowRules | None = None) -> np.ndarray:
        """The chosen sub-goal poses (N, 5): x, y, the target's heading, zero velocity; under ``rules``
        (module docstring), of ``ruled_scene``'s target."""
        scene = ruled_scene(scene, rules, self.zone_margin)
        cand = self.candidates(scene)
        best = np.argmax(self.score(scene, cand, rules, choice=True), axis=1)  # ties to the earlier one
        return halted(scene, rules, self.subgoals(scene, cand[np.arange(len(cand)), best]))

    subgoals = staticmethod(subgoal_poses)

    def read(self, obs: np.ndarray) -> Scene:
        return read_scene(obs, self.max_pos or self.field.max_pos, self.robot.max_speed, self.observation)

    def __call__(self, obs: np.ndarray, rules: RowRules | None = None) -> np.ndarray:
        """Actions (N, A) for manager observations (N, O), under the rules of the N robots where given."""
        scene = self.read(obs)
        return self.action(scene, self.plan(scene, rules))

    def action(self, scene: Scene, subgoal: np.ndarray) -> np.ndarray:
        """The actions (N, A) that name sub-goal poses (N, 5) in ``scene``'s task."""
        return scene_action(
            scene, subgoal, self.field, self.robot.max_speed, self.action_form, self.action_frame
        )


def build_planner(
    name: str, config: TaskSettings, worker: object = None, **options: object
) -> DirectPlanner | SamplingPlanner | TrajectoryPlanner:
    """The scripted manager ``name`` ("direct", "sampling" or "trajectory") for environments built from
    ``config``.

    The sampling and trajectory planners use the world's robot limits, the speed capped by the worker's
    own cap where it states one (``max_speed``: the paper's worker stops at 2.2 m/s), and the worker's
    braking acceleration where it has one (the sampling planner's rollouts, the trajectory planner's
    acceptor). ``worker`` is a ready worker object, which both need (``hier_ssl.envs.planners.make_planner``
    resolves one from a spec or the config). ``options`` override planner settings (e.g. ``margin=0.1``;
    for "trajectory", the fields of ``TrajectoryParams`` too, e.g. ``num_sub_destinations=8``).
    """
    if name not in PLANNERS:
        raise ValueError(f"unknown planner {name!r}; known: {list(PLANNERS)}")
    fld, robot = get_field(config.field), RobotSpec()
    layout = {"observation": config.observation, "action_frame": config.action_frame}
    if name == "direct":
        return DirectPlanner(fld, config.action_form, max_v=robot.max_speed, **layout, **options)
    if worker is None:
        raise ValueError(f"the {name} planner needs a worker: hier_ssl.envs.planners.make_planner makes one")
    brake = getattr(worker, "brake_accel", None)
    limits = {
        "max_speed": getattr(worker, "max_speed", robot.max_speed),
        "collision_distance": config.collision_distance,
    }
    brake = brake if brake is not None else robot.max_accel * getattr(worker, "margin", 1.0)
    if name == "trajectory":
        fields = {f.name for f in dataclasses.fields(TrajectoryParams)}
        params = TrajectoryParams(**{k: v for k, v in options.items() if k in fields})
        rest = {k: v for k, v in options.items() if k not in fields}
        # The robot's acceleration, less the worker's reserve where it keeps one: the paper worker
        # accelerates at the robot's limit and brakes earlier, which a symmetric bang-bang cannot model;
        # its first second, where the moving obstacles are, is the acceleration (docs/research-notes.md,
        # "The trajectory planner's settings").
        accel = robot.max_accel * getattr(worker, "margin", 1.0)
        settings = {**limits, "max_accel": accel, "brake_accel": brake, **layout, **rest}
        return TrajectoryPlanner(fld, robot, config.action_form, params=params, **settings)
    settings = {
        **limits,
        "brake_accel": brake,
        "arrive_radius": config.d_th,
        "hold": config.frame_skip * config.dt,
        **layout,
        **options,
    }
    return SamplingPlanner(fld, robot, config.action_form, **settings)


__all__ = [
    "PLANNERS",
    "DirectPlanner",
    "SamplingPlanner",
    "Scene",
    "TrajectoryParams",
    "TrajectoryPlanner",
    "build_planner",
    "read_scene",
]
