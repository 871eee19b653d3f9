"""Scripted goToPoint workers: batched maps from (robot state, sub-goal) to a velocity command.

A sub-goal is (x, y, theta, vx, vy) in the field frame, shape (N, R, 5); a command is (vx, vy, w) in the
robot's own frame, shape (N, R, 3), which is what an SSL robot's firmware takes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hier_ssl.world.physics import RobotState, to_robot_frame, wrap_angle


def _goal_frame(state: RobotState, subgoal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance to the sub-goal (N, R) and the unit axes (N, R, 2) pointing to it and 90 deg to its left.

    At the sub-goal itself the axes fall back to the field's x and y, so nothing divides by zero.
    """
    delta = subgoal[..., :2] - state.pos
    dist = np.sqrt(np.einsum("...i,...i->...", delta, delta))
    safe = dist > 1e-9
    ex = np.where(safe[..., None], delta / np.where(safe, dist, 1.0)[..., None], [1.0, 0.0])
    ey = np.stack([-ex[..., 1], ex[..., 0]], axis=-1)
    return dist, ex, ey


def _command(state: RobotState, vel_field: np.ndarray, spin: np.ndarray) -> np.ndarray:
    return np.concatenate([to_robot_frame(vel_field, state.angle), spin[..., None]], axis=-1)


@dataclass
class PaperGoToPoint:
    """The paper's scripted controller (SPEC.md "Scripted goToPoint controller of the public code").

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
    angle_deadband: float = np.deg2rad(2.5)

    def reset(self, fields: np.ndarray) -> None:
        """Stateless: nothing to forget."""

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        dist, ex, ey = _goal_frame(state, subgoal)
        axes = np.stack([ex, ey], axis=-2)  # (N, R, 2 axes, 2)
        v = np.einsum("...ai,...i->...a", axes, state.vel)
        v_goal = np.einsum("...ai,...i->...a", axes, subgoal[..., 3:5])
        delta = np.stack([dist, np.zeros_like(dist)], axis=-1)

        away = v * delta < 0
        at_goal_axis = delta == 0
        braking = np.abs(v**2 - v_goal**2) / (2 * self.brake_accel)
        brake = away | at_goal_axis | (np.abs(delta) <= braking)
        desired = np.where(brake, v_goal, np.sign(delta) * self.max_speed)
        v_new = v + np.clip(desired - v, -self.dv, self.dv)
        v_new[..., 0] = np.minimum(v_new[..., 0], dist / self.dt + np.maximum(v_goal[..., 0], 0.0))

        vel = np.einsum("...a,...ai->...i", v_new, axes)
        speed = np.sqrt(np.einsum("...i,...i->...", vel, vel))
        vel *= np.minimum(1.0, self.max_speed / np.maximum(speed, 1e-12))[..., None]

        dtheta = wrap_angle(subgoal[..., 2] - state.angle)
        spin = np.where(np.abs(dtheta) >= self.angle_deadband, self.angle_gain * dtheta, 0.0)
        return _command(state, vel, spin)


@dataclass
class BangBangGoToPoint:
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

    def reset(self, fields: np.ndarray) -> None:
        """Stateless: nothing to forget."""

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        dist, ex, ey = _goal_frame(state, subgoal)
        v_along = np.einsum("...i,...i->...", state.vel, ex)
        v_across = np.einsum("...i,...i->...", state.vel, ey)
        goal_along = np.einsum("...i,...i->...", subgoal[..., 3:5], ex)
        goal_across = np.einsum("...i,...i->...", subgoal[..., 3:5], ey)

        step = self.max_accel * self.dt
        dv_across = np.clip(goal_across - v_across, -step, step)
        step_along = np.sqrt(np.maximum(step**2 - dv_across**2, 0.0))
        brake = self.margin * self.max_accel
        desired = np.minimum(np.sqrt(goal_along**2 + 2 * brake * dist), self.max_speed)
        desired = np.minimum(desired, dist / self.dt + np.maximum(goal_along, 0.0))
        dv_along = np.clip(desired - v_along, -step_along, step_along)
        vel = (v_along + dv_along)[..., None] * ex + (v_across + dv_across)[..., None] * ey

        dtheta = wrap_angle(subgoal[..., 2] - state.angle)
        turn = np.minimum(np.sqrt(2 * self.margin * self.max_ang_accel * np.abs(dtheta)), self.max_ang_speed)
        turn = np.minimum(turn, np.abs(dtheta) / self.dt)
        spin_step = self.max_ang_accel * self.dt
        spin = state.ang_vel + np.clip(np.sign(dtheta) * turn - state.ang_vel, -spin_step, spin_step)
        return _command(state, vel, spin)
