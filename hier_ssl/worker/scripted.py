"""Scripted goToPoint workers: batched maps from (robot state, sub-goal) to a velocity command.

A sub-goal is (x, y, theta, vx, vy) in the field frame, shape (N, R, 5); a command is (vx, vy, w) in the
robot's own frame, shape (N, R, 3), which is what an SSL robot's firmware takes.

Both workers run once per control step for every robot of every field. Written as numpy operations on
(N, R) arrays, a step of one field was some 35 calls each costing numpy's per-call overhead (a fifth of a
PettingZoo step); each worker is instead one compiled loop over the robots (numba), a few scalar lines per
robot, the same at every N. The sub-goal is seen along the line to it: (along, across) components of a
velocity are its projections on the unit vector ``(ex, ey)`` pointing to the sub-goal and on that vector
turned 90 deg to the left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from hier_ssl.world.frames import as_float, wrap
from hier_ssl.world.physics import RobotState

# Compiled once per argument layout and cached on disk next to this module (numba's ``cache``).
_jit = numba.njit(cache=True)
# Along x at the sub-goal itself: the 1e-12 m nudge makes the line's direction the field's x axis there
# instead of 0 / 0, and turns it by at most 1e-12 / dist rad elsewhere.
_NUDGE = 1e-12


@_jit
def _line(px: float, py: float, gx: float, gy: float) -> tuple[float, float, float]:
    """Distance from (px, py) to the sub-goal (gx, gy), and the unit vector (ex, ey) pointing to it."""
    dx, dy = gx - px, gy - py
    nx = dx + _NUDGE
    size = math.hypot(nx, dy)
    return math.hypot(dx, dy), nx / size, dy / size


@_jit
def _along(x: float, y: float, ex: float, ey: float) -> tuple[float, float]:
    """Field-frame vector (x, y) as (along, across) the line of unit vector (ex, ey)."""
    return x * ex + y * ey, y * ex - x * ey


@_jit
def _to_robot(along: float, across: float, ex: float, ey: float, heading: complex) -> tuple[float, float]:
    """(along, across) the line as a vector in the frame of a robot at ``heading`` (exp(i angle))."""
    x, y = along * ex - across * ey, along * ey + across * ex
    c, s = heading.real, heading.imag
    return x * c + y * s, y * c - x * s


@_jit
def _capped(along: float, across: float, max_speed: float) -> tuple[float, float]:
    """The vector scaled down to ``max_speed`` where faster, direction kept."""
    speed = math.hypot(along, across)
    if speed <= max_speed:
        return along, across
    scale = max_speed / speed
    return along * scale, across * scale


@_jit
def _clamp(value: float, bound: float) -> float:
    return max(min(value, bound), -bound)


class _Scripted:
    """What both scripted workers share: no memory, gains as one float64 array in ``_gains()``'s order, and
    a compiled ``_kernel(pos, angle, vel, ang_vel, heading, subgoal, gains, out)`` writing the commands."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "_k", np.array(list(self._gains().values()), dtype=np.float64))

    def _gains(self) -> dict[str, float]:
        raise NotImplementedError

    def reset(self, fields: np.ndarray) -> None:
        """Stateless: nothing to forget."""

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        """Commands (N, R, 3) for robots ``state`` (N, R) to reach ``subgoal`` (N, R, 5)."""
        out = np.empty(state.angle.shape + (3,))
        self._kernel(
            state.pos, state.angle, state.vel, state.ang_vel, state.heading, as_float(subgoal), self._k, out
        )
        return out


@dataclass(frozen=True)
class PaperGoToPoint(_Scripted):
    """The paper's scripted controller (docs/paper.md "The worker").

    Per step, along the axis to the sub-goal and across it: if the robot moves away from the sub-goal or is
    inside the braking distance |v^2 - v_goal^2| / (2 brake_accel), the velocity moves ``dv`` towards the
    sub-goal velocity, else ``dv`` towards the sub-goal; speed is capped at ``max_speed``. One addition:
    the speed towards the sub-goal never exceeds distance / dt, so the discrete loop cannot step past the
    sub-goal and circle it in a limit cycle of +-dv. Heading: w = gain * dtheta outside a dead band.
    """

    dt: float = 0.025
    dv: float = 0.1
    brake_accel: float = 1.0
    max_speed: float = 2.2
    angle_gain: float = 2.0
    angle_deadband: float = float(np.deg2rad(2.5))

    def _gains(self) -> dict[str, float]:
        return {
            "dt": self.dt,
            "dv": self.dv,
            "two_brake_accel": 2 * self.brake_accel,
            "max_speed": self.max_speed,
            "angle_gain": self.angle_gain,
            "angle_deadband": self.angle_deadband,
        }

    @staticmethod
    @_jit
    def _kernel(
        pos: np.ndarray,
        angle: np.ndarray,
        vel: np.ndarray,
        ang_vel: np.ndarray,
        heading: np.ndarray,
        subgoal: np.ndarray,
        gains: np.ndarray,
        out: np.ndarray,
    ) -> None:
        dt, dv, two_brake_accel, max_speed = gains[0], gains[1], gains[2], gains[3]
        angle_gain, angle_deadband = gains[4], gains[5]
        for f in range(angle.shape[0]):
            for i in range(angle.shape[1]):
                goal = subgoal[f, i]
                dist, ex, ey = _line(pos[f, i, 0], pos[f, i, 1], goal[0], goal[1])
                v_along, v_across = _along(vel[f, i, 0], vel[f, i, 1], ex, ey)
                goal_along, goal_across = _along(goal[3], goal[4], ex, ey)
                # Both axes move towards the sub-goal's velocity, except that along the line the robot heads
                # for the sub-goal at full speed unless moving away from it or within braking distance
                # |v^2 - v_goal^2| / (2 a) (dist = 0 is always within braking distance).
                change = goal_along - v_along
                braking = abs(change * (v_along + goal_along)) / two_brake_accel
                if dist > braking and v_along >= 0.0:
                    change = max_speed - v_along
                # +-dv per axis; the last step lands on the sub-goal rather than past it.
                along = min(v_along + _clamp(change, dv), max(goal_along, 0.0) + dist / dt)
                across = v_across + _clamp(goal_across - v_across, dv)
                along, across = _capped(along, across, max_speed)
                out[f, i, 0], out[f, i, 1] = _to_robot(along, across, ex, ey, heading[f, i])
                error = wrap(goal[2] - angle[f, i])
                out[f, i, 2] = 0.0 if abs(error) < angle_deadband else error * angle_gain


@dataclass(frozen=True)
class BangBangGoToPoint(_Scripted):
    """Time-optimal (bang-bang, trapezoidal) goToPoint, as SSL teams run it.

    The robot's acceleration budget ``max_accel`` is shared between the two axes: the axis across the line
    to the sub-goal takes what it needs to reach the sub-goal's cross velocity this step, the axis along it
    gets the rest. Along the line the desired speed follows the braking curve sqrt(v_goal^2 + 2 a d), the
    fastest profile that can still stop (or arrive at v_goal) in time, capped by ``max_speed`` and by d / dt
    so the last step lands on the sub-goal. Heading follows the same law with the angular limits. The
    braking acceleration keeps ``margin`` in reserve so a robot that lags its command still stops in time.
    """

    dt: float = 0.025
    max_speed: float = 2.5
    max_accel: float = 3.0
    max_ang_speed: float = 10.0
    max_ang_accel: float = 60.0
    margin: float = 0.9

    def _gains(self) -> dict[str, float]:
        return {
            "dt": self.dt,
            "step": self.max_accel * self.dt,
            "two_brake": 2 * self.margin * self.max_accel,
            "max_speed": self.max_speed,
            "two_ang_brake": 2 * self.margin * self.max_ang_accel,
            "max_ang_speed": self.max_ang_speed,
            "spin_step": self.max_ang_accel * self.dt,
        }

    @staticmethod
    @_jit
    def _kernel(
        pos: np.ndarray,
        angle: np.ndarray,
        vel: np.ndarray,
        ang_vel: np.ndarray,
        heading: np.ndarray,
        subgoal: np.ndarray,
        gains: np.ndarray,
        out: np.ndarray,
    ) -> None:
        dt, step, two_brake, max_speed = gains[0], gains[1], gains[2], gains[3]
        two_ang_brake, max_ang_speed, spin_step = gains[4], gains[5], gains[6]
        for f in range(angle.shape[0]):
            for i in range(angle.shape[1]):
                goal = subgoal[f, i]
                dist, ex, ey = _line(pos[f, i, 0], pos[f, i, 1], goal[0], goal[1])
                v_along, v_across = _along(vel[f, i, 0], vel[f, i, 1], ex, ey)
                goal_along, goal_across = _along(goal[3], goal[4], ex, ey)
                # Across first: as much of this step's velocity change as it needs, the rest goes along.
                dv_across = _clamp(goal_across - v_across, step)
                step_along = math.sqrt(max(step * step - dv_across * dv_across, 0.0))
                # Along: the braking curve, the speed limit, and landing on the sub-goal in the last step.
                desired = min(math.sqrt(goal_along * goal_along + dist * two_brake), max_speed)
                desired = min(desired, max(goal_along, 0.0) + dist / dt)
                along = v_along + _clamp(desired - v_along, step_along)
                out[f, i, 0], out[f, i, 1] = _to_robot(along, v_across + dv_across, ex, ey, heading[f, i])
                # Heading: the same law with the angular limits.
                error = wrap(goal[2] - angle[f, i])
                turn = min(min(math.sqrt(abs(error) * two_ang_brake), max_ang_speed), abs(error) / dt)
                spin = ang_vel[f, i]
                out[f, i, 2] = spin + _clamp(math.copysign(turn, error) - spin, spin_step)
