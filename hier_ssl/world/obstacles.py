"""Scripted obstacle behaviours: random agents that move obstacle robots.

A behaviour drives one obstacle robot in every field: ``reset(fields, rng)`` when episodes start and
``__call__(pos (N, 2), angle (N,), rng) -> (N, 3)`` each control step, a robot-frame (vx, vy, w)
command given the obstacle's own pose. An obstacle exposed as an agent instead sees
``obstacle_observation``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from hier_ssl.world.field import Field
from hier_ssl.world.physics import RobotSpec, RobotState

OBSTACLE_AGENT_OBS_DIM = 7  # an exposed obstacle's view of itself (``obstacle_observation``)


def obstacle_observation(state: RobotState, index: int, field: Field, robot: RobotSpec) -> np.ndarray:
    """Robot ``index``'s view of itself in every field (N, 7) float32: position, sin/cos heading,
    velocity and angular velocity, each over the field's or the robot's limit, clipped to +-1.2."""
    obs = np.concatenate(
        [
            state.pos[:, index] / field.max_pos,
            np.sin(state.angle[:, index])[:, None],
            np.cos(state.angle[:, index])[:, None],
            state.vel[:, index] / robot.max_speed,
            state.ang_vel[:, index, None] / robot.max_ang_speed,
        ],
        axis=1,
    )
    return np.clip(obs, -1.2, 1.2).astype(np.float32)


@dataclass
class Stationary:
    """Stands still (the obstacle of the paper's real-robot experiment)."""

    def reset(self, fields: np.ndarray, rng: np.random.Generator) -> None:
        """Stateless."""

    def __call__(self, pos: np.ndarray, angle: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return np.zeros((len(angle), 3))


@dataclass
class RandomWalk:
    """Paper text: a random direction each step, speed drawn uniformly in ``speed`` (m/s), no spin."""

    speed: tuple[float, float] = (0.0, 1.0)

    def __post_init__(self) -> None:
        lo, hi = self.speed
        if not 0 <= lo <= hi:
            raise ValueError(f"RandomWalk speed range must satisfy 0 <= low <= high, got {self.speed!r}")

    def reset(self, fields: np.ndarray, rng: np.random.Generator) -> None:
        """Stateless: a new draw every step."""

    def __call__(self, pos: np.ndarray, angle: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        n = len(angle)
        heading = rng.uniform(-np.pi, np.pi, n)
        speed = rng.uniform(*self.speed, n)
        # The direction in the robot's frame is the field heading minus the robot's own: one rotation.
        relative = heading - angle
        command = np.zeros((n, 3))
        command[:, 0] = speed * np.cos(relative)
        command[:, 1] = speed * np.sin(relative)
        return command


@dataclass
class PublicCodeRandom:
    """The paper's public code: per episode, with probability ``p_still`` the obstacle stays still;
    otherwise every step it draws vx, vy ~ U(-max_speed, max_speed) and w ~ U(-max_spin, max_spin)."""

    p_still: float = 0.5
    max_speed: float = 2.5
    max_spin: float = np.pi
    num_fields: int = 1
    _still: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not 0 <= self.p_still <= 1:
            raise ValueError(f"PublicCodeRandom p_still must be in [0, 1], got {self.p_still!r}")
        self._still = np.ones(self.num_fields, dtype=bool)

    def reset(self, fields: np.ndarray, rng: np.random.Generator) -> None:
        self._still[fields] = rng.random(len(fields)) < self.p_still

    def __call__(self, pos: np.ndarray, angle: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        n = len(angle)
        cmd = np.empty((n, 3))
        # The draws of rng.uniform(-max_speed, max_speed, (n, 2)), then of rng.uniform for the spin: the
        # same doubles in the same order, scaled as numpy does, in one compiled loop (a third of the calls).
        limits = (float(self.max_speed), float(self.max_spin))
        _uniform_commands(rng.random((n, 2)), rng.random(n), self._still, *limits, cmd)
        return cmd


@numba.njit(cache=True)
def _uniform_commands(
    unit_xy: np.ndarray,
    unit_w: np.ndarray,
    still: np.ndarray,
    max_speed: float,
    max_spin: float,
    out: np.ndarray,
) -> None:
    """``out`` (N, 3): zeros where ``still`` (N,), else vx, vy ~ U(-max_speed, max_speed) of the unit draws
    ``unit_xy`` (N, 2) and w ~ U(-max_spin, max_spin) of ``unit_w`` (N,), each low + (high - low) * u as
    numpy's Generator.uniform computes it (tests/world/test_obstacles.py holds the two equal)."""
    speed_range, spin_range = max_speed - -max_speed, max_spin - -max_spin
    for j in range(out.shape[0]):
        if still[j]:
            out[j] = 0.0
            continue
        out[j, 0] = -max_speed + speed_range * unit_xy[j, 0]
        out[j, 1] = -max_speed + speed_range * unit_xy[j, 1]
        out[j, 2] = -max_spin + spin_range * unit_w[j]


OBSTACLES = {"stationary": Stationary, "random_walk": RandomWalk, "public_code": PublicCodeRandom}


def make_obstacle(
    name: str, num_fields: int, **options: object
) -> Stationary | RandomWalk | PublicCodeRandom:
    """A behaviour by name; ``options`` are its fields. Unknown names or options raise ValueError."""
    if name not in OBSTACLES:
        raise ValueError(f"unknown obstacle behaviour {name!r}; known: {sorted(OBSTACLES)}")
    cls = OBSTACLES[name]
    if cls is PublicCodeRandom:
        options = {**options, "num_fields": num_fields}
    try:
        return cls(**options)
    except TypeError as err:
        raise ValueError(f"obstacle behaviour {name!r}: {err}") from None
