"""Scripted goToPoint workers: batched maps from (robot state, sub-goal) to a velocity command.

A sub-goal is (x, y, theta, vx, vy) in the field frame, shape (N, R, 5); a command is (vx, vy, w) in the
robot's own frame, shape (N, R, 3), which is what an SSL robot's firmware takes.

Both workers run once per control step for every field, so at one field their cost is numpy's per-call
overhead, not arithmetic: 2-D vectors are complex numbers (a rotation is one multiply or divide),
constants are 0-d arrays (a Python float operand is converted on every call), operands share one dtype,
and results are new arrays (numpy's overlap check makes an in-place update of a one-element array slower).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from hier_ssl.world.frames import as_complex, as_float, cap_speed, wrap_angle
from hier_ssl.world.physics import RobotState

_COMPLEX = np.dtype(np.complex128)


def _constants(**values: complex) -> SimpleNamespace:
    return SimpleNamespace(**{name: np.array(value) for name, value in values.items()})


_K = _constants(zero=0.0, nudge=1e-12 + 0j)


def _goal_axes(
    state: RobotState, subgoal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The sub-goal seen along the line to it.

    Returns dist (N, R), the unit vector ``ex`` (N, R) complex pointing to the sub-goal, and the robot's
    and the sub-goal's velocities in the (along, across) frame of that line, as complex (N, R): real part
    along ``ex``, imaginary part 90 deg to its left.
    """
    delta = (subgoal[..., 0:2] - state.pos).view(_COMPLEX)[..., 0]
    dist = np.abs(delta)
    # z / |z| written out, as numpy >= 2 computes its complex sign (hypot, then each part divided: the same
    # bits); numpy < 2's sign is the sign of the real part. The 1e-12 m nudge along x makes the axis the
    # field's x axis at the sub-goal itself instead of 0 / 0, and turns it by at most 1e-12 / dist rad
    # elsewhere.
    nudged = delta + _K.nudge
    size = np.hypot(nudged.real, nudged.imag)
    ex = np.empty_like(nudged)
    ex.real, ex.imag = nudged.real / size, nudged.imag / size
    # Dividing by a unit complex number rotates by minus its angle: into the (along, across) frame.
    return dist, ex, as_complex(state.vel) / ex, as_complex(subgoal[..., 3:5]) / ex


def _heading_error(state: RobotState, subgoal: np.ndarray) -> np.ndarray:
    """Sub-goal heading minus robot heading, wrapped to [-pi, pi). Shape (N, R)."""
    return wrap_angle(subgoal[..., 2] - state.angle)


def _command(state: RobotState, vel: np.ndarray, spin: np.ndarray) -> np.ndarray:
    """Field-frame velocities ``vel`` (N, R) complex and spins (N, R) as robot-frame commands (N, R, 3)."""
    out = np.empty(spin.shape + (3,))
    np.divide(vel, state.heading, out=out[..., 0:2].view(_COMPLEX)[..., 0])
    out[..., 2] = spin
    return out


class _Scripted:
    """What both scripted workers share: no memory, constants (``_gains``) held as 0-d arrays, and the
    sub-goal seen along the line to it (``_goal_axes``), from which ``_steer`` makes the commands."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "_k", _constants(**self._gains()))

    def _gains(self) -> dict[str, float]:
        raise NotImplementedError

    def _steer(
        self, k: SimpleNamespace, state: RobotState, subgoal: np.ndarray, *axes: np.ndarray
    ) -> np.ndarray:
        raise NotImplementedError

    def reset(self, fields: np.ndarray) -> None:
        """Stateless: nothing to forget."""

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        """Commands (N, R, 3) for robots ``state`` (N, R) to reach ``subgoal`` (N, R, 5)."""
        subgoal = as_float(subgoal)
        return self._steer(self._k, state, subgoal, *_goal_axes(state, subgoal))


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
            "minus_dv": -self.dv,
            "two_brake_accel": 2 * self.brake_accel,
            "max_speed": self.max_speed,
            "angle_gain": self.angle_gain,
            "angle_deadband": self.angle_deadband,
        }

    def _steer(
        self, k: SimpleNamespace, state: RobotState, subgoal: np.ndarray, *axes: np.ndarray
    ) -> np.ndarray:
        dist, ex, v, goal_v = axes
        v_along, goal_along = v.real, goal_v.real

        # Both axes move towards the sub-goal's velocity, except that along the line the robot heads for the
        # sub-goal at full speed unless moving away from it or within braking distance |v^2 - v_goal^2| /
        # (2 a) (v * dist < 0 is v < 0 for dist > 0, and dist = 0 is always within braking distance).
        change = goal_v - v
        braking = np.abs(change.real * (v_along + goal_along)) / k.two_brake_accel
        drive = (dist > braking) & (v_along >= _K.zero)
        # The last step lands on the sub-goal rather than past it.
        reach = np.maximum(goal_along, _K.zero) + dist / k.dt
        np.copyto(change.real, k.max_speed - v_along, where=drive)

        # +-dv per axis, both axes in one call on the (along, across) float pairs.
        change = np.maximum(np.minimum(change.view(np.float64), k.dv), k.minus_dv)
        v_new = v + change.view(_COMPLEX)
        v_new.real = np.minimum(v_new.real, reach)
        # Field frame, scaled down to max_speed where faster, direction kept (no division when none is).
        vel = cap_speed(v_new * ex, k.max_speed)

        error = _heading_error(state, subgoal)
        spin = error * k.angle_gain
        np.copyto(spin, _K.zero, where=np.abs(error) < k.angle_deadband)
        return _command(state, vel, spin)


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
        step, spin_step = self.max_accel * self.dt, self.max_ang_accel * self.dt
        return {
            "dt": self.dt,
            "step": step,
            "minus_step": -step,
            "step_sq": step**2,
            "two_brake": 2 * self.margin * self.max_accel,
            "max_speed": self.max_speed,
            "two_ang_brake": 2 * self.margin * self.max_ang_accel,
            "max_ang_speed": self.max_ang_speed,
            "spin_step": spin_step,
            "minus_spin_step": -spin_step,
        }

    def _steer(
        self, k: SimpleNamespace, state: RobotState, subgoal: np.ndarray, *axes: np.ndarray
    ) -> np.ndarray:
        dist, ex, v, goal_v = axes
        goal_along = goal_v.real

        # Across first: as much of this step's velocity change as it needs, the rest is left for along.
        dv_across = np.maximum(np.minimum(goal_v.imag - v.imag, k.step), k.minus_step)
        step_along = np.sqrt(np.maximum(k.step_sq - np.square(dv_across), _K.zero))

        # Along: the braking curve, the speed limit, and landing on the sub-goal in the last step.
        desired = np.minimum(np.sqrt(np.square(goal_along) + dist * k.two_brake), k.max_speed)
        desired = np.minimum(desired, np.maximum(goal_along, _K.zero) + dist / k.dt)
        dv_along = np.maximum(np.minimum(desired - v.real, step_along), -step_along)
        v_new = np.empty_like(v)
        v_new.real = v.real + dv_along
        v_new.imag = v.imag + dv_across
        vel = v_new * ex

        error = _heading_error(state, subgoal)
        size = np.abs(error)
        turn = np.minimum(np.sqrt(size * k.two_ang_brake), k.max_ang_speed)
        turn = np.copysign(np.minimum(turn, size / k.dt), error)
        change = np.maximum(np.minimum(turn - state.ang_vel, k.spin_step), k.minus_spin_step)
        return _command(state, vel, state.ang_vel + change)
