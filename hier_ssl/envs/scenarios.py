"""Multi-robot field scenarios: small classes over the shared world, picked by name from ``SCENARIOS``.

A scenario (in the spirit of VMAS's) says which field, how many controlled robots (1..11) and obstacle robots
(0..11), how obstacles move, and how starts and targets are drawn (``reset_world_at``). Everything else
(observation, sub-goal decoding, rewards, success and collision rules) is shared by all scenarios:
``hier_ssl.manager``'s pure functions, run per robot by ``hier_ssl.envs.multi``. Its settings are keys of
``ScenarioConfig``, whose defaults each scenario class may change through ``defaults``. Robot order in every
field: controlled robots 0..M-1, then obstacles M..M+K-1.

- ``crossing``: M robots on a circle swap to the antipodal points, all through the centre (Division B).
- ``crowd``: robots cross the field, either way, through a band of random-walking obstacles.
- ``formation``: M robots take the slots of a grid formation while obstacles move about the field.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, Field

from hier_ssl.config import (
    BehaviourConfig,
    ConfigError,
    ScenarioConfig,
    Strict,
    apply_overrides,
    load_yaml,
    parse_config,
)
from hier_ssl.world.field import get_field


@dataclass
class Layout:
    """Where a reset puts M controlled robots and K obstacles in m fields.

    Shapes: pos (m, M + K, 2) m and angle (m, M + K) rad, controlled robots first; target (m, M, 5) x, y,
    theta, vx, vy of each controlled robot.
    """

    pos: np.ndarray
    angle: np.ndarray
    target: np.ndarray


class Scenario:
    """Base of the scenarios: reads the config, draws non-overlapping points. Subclasses set ``name``,
    ``defaults`` (ScenarioConfig keys), ``Options`` (a model of their own settings) and
    ``reset_world_at``."""

    name: ClassVar[str]
    defaults: ClassVar[dict[str, Any]] = {}
    Options: ClassVar[type[BaseModel]] = Strict

    def __init__(self, config: ScenarioConfig) -> None:
        self.config = config
        self.options = self.Options.model_validate(config.options)
        self.field = get_field(config.field)
        self.num_agents, self.num_obstacles = config.num_agents, config.num_obstacles
        # Robots start and targets lie this far apart, so no reset begins inside the collision distance.
        self.gap = 2 * config.collision_distance
        margin = config.spawn_margin
        self.half = np.array([self.field.half_length - margin, self.field.half_width - margin])

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

    def _layout(
        self, rng: np.random.Generator, start: np.ndarray, target_xy: np.ndarray, obstacles: np.ndarray
    ) -> Layout:
        """Random headings for every robot and target; start (m, M, 2), target_xy (m, M, 2), obstacles
        (m, K, 2)."""
        m = len(start)
        target = np.zeros((m, self.num_agents, 5))
        target[..., 0:2] = target_xy
        target[..., 2] = rng.uniform(-np.pi, np.pi, (m, self.num_agents))
        pos = np.concatenate([start, obstacles], axis=1)
        return Layout(pos, rng.uniform(-np.pi, np.pi, pos.shape[:2]), target)


class CrossingOptions(Strict):
    radius: float = Field(2.5, gt=0)  # m, of the circle the robots start on
    jitter: float = Field(0.25, ge=0, lt=0.5)  # random turn of each start, in fractions of the spacing


class Crossing(Scenario):
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

    def reset_world_at(self, m: int, rng: np.random.Generator) -> Layout:
        count, opt = self.num_agents, self.options
        spacing = 2 * np.pi / count
        turn = rng.uniform(-np.pi, np.pi, (m, 1)) + spacing * np.arange(count)
        turn = turn + spacing * rng.uniform(-opt.jitter, opt.jitter, (m, count))
        start = opt.radius * np.stack([np.cos(turn), np.sin(turn)], axis=-1)
        placed = np.concatenate([start, -start], axis=1)
        obstacles = self.scatter(rng, m, self.num_obstacles, -self.half, self.half, placed)
        return self._layout(rng, start, -start, obstacles)


class CrowdOptions(Strict):
    band: float = Field(1.5, gt=0)  # m: obstacles start within |x| < band


class Crowd(Scenario):
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

    def reset_world_at(self, m: int, rng: np.random.Generator) -> Layout:
        count, half = self.num_agents, self.half
        zone_low, zone_high = np.array([-half[0], -half[1]]), np.array([-self.inner, half[1]])
        start = self.scatter(rng, m, count, zone_low, zone_high)
        target = -self.scatter(rng, m, count, zone_low, zone_high)
        # Every robot crosses left to right or, mirrored through the centre, right to left: robots of one
        # field meet head-on in the band. Robots of one direction keep their gaps; those of the other
        # start and end in the other zone.
        flip = np.where(rng.random((m, count, 1)) < 0.5, -1.0, 1.0)
        start, target = start * flip, target * flip
        band = np.array([self.options.band, half[1]])
        placed = np.concatenate([start, target], axis=1)
        obstacles = self.scatter(rng, m, self.num_obstacles, -band, band, placed)
        return self._layout(rng, start, target, obstacles)


class FormationOptions(Strict):
    rows: int = Field(2, ge=1)
    spacing: float = Field(0.5, gt=0)  # m between neighbouring slots


class Formation(Scenario):
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

    def reset_world_at(self, m: int, rng: np.random.Generator) -> Layout:
        heading = rng.uniform(-np.pi, np.pi, (m, 1))
        centre = rng.uniform(-(self.half - self.reach), self.half - self.reach, (m, 2)) @ np.array([1.0, 1j])
        slots = centre[:, None] + self.slots * np.exp(1j * heading)
        slot_xy = np.stack([slots.real, slots.imag], axis=-1)
        start = self.scatter(rng, m, self.num_agents, -self.half, self.half, slot_xy)
        # Robots and slots both ranked by their coordinate across the formation; rank i takes rank i.
        across = np.stack([-np.sin(heading), np.cos(heading)], axis=-1)
        rank = np.argsort(np.argsort((start * across).sum(-1), axis=1), axis=1)
        by_slot = np.argsort((slot_xy * across).sum(-1), axis=1)
        target_xy = np.take_along_axis(slot_xy, by_slot[..., None], axis=1)
        target_xy = np.take_along_axis(target_xy, rank[..., None], axis=1)
        placed = np.concatenate([start, slot_xy], axis=1)
        obstacles = self.scatter(rng, m, self.num_obstacles, -self.half, self.half, placed)
        layout = self._layout(rng, start, target_xy, obstacles)
        layout.target[..., 2] = heading
        return layout


SCENARIOS: dict[str, type[Scenario]] = {cls.name: cls for cls in (Crossing, Crowd, Formation)}


def scenario_config(
    config: str | Path | ScenarioConfig | None = None, overrides: Sequence[str] = (), **settings: Any
) -> ScenarioConfig:
    """A ScenarioConfig from a registered name, a YAML file (a scenario, or a training config's
    ``scenario`` section) or a config; ``settings`` and then ``overrides`` (``key.sub=value`` strings, as
    ``--set`` takes them) override its keys. One that names another scenario starts from that scenario's
    defaults, not from ``config``'s keys.

    ``scenario_config("crossing", num_agents=4)``; ``scenario_config("configs/scenarios/crowd.yaml")``.
    Errors are ConfigErrors naming the key (``scenario.options.radius: ...``).
    """
    if isinstance(config, ScenarioConfig):
        data = config.model_dump(exclude_unset=True)
    elif isinstance(config, str) and config in SCENARIOS:
        data = {"scenario": config}
    elif isinstance(config, str) and not Path(config).is_file() and not config.endswith((".yaml", ".yml")):
        known = sorted(SCENARIOS)
        raise ConfigError(f"scenario: unknown scenario {config!r}; known: {known}, or a YAML file")
    elif config is not None:
        data = load_yaml(config)
        if isinstance(data.get("scenario"), dict):  # a training config: its scenario section
            data = data["scenario"]
    else:
        data = {}
    merged = apply_overrides({**data, **settings}, list(overrides))
    if "scenario" in data and merged.get("scenario") != data["scenario"]:
        merged = apply_overrides(dict(settings), list(overrides))
    return parse_config(merged, ScenarioConfig, root="scenario")


def make_scenario(config: ScenarioConfig) -> Scenario:
    """The scenario object that ``config`` names."""
    return SCENARIOS[config.scenario](config)


__all__ = [
    "SCENARIOS",
    "BehaviourConfig",
    "Crossing",
    "Crowd",
    "Formation",
    "Layout",
    "Scenario",
    "ScenarioConfig",
    "make_scenario",
    "scenario_config",
]
