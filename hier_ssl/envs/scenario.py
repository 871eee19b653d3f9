"""What a task is to the core: one class that owns its world, its observation, its reward and its ending.

A scenario says which field, how many controlled robots (M, agents ``manager_0 .. manager_{M-1}``) and
obstacle robots (K) a field holds, how the obstacles move (``groups``: obstacles under one behaviour of
``hier_ssl.world.obstacles``), and, as methods the core calls:

- ``make_world``: the world of N fields with the scenario's entities;
- ``reset_world_at``: where a reset places every robot and each controlled robot's target (a ``Placement``);
- ``observation``: the managers' observations (by default the observation layout ``config.observation``
  names, ``hier_ssl.envs.observations``);
- ``decision_terms`` and ``score``: each control step's reward and ending, success and collision (by
  default the rules of the task ``reward_task`` names, ``hier_ssl.envs.rules``, compiled);
- ``post_reset``, ``pre_step``, ``post_step`` and ``extra_render``: hooks after a reset has placed some
  fields, before and after the world steps and for drawing, which do nothing by default;
- ``episode_stats``: what a robot's episode statistics add to the core's (``stat_names``), none by
  default.

The core (``hier_ssl.envs.core``) runs every scenario the same way: hold sub-goals, worker, hooks, world,
score, end, reset. Robot order in every field: controlled robots 0..M-1, then obstacles M..M+K-1.

Subclasses: the paper's tasks (``hier_ssl.envs.tasks``: Baseline, Proposed, Obstacle, one robot) and
the multi-robot scenarios (``hier_ssl.envs.scenarios``: crossing, crowd, formation), each built from its
config (``EnvConfig`` or ``ScenarioConfig``); ``hier_ssl.envs.registry.make_scenario`` picks the class.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from hier_ssl.config import Strict, TaskSettings
from hier_ssl.envs.observations import NeighbourObservation, PaperObservation, observation_layout
from hier_ssl.envs.rules import DecisionTerms, Rules
from hier_ssl.manager import action_dim
from hier_ssl.world.entities import Entities
from hier_ssl.world.field import get_field
from hier_ssl.world.physics import RobotSpec, RobotState, World


@dataclass
class Placement:
    """Where a reset puts M controlled robots and K obstacles in F fields.

    Shapes: pos (F, M + K, 2) m and angle (F, M + K) rad, controlled robots first; target (F, M, 5) x, y,
    theta, vx, vy of each controlled robot; vel (F, M + K, 2) and ang_vel (F, M + K), at rest if None.
    In a world with B balls per field, ``ball_pos`` (F, B, 2) m places them (required there) and
    ``ball_vel`` (F, B, 2) m/s sets them rolling (at rest if None).
    """

    pos: np.ndarray
    angle: np.ndarray
    target: np.ndarray
    vel: np.ndarray | None = None
    ang_vel: np.ndarray | None = None
    ball_pos: np.ndarray | None = None
    ball_vel: np.ndarray | None = None


@dataclass(frozen=True)
class ObstacleGroup:
    """``count`` consecutive obstacles moved by one behaviour object, whose rows are the (field, obstacle)
    pairs in field-major order: one draw of its random numbers moves all of them."""

    behaviour: str
    options: dict[str, Any] = field(default_factory=dict)
    count: int = 1


class Scenario:
    """Base of every task: robots, obstacle groups, observation, reward and ending, interface sizes;
    subclasses set ``name``, ``reward_task``, ``defaults`` (config keys a config leaves out), ``Options``
    (a model of their own ``options``) and ``reset_world_at``, and override whichever other method their
    task changes."""

    name: ClassVar[str]
    defaults: ClassVar[dict[str, Any]] = {}
    Options: ClassVar[type[BaseModel]] = Strict
    # The rules of hier_ssl.manager that score a robot by default: "baseline", "proposed" or "obstacle".
    reward_task: str = "obstacle"
    # Sub-goal velocities are forced to 0 (the Proposed task's constraint; pose4 has none anyway).
    zero_velocity: bool = True
    # The observation ends with the game's columns (``hier_ssl.manager.game_observation``): a scripted
    # planner reads its rules there (``make_planner``).
    rules_in_observation: ClassVar[bool] = False

    def __init__(self, config: TaskSettings, num_agents: int, groups: list[ObstacleGroup]) -> None:
        self.config = config
        self.options = self.Options.model_validate(getattr(config, "options", {}))
        self.field = get_field(config.field)
        self.robot = RobotSpec()
        self.num_agents, self.groups = num_agents, groups
        self.num_obstacles = sum(group.count for group in groups)
        self.num_robots = num_agents + self.num_obstacles
        # Robots start and targets lie this far apart, so no reset begins inside the collision distance.
        self.gap = 2 * config.collision_distance
        margin = config.spawn_margin
        self.half = np.array([self.field.half_length - margin, self.field.half_width - margin])
        # The observation's normalisers (m, m/s, rad/s) and the field's half size that actions scale to.
        self.scales = {
            "max_pos": self.field.max_pos,
            "max_v": self.robot.max_speed,
            "max_w": self.robot.max_ang_speed,
            "half_length": self.field.half_length,
            "half_width": self.field.half_width,
        }
        # others[i]: every robot but robot i, the ones it sees and can hit; teammate: which are controlled.
        m, r = num_agents, self.num_robots
        others = [[j for j in range(r) if j != i] for i in range(m)]
        self.others = np.array(others, dtype=np.int64).reshape(m, r - 1)  # (m, 0) where r = 1
        self.teammate = self.others < m
        # The controlled robots' columns, None where every robot is controlled (no slicing to do).
        self._own = None if self.num_obstacles == 0 else np.s_[:, :m]

    # -- the world -----------------------------------------------------------------------------------------

    def make_world(self, num_fields: int) -> World:
        """The world of ``num_fields`` fields holding this scenario's entities: its robots, a group of the
        controlled ones first, then a group for each obstacle group (``groups``), in their order."""
        entities = Entities()
        entities.add("robot", self.num_agents, "controlled")
        for i, group in enumerate(self.groups):
            entities.add("robot", group.count, f"obstacles {i}: {group.behaviour}")
        config = self.config
        return World(num_fields, entities, self.field, dt=config.dt, substeps=config.substeps)

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> Placement:
        """Starts and targets of ``num_fields`` new episodes."""
        raise NotImplementedError

    def others_of(self, values: np.ndarray) -> np.ndarray:
        """Per-robot ``values`` (N, R, ...) of the robots each controlled robot sees, (N, M, R - 1, ...): a
        view for one controlled robot, else ``take`` (a tenth of the cost of indexing with the array)."""
        if self.num_agents == 1:
            return values[:, None, 1:]
        return values.take(self.others, axis=1)

    # -- observation ---------------------------------------------------------------------------------------

    @cached_property
    def observation_layout(self) -> PaperObservation | NeighbourObservation:
        """The default observation: the layout ``config.observation`` names."""
        config = self.config
        return observation_layout(config.observation, self, self.num_robots, config.neighbours, self.scales)

    @property
    def obs_dim(self) -> int:
        """Length of each controlled robot's manager observation."""
        return self.observation_layout.dim

    @property
    def act_dim(self) -> int:
        """Length of each manager action."""
        return action_dim(self.config.action_form)

    def observation(
        self, target: np.ndarray, state: RobotState, fields: np.ndarray | None = None
    ) -> np.ndarray:
        """The managers' observations (F, M, obs_dim) float32 of ``fields`` (F,) ints (None: every field)
        with targets (F, M, 5) and robots ``state`` (F, R): of the world's robots, or of tracked ones in the
        deploy view. The default layouts read the robots alone, not which fields they are in."""
        return self.observation_layout(target, state)

    # -- reward and ending ---------------------------------------------------------------------------------

    @cached_property
    def rules(self) -> Rules:
        """The default reward and ending: the task ``reward_task`` names, with the config's settings."""
        return Rules(self.reward_task, self.config)

    def decision_terms(self, target: np.ndarray, subgoal: np.ndarray) -> DecisionTerms | None:
        """What ``score`` can compute once a decision from the targets and sub-goals (N, M, 5), passed to
        it every control step until they change; None when nothing is."""
        return self.rules.decision_terms(target, subgoal)

    def score(
        self, terms: DecisionTerms | None, target: np.ndarray, subgoal: np.ndarray, world: World
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reward (N, M) float, success (N, M) bool and collision (N, M) bool of every controlled robot
        after a control step of ``world``; ``terms``: ``decision_terms`` of these targets and sub-goals.
        A robot leaves its episode on success or collision; the core keeps only the live robots' values."""
        s, own = world.state, self._own
        pos, angle, vel = (s.pos, s.angle, s.vel) if own is None else (s.pos[own], s.angle[own], s.vel[own])
        touching = world.robot_touch[:, : self.num_agents]
        return self.rules(terms, target, subgoal, pos, angle, vel, self.others_of(s.pos), touching)

    # -- hooks ---------------------------------------------------------------------------------------------

    # The per-robot episode statistics ``episode_stats`` adds to the core's ``info["task"]``.
    stat_names: ClassVar[tuple[str, ...]] = ()

    def episode_stats(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        """Statistics (E,) of the robots at flat ``rows`` (E,) (row = field * M + robot) whose episode ended
        in the step just taken, before any reset: the ``stat_names`` columns, which the core adds to its
        own in ``info["task"]``, and any of the core's own it replaces. None by default."""
        return {}

    def post_reset(self, core: Any, fields: np.ndarray, placement: Placement) -> None:
        """After the core has placed ``fields`` (F,) ints as ``placement`` says, before their first
        observation: the scenario's own per-field state of them starts afresh. Nothing by default."""

    def pre_step(self, core: Any, command: np.ndarray) -> None:
        """Before the world of ``core`` (the ``HierarchicalCore`` running this scenario, which imports this
        module) steps: ``command`` (N, R, 3), every robot's velocity command in its own frame, may be
        changed in place. Nothing by default."""

    def post_step(self, core: Any) -> None:
        """After the world of ``core`` steps, before ``score``. Nothing by default."""

    def extra_render(self, ax: Any, field_index: int) -> None:
        """Draw what the scenario adds to field ``field_index`` (matplotlib ``ax``, field coordinates in m)
        under the robots. Nothing by default."""

    def scatter(
        self,
        rng: np.random.Generator,
        num_fields: int,
        count: int,
        low: np.ndarray,
        high: np.ndarray,
        placed: np.ndarray | None = None,
    ) -> np.ndarray:
        """``count`` points (num_fields, count, 2) uniform in the box [low, high], each at least ``gap``
        from the others and from ``placed`` (num_fields, P, 2). Rejection sampling, vectorised over
        fields: a point that is too close to an earlier one or to ``placed`` is drawn again until none
        is."""
        pts = rng.uniform(low, high, (num_fields, count, 2))
        placed = np.zeros((num_fields, 0, 2)) if placed is None else placed
        earlier = np.tril(np.ones((count, count), dtype=bool), k=-1)
        for _ in range(1000):
            near = np.linalg.norm(pts[:, :, None] - pts[:, None], axis=-1) < self.gap
            near_placed = np.linalg.norm(pts[:, :, None] - placed[:, None], axis=-1) < self.gap
            bad = (near & earlier).any(axis=2) | near_placed.any(axis=2)
            if not bad.any():
                return pts
            pts[bad] = rng.uniform(low, high, (int(bad.sum()), 2))
        raise RuntimeError(
            f"scenario {self.name!r}: cannot place {count} robots {self.gap} m apart in "
            f"[{low}, {high}]; use fewer robots or a larger area"
        )


__all__ = ["ObstacleGroup", "Placement", "Scenario"]
