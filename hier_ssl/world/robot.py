"""An SSL robot's limits (``RobotSpec``) and the poses and velocities of many (``RobotState``), as the world
(``hier_ssl.world.physics``) steps them and everything above it reads them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hier_ssl.world.frames import heading


@dataclass(frozen=True)
class RobotSpec:
    """An SSL robot (docs/paper.md); speeds in m/s and rad/s, accelerations in m/s^2 and rad/s^2."""

    radius: float = 0.09
    mass: float = 2.2
    max_speed: float = 2.5
    max_accel: float = 3.0
    max_ang_speed: float = 10.0
    max_ang_accel: float = 60.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not value > 0:
                raise ValueError(f"RobotSpec.{name} must be > 0, got {value!r}")


@dataclass
class RobotState:
    """Poses and velocities of every robot, field frame.

    Shapes: pos (N, R, 2) m, angle (N, R) rad in [-pi, pi), vel (N, R, 2) m/s, ang_vel (N, R) rad/s.
    A state is replaced, never changed: ``heading`` is computed once (the world passes the one it made).
    """

    pos: np.ndarray
    angle: np.ndarray
    vel: np.ndarray
    ang_vel: np.ndarray
    _heading: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def heading(self) -> np.ndarray:
        """exp(i angle) (N, R) complex (``hier_ssl.world.frames.heading``)."""
        if self._heading is None:
            self._heading = heading(self.angle)
        return self._heading

    def robots(self, index: slice | np.ndarray | list[int]) -> RobotState:
        """The same fields, a subset of robots (a view for slices)."""
        h = None if self._heading is None else self._heading[:, index]
        return RobotState(
            self.pos[:, index], self.angle[:, index], self.vel[:, index], self.ang_vel[:, index], h
        )

    def fields(self, index: np.ndarray) -> RobotState:
        h = None if self._heading is None else self._heading[index]
        return RobotState(self.pos[index], self.angle[index], self.vel[index], self.ang_vel[index], h)

    def copy(self) -> RobotState:
        return RobotState(self.pos.copy(), self.angle.copy(), self.vel.copy(), self.ang_vel.copy())


__all__ = ["RobotSpec", "RobotState"]
