"""The SSL ball (``BallSpec``) and the positions and velocities of many (``BallState``), as the world
(``hier_ssl.world.physics``) steps them.

The ball is a disc in the plane that rolls: it keeps its velocity but for a constant deceleration
opposing it, which stops it and never reverses it, and for its contacts with walls, goals and robots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BallSpec:
    """A golf ball on carpet: lengths in m, mass in kg, deceleration in m/s^2, restitutions in [0, 1].

    ``restitution_wall`` is the normal speed kept when it bounces off a wall, a goal wall or a post,
    ``restitution_robot`` off a robot. Its contacts have no friction: a robot without a dribbler pushes it
    along the contact normal alone, and a wall only turns back its normal velocity.
    """

    # Rules 2.2 "Ball": an orange golf ball, 0.043 m across. The ER-Force simulator (its simball.h, as
    # UBC-Thunderbots/Software vendors it in er_force_sim) has BALL_RADIUS 0.0215 and BALL_MASS 0.046.
    radius: float = 0.0215
    mass: float = 0.046
    # The ER-Force simulator's BALL_ROLLING_FRICTION_DECELERATION (simball.h above): 0.5 m/s^2 while the
    # ball rolls on the carpet. Its sliding phase right after a kick (about 5/7 of the kick speed lost
    # within a few centimetres) is not modelled: a ball here starts rolling at the speed it is given.
    deceleration: float = 0.5
    # The walls are wooden or plastic boards and the goals aluminium: a golf ball keeps most of its normal
    # speed off hard surfaces (0.7 to 0.8 off a floor), a board that gives a little somewhat less.
    restitution_wall: float = 0.6
    # A robot's shell and kicker bar are stiff, but its dribbler bar and bumpers are meant to soak a pass
    # up: a ball keeps a third of its normal speed against a robot.
    restitution_robot: float = 0.3

    def __post_init__(self) -> None:
        for name in ("radius", "mass", "deceleration"):
            if not getattr(self, name) > 0:
                raise ValueError(f"BallSpec.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("restitution_wall", "restitution_robot"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"BallSpec.{name} must be in [0, 1], got {getattr(self, name)!r}")


@dataclass(frozen=True)
class BallState:
    """Every ball's position ``pos`` (N, B, 2) m and velocity ``vel`` (N, B, 2) m/s, field frame. A state
    is replaced, never changed."""

    pos: np.ndarray
    vel: np.ndarray

    def fields(self, index: np.ndarray | slice | list[int]) -> BallState:
        """The balls of the fields ``index``."""
        return BallState(self.pos[index], self.vel[index])


__all__ = ["BallSpec", "BallState"]
