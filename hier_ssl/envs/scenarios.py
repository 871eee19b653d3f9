"""Multi-robot field scenarios: M controlled robots (1..11) sharing one manager policy, K obstacle robots
(0..11) moving under one behaviour, on the hardware-challenge or Division A/B field.

Each is a small class over ``hier_ssl.envs.scenario.Scenario`` built from a ``ScenarioConfig``; its
``defaults`` change that config's defaults and its ``Options`` are its own ``options``. Observation (the
"neighbours" observation layout), sub-goal decoding, rewards (the Obstacle task's, or the Proposed task's
for a robot alone in its field), success and collision rules are shared by all of them.

- ``crossing``: M robots on a circle swap to the antipodal points, all through the centre (Division B).
- ``crowd``: robots cross the field, either way, through a band of random-walking obstacles.
- ``formation``: M robots take the slots of a grid formation while obstacles move about the field.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from hier_ssl.config import ScenarioConfig, Strict
from hier_ssl.envs.scenario import ObstacleGroup, Placement, Scenario


class FieldScenario(Scenario):
    """A multi-robot scenario: ``config.num_agents`` controlled robots and ``config.num_obstacles``
    obstacles, all moved by ``config.obstacles``'s behaviour."""

    def __init__(self, config: ScenarioConfig) -> None:
        k, behaviour = config.num_obstacles, config.obstacles
        groups = [ObstacleGroup(behaviour.behaviour, behaviour.options, k)] if k else []
        super().__init__(config, config.num_agents, groups)
        # A robot alone in its field has nothing to avoid: the obstacle terms would have no obstacle.
        self.reward_task = "obstacle" if config.num_agents + k > 1 else "proposed"

    def _placement(
        self, rng: np.random.Generator, start: np.ndarray, target_xy: np.ndarray, obstacles: np.ndarray
    ) -> Placement:
        """Random headings for every robot and target; start (F, M, 2), target_xy (F, M, 2), obstacles
        (F, K, 2)."""
        num_fields = len(start)
        target = np.zeros((num_fields, self.num_agents, 5))
        target[..., 0:2] = target_xy
        target[..., 2] = rng.uniform(-np.pi, np.pi, (num_fields, self.num_agents))
        pos = np.concatenate([start, obstacles], axis=1)
        return Placement(pos, rng.uniform(-np.pi, np.pi, pos.shape[:2]), target)


class CrossingOptions(Strict):
    radius: float = Field(2.5, gt=0)  # m, of the circle the robots start on
    jitter: float = Field(0.25, ge=0, lt=0.5)  # random turn of each start, in fractions of the spacing


class Crossing(FieldScenario):
    """Robots evenly spaced (with jitter) on a circle at a random rotation; each target is the antipodal
    point of its start, so every straight path runs through the centre. Obstacles, if any, stand anywhere
    clear of starts and targets."""

    name = "crossing"
    defaults = {"field": "division_b", "num_agents": 6}
    Options = CrossingOptions

    def __init__(self, config: ScenarioConfig) -> None:
        super().__init__(config)
        if self.options.radius > self.half.min():
            raise ValueError(
                f"options.radius: {self.options.radius} m does not fit the field {config.field!r} "
                f"(at most {self.half.min():.2f} m)"
            )

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> Placement:
        count, opt = self.num_agents, self.options
        spacing = 2 * np.pi / count
        turn = rng.uniform(-np.pi, np.pi, (num_fields, 1)) + spacing * np.arange(count)
        turn = turn + spacing * rng.uniform(-opt.jitter, opt.jitter, (num_fields, count))
        start = opt.radius * np.stack([np.cos(turn), np.sin(turn)], axis=-1)
        placed = np.concatenate([start, -start], axis=1)
        obstacles = self.scatter(rng, num_fields, self.num_obstacles, -self.half, self.half, placed)
        return self._placement(rng, start, -start, obstacles)


class CrowdOptions(Strict):
    band: float = Field(1.5, gt=0)  # m: obstacles start within |x| < band


class Crowd(FieldScenario):
    """Robots start beyond one end of a band of obstacles across the field and have targets beyond the
    other end (left to right or right to left, one coin per robot)."""

    name = "crowd"
    defaults = {"field": "division_b", "num_agents": 1, "num_obstacles": 8}
    Options = CrowdOptions

    def __init__(self, config: ScenarioConfig) -> None:
        super().__init__(config)
        self.inner = self.options.band + self.gap
        if self.inner >= self.half[0]:
            raise ValueError(
                f"options.band: {self.options.band} m leaves no room for starts and targets on the field "
                f"{config.field!r} (band + {self.gap} m must be below {self.half[0]:.2f} m)"
            )

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> Placement:
        count, half = self.num_agents, self.half
        zone_low, zone_high = np.array([-half[0], -half[1]]), np.array([-self.inner, half[1]])
        start = self.scatter(rng, num_fields, count, zone_low, zone_high)
        target = -self.scatter(rng, num_fields, count, zone_low, zone_high)
        # Every robot crosses left to right or, mirrored through the centre, right to left: robots of one
        # field meet head-on in the band. Robots of one direction keep their gaps; those of the other
        # start and end in the other zone.
        flip = np.where(rng.random((num_fields, count, 1)) < 0.5, -1.0, 1.0)
        start, target = start * flip, target * flip
        band = np.array([self.options.band, half[1]])
        placed = np.concatenate([start, target], axis=1)
        obstacles = self.scatter(rng, num_fields, self.num_obstacles, -band, band, placed)
        return self._placement(rng, start, target, obstacles)


class FormationOptions(Strict):
    rows: int = Field(2, ge=1)
    spacing: float = Field(0.5, gt=0)  # m between neighbouring slots


class Formation(FieldScenario):
    """Robots scattered over the field take the slots of a ``rows``-row grid formation placed at a random
    point and heading; all targets face the formation's heading. Robots are assigned to slots in the order
    of their position across the formation, so paths rarely have to cross. Obstacles start anywhere clear
    of robots and slots."""

    name = "formation"
    defaults = {
        "field": "division_b",
        "num_agents": 6,
        "num_obstacles": 6,
        "obstacles": {"behaviour": "public_code", "options": {"p_still": 0.0}},
    }
    Options = FormationOptions

    def __init__(self, config: ScenarioConfig) -> None:
        super().__init__(config)
        opt, count = self.options, self.num_agents
        cols = -(-count // opt.rows)
        i = np.arange(count)
        grid = np.stack([(i // cols) * opt.spacing, (i % cols) * opt.spacing], axis=-1)
        # Slots as complex offsets from the formation's centre: x along its heading, y across it.
        self.slots = (grid - grid.mean(axis=0)) @ np.array([1.0, 1j])
        self.reach = float(np.abs(self.slots).max())
        if self.reach >= self.half.min():
            raise ValueError(f"options: a {opt.rows}-row formation of {count} robots does not fit the field")
        if opt.spacing < self.gap:
            raise ValueError(f"options.spacing: {opt.spacing} m puts slots closer than {self.gap} m")

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> Placement:
        heading = rng.uniform(-np.pi, np.pi, (num_fields, 1))
        reach = self.half - self.reach
        centre = rng.uniform(-reach, reach, (num_fields, 2)) @ np.array([1.0, 1j])
        slots = centre[:, None] + self.slots * np.exp(1j * heading)
        slot_xy = np.stack([slots.real, slots.imag], axis=-1)
        start = self.scatter(rng, num_fields, self.num_agents, -self.half, self.half, slot_xy)
        # Robots and slots both ranked by their coordinate across the formation; rank i takes rank i.
        across = np.stack([-np.sin(heading), np.cos(heading)], axis=-1)
        rank = np.argsort(np.argsort((start * across).sum(-1), axis=1), axis=1)
        by_slot = np.argsort((slot_xy * across).sum(-1), axis=1)
        target_xy = np.take_along_axis(slot_xy, by_slot[..., None], axis=1)
        target_xy = np.take_along_axis(target_xy, rank[..., None], axis=1)
        placed = np.concatenate([start, slot_xy], axis=1)
        obstacles = self.scatter(rng, num_fields, self.num_obstacles, -self.half, self.half, placed)
        placement = self._placement(rng, start, target_xy, obstacles)
        placement.target[..., 2] = heading
        return placement


SCENARIOS: dict[str, type[FieldScenario]] = {cls.name: cls for cls in (Crossing, Crowd, Formation)}

__all__ = ["SCENARIOS", "Crossing", "Crowd", "FieldScenario", "Formation"]
