"""What a learned goToPoint worker sees, and how its normalised action becomes a command."""

from __future__ import annotations

import numpy as np

from hier_ssl.world.frames import to_robot_frame, wrap_angle
from hier_ssl.world.physics import RobotSpec, RobotState

WORKER_OBS_DIM = 9


def worker_observation(
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    ang_vel: np.ndarray,
    subgoal: np.ndarray,
    robot: RobotSpec,
    max_pos: float,
) -> np.ndarray:
    """The sub-goal relative to the robot, in the robot's frame, normalised.

    Shapes: pos (N, 2), angle (N,), vel (N, 2), ang_vel (N,), subgoal (N, 5) -> (N, 9) float32:
    sub-goal offset x, y; sin, cos of the heading error; robot velocity x, y; angular velocity;
    sub-goal velocity x, y. Relative, robot-frame inputs make the skill the same everywhere on the field.
    """
    offset = to_robot_frame(subgoal[:, 0:2] - pos, angle) / max_pos
    error = wrap_angle(subgoal[:, 2] - angle)
    obs = np.concatenate(
        [
            offset,
            np.sin(error)[:, None],
            np.cos(error)[:, None],
            to_robot_frame(vel, angle) / robot.max_speed,
            ang_vel[:, None] / robot.max_ang_speed,
            to_robot_frame(subgoal[:, 3:5], angle) / robot.max_speed,
        ],
        axis=1,
    )
    return np.clip(obs, -1.2, 1.2).astype(np.float32)


def controlled_worker_observation(
    state: RobotState, subgoal: np.ndarray, robot: RobotSpec, max_pos: float
) -> np.ndarray:
    """The worker observations (N, M, 9) of robots 0..M-1 of every field towards ``subgoal`` (N, M, 5)."""
    n, m = subgoal.shape[:2]
    own = state.robots(slice(0, m))
    obs = worker_observation(
        own.pos.reshape(n * m, 2),
        own.angle.reshape(n * m),
        own.vel.reshape(n * m, 2),
        own.ang_vel.reshape(n * m),
        subgoal.reshape(n * m, 5),
        robot,
        max_pos,
    )
    return obs.reshape(n, m, -1)


def scale_command(action: np.ndarray, robot: RobotSpec) -> np.ndarray:
    """A normalised action (..., 3) in [-1, 1] as a robot-frame command (vx, vy, w) in m/s and rad/s."""
    return action * np.array([robot.max_speed, robot.max_speed, robot.max_ang_speed])
