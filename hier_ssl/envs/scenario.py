"""What a task is to the core: a small class that places robots and names the rules, over the shared world.

A scenario says which field, how many controlled robots (M, agents ``manager_0 .. manager_{M-1}``) and
obstacle robots (K) a field holds, how the obstacles move (``groups``: obstacles under one behaviour of
``hier_ssl.world.obstacles``), how starts and targets are drawn (``reset_world_at``), which observation
layout the managers read, and which task's reward and success rules score them (``reward_task``). The
core (``hier_ssl.envs.core``) runs every scenario the same way: hold sub-goals, worker, world, score,
end, reset. Robot order in every field: controlled robots 0..M-1, then obstacles M..M+K-1.

Subclasses: the paper's tasks (``hier_ssl.envs.tasks``: Baseline, Proposed, Obstacle, one robot) and
the multi-robot scenarios (``hier_ssl.envs.scenarios``: crossing, crowd, formation), each built from its
config (``EnvConfig`` or ``ScenarioConfig``); ``hier_ssl.envs.registry.make_scenario`` picks the class.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from hier_ssl.config import Strict, TaskSettings
from hier_ssl.manager import action_dim, manager_obs_dim
from hier_ssl.manager.neighbours import neighbour_obs_dim
from hier_ssl.world.field import get_field
from hier_ssl.world.physics import RobotSpec


@dataclass
class Layout:
    """Where a reset puts M controlled robots and K obstacles in m fields.

    Shapes: pos (m, M + K, 2) m and angle (m, M + K) rad, controlled robots first; target (m, M, 5) x, y,
    theta, vx, vy of each controlled robot; vel (m, M + K, 2) and ang_vel (m, M + K), at rest if None.
    """

    pos: np.ndarray
    angle: np.ndarray
    target: np.ndarray
    vel: np.ndarray | None = None
    ang_vel: np.ndarray | None = None


@dataclass(frozen=True)
class ObstacleGroup:
    """``count`` consecutive obstacles moved by one behaviour object, whose rows are the (field, obstacle)
    pairs in field-major order: one draw of its random numbers moves all of them."""

    behaviour: str
    options: dict[str, Any] = field(default_factory=dict)
    count: int = 1


class Scenario:
    """Base of every task: robots, obstacle groups, rules and interface sizes; subclasses set ``name``,
    ``reward_task``, ``defaults`` (config keys a config leaves out), ``Options`` (a model of their own
    ``options``) and ``reset_world_at``."""

    name: ClassVar[str]
    defaults: ClassVar[dict[str, Any]] = {}
    Options: ClassVar[type[BaseModel]] = Strict
    # The rules of hier_ssl.manager that score a robot: "baseline", "proposed" or "obstacle".
    reward_task: str = "obstacle"
    # Sub-goal velocities are forced to 0 (the Proposed task's constraint; pose4 has none anyway).
    zero_velocity: bool = True

    def __init__(self, config: TaskSettings, num_agents: int, groups: list[ObstacleGroup]) -> None:
        self.config = config
        self.options = self.Options.model_validate(getattr(config, "options", {}))
        self.field = get_field(config.field)
        self.robot = RobotSpec()
        self.num_agents, self.groups = num_agents, groups
        self.num_obstacles = sum(group.count for group in groups)
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

    @property
    def observation(self) -> str:
        """The managers' observation layout: "paper" (one robot, its obstacles), "neighbours" or
        "encounters"."""
        return self.config.observation

    @property
    def obs_dim(self) -> int:
        """Length of each controlled robot's manager observation."""
        if self.observation != "paper":
            return neighbour_obs_dim(self.config.neighbours, self.observation == "encounters")
        return manager_obs_dim(self.num_obstacles)

    @property
    def act_dim(self) -> int:
        """Length of each manager action."""
        return action_dim(self.config.action_form)

    def reset_world_at(self, m: int, rng: np.random.Generator) -> Layout:
        """Starts and targets of ``m`` new episodes."""
        raise NotImplementedError

    def scatter(
        self,
        rng: np.random.Generator,
        m: int,
        count: int,
        low: np.ndarray,
        high: np.ndarray,
        placed: np.ndarray | None = None,
    ) -> np.ndarray:
        """``count`` points (m, count, 2) uniform in the box [low, high], each at least ``gap`` from the
        others and from ``placed`` (m, P, 2). Rejection sampling, vectorised over fields: a point that is
        too close to an earlier one or to ``placed`` is drawn again until none is."""
        pts = rng.uniform(low, high, (m, count, 2))
        placed = np.zeros((m, 0, 2)) if placed is None else placed
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


__all__ = ["Layout", "ObstacleGroup", "Scenario"]
