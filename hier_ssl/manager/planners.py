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
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hier_ssl.manager.actions import action_dim, encode_subgoal
from hier_ssl.manager.candidate_points import candidate_points, candidate_weights
from hier_ssl.manager.scene import Scene, read_scene, scene_action, subgoal_poses
from hier_ssl.manager.trajectory import TrajectoryParams, TrajectoryPlanner
from hier_ssl.world.field import Field, get_field
from hier_ssl.world.frames import as_complex
from hier_ssl.world.physics import RobotSpec

if TYPE_CHECKING:
    from hier_ssl.config import TaskSettings

PLANNERS = ("direct", "sampling", "trajectory")


@dataclass(frozen=True)
class DirectPlanner:
    """The sub-goal is the target pose (its velocity too, where the action form carries one)."""

    field: Field
    action_form: str = "pose4"
    max_pos: float | None = None  # observation normaliser; default field.max_pos
    max_v: float = 2.5
    observation: str = "paper"  # layout of the observations read (``read_scene``)
    action_frame: str = "field"  # frame of the actions written (``decode_subgoal``)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Actions (N, A) for manager observations (N, O)."""
        max_pos = self.max_pos or self.field.max_pos
        scene = read_scene(obs, max_pos, self.max_v, self.observation)
        fld = self.field
        return encode_subgoal(
            scene.target,
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
    if none is, the candidate farthest from the obstacles over the prediction window (evasion).

    Candidates, per field: the target; the robot's own position (stop); two rings of ``ring_points``
    around each obstacle; ``num_samples`` points drawn once (seeded) in the frame of the robot-target line
    (a fraction 0.1-0.9 of the way, up to ``across`` metres to the side); a ring of radius ``escape``
    around the robot. All are clipped to the field, where a sub-goal can be. The work is (N, M) complex
    arrays over ``horizon / dt`` steps, no per-field loop: about 0.3 ms per field and call (1000 fields,
    one obstacle, 50 candidates: 0.27 s).
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

    def __post_init__(self) -> None:
        action_dim(self.action_form)
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

    def rollout(self, scene: Scene, cand: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each candidate's trajectory scored, all (N, M): arrival time in s (horizon + remaining distance
        / speed when it does not arrive); the smallest clearance in m to the nearest predicted obstacle
        beyond the growing safety distance; the same beyond the fixed one (collision distance + margin).
        Clearances are +inf without obstacles and only count before arrival, within check_horizon."""
        n, m = cand.shape
        dt, speed = self.dt, self.speed
        step = self.robot.max_accel * dt
        two_brake = 2.0 * (self.brake_accel or self.robot.max_accel)
        goal = (scene.target[:, 0] + 1j * scene.target[:, 1])[:, None]
        p = np.repeat((scene.robot_pos[:, 0] + 1j * scene.robot_pos[:, 1])[:, None], m, axis=1)
        v = np.repeat((scene.robot_vel[:, 0] + 1j * scene.robot_vel[:, 1])[:, None], m, axis=1)
        q = (scene.obstacle_pos[..., 0] + 1j * scene.obstacle_pos[..., 1])[:, None, :]  # (N, 1, K)
        u = (scene.obstacle_vel[..., 0] + 1j * scene.obstacle_vel[..., 1])[:, None, :]
        has_obstacles = q.shape[2] > 0
        # Heading for the sub-goal rather than the target: every candidate but the target itself, until the
        # sub-goal is no longer held and the robot is within switch_radius of it.
        via = np.abs(cand - goal) > 0.0
        if self.hold <= 0.0:
            via &= np.abs(cand - p) > self.switch_radius
        arrival = np.full((n, m), np.inf)
        clearance = np.full((n, m), np.inf)
        hard = np.full((n, m), np.inf)
        near = np.full((n, m), np.inf)
        steps = int(np.ceil(self.horizon / dt))
        for i in range(1, steps + 1):
            t = i * dt
            # Bang-bang towards the current goal: braking curve, speed cap, land on it in the last step.
            aim = np.where(via, cand, goal)
            delta = aim - p
            dist = np.abs(delta)
            want = np.minimum(np.minimum(np.sqrt(two_brake * dist), speed), dist / dt)
            change = delta * (want / np.maximum(dist, 1e-9)) - v
            size = np.abs(change)
            v = v + change * np.minimum(1.0, step / np.maximum(size, 1e-12))
            p = p + v * dt
            if t >= self.hold:  # the worker drives to the sub-goal for as long as it is held
                via &= np.abs(cand - p) > self.switch_radius
            moving = np.isinf(arrival)
            if has_obstacles:
                seen = min(t, self.predict_horizon)
                gap = np.abs(p[:, :, None] - (q + u * seen)).min(axis=2)
                gap = np.where(moving, gap - (self.collision_distance + self.margin), np.inf)
                hard = np.minimum(hard, gap)
                if t <= self.predict_horizon:
                    near = np.minimum(near, gap)
                clearance = np.minimum(clearance, gap - self.margin_growth * seen**1.5)
            arrival = np.where(moving & ~via & (np.abs(goal - p) < self.arrive_radius), t, arrival)
            if not np.isinf(arrival).any():
                break
        late = np.isinf(arrival)
        arrival[late] = self.horizon + np.abs(goal - p)[late] / speed
        return arrival, clearance, hard, near

    def score(self, scene: Scene, cand: np.ndarray) -> np.ndarray:
        """How the planner ranks the candidates (N, M): the highest is its choice. Within the best tier it
        can choose from, minus the arrival time (the candidates clear of the growing safety distance;
        failing those, the ones clear of the fixed one), -inf outside it; failing both, the distance kept
        from the obstacles over the prediction window (1e3 without obstacles)."""
        arrival, clearance, hard, near = self.rollout(scene, cand)
        safe, close = clearance >= 0.0, hard >= 0.0
        score = np.where(np.isfinite(near), near, 1e3)
        score = np.where(close.any(1, keepdims=True), np.where(close, -arrival, -np.inf), score)
        return np.where(safe.any(1, keepdims=True), np.where(safe, -arrival, -np.inf), score)

    def plan(self, scene: Scene) -> np.ndarray:
        """The chosen sub-goal poses (N, 5): x, y, the target's heading, zero velocity."""
        cand = self.candidates(scene)
        best = np.argmax(self.score(scene, cand), axis=1)  # ties to the earlier candidate
        return self.subgoals(scene, cand[np.arange(len(cand)), best])

    subgoals = staticmethod(subgoal_poses)

    def read(self, obs: np.ndarray) -> Scene:
        return read_scene(obs, self.max_pos or self.field.max_pos, self.robot.max_speed, self.observation)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Actions (N, A) for manager observations (N, O)."""
        scene = self.read(obs)
        return self.action(scene, self.plan(scene))

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
