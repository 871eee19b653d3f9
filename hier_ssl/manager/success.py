"""Success and failure predicates of the manager's tasks (SPEC "Thresholds and episode end").

Comparisons are strict (d < D_th), as in the public code; the reward's bonus applies at
d <= D_th, a difference only on a set of measure zero.
"""

from __future__ import annotations

import numpy as np

from hier_ssl.manager.rewards import (
    ANGLE_THRESHOLD,
    DIST_THRESHOLD,
    TASKS,
    nearest_obstacle_distance,
    pose_errors,
)

SPEED_THRESHOLD = 0.05  # m/s: the robot counts as stopped below this
COLLISION_DISTANCE = 0.2  # m, centre to centre: two robot radii of 0.09 m plus a margin


def baseline_success(
    target: np.ndarray,
    robot_pos: np.ndarray,
    robot_angle: np.ndarray,
    robot_vel: np.ndarray,
    *,
    d_th: float = DIST_THRESHOLD,
    theta_th: float = ANGLE_THRESHOLD,
    speed_th: float = SPEED_THRESHOLD,
) -> np.ndarray:
    """The robot is within d_th and theta_th of the target and slower than speed_th.

    Args:
        target: (N, 5) pose. robot_pos: (N, 2) m. robot_angle: (N,) rad. robot_vel: (N, 2) m/s.

    Returns:
        (N,) bool.
    """
    d, delta = pose_errors(np.column_stack([robot_pos, robot_angle]), target)
    speed = np.linalg.norm(robot_vel, axis=1)
    return (d < d_th) & (delta < theta_th) & (speed < speed_th)


def proposed_success(
    target: np.ndarray,
    subgoal: np.ndarray,
    robot_pos: np.ndarray,
    robot_vel: np.ndarray,
    *,
    d_th: float = DIST_THRESHOLD,
    theta_th: float = ANGLE_THRESHOLD,
    speed_th: float = SPEED_THRESHOLD,
) -> np.ndarray:
    """The sub-goal is within d_th and theta_th of the target, and the robot within d_th of it
    and slower than speed_th. The robot's heading is not checked (SPEC, public code).

    Args:
        target, subgoal: (N, 5) poses. robot_pos: (N, 2) m. robot_vel: (N, 2) m/s.

    Returns:
        (N,) bool.
    """
    d, delta = pose_errors(subgoal, target)
    robot_d = np.linalg.norm(robot_pos - target[:, 0:2], axis=1)
    speed = np.linalg.norm(robot_vel, axis=1)
    return (d < d_th) & (delta < theta_th) & (robot_d < d_th) & (speed < speed_th)


def task_success(
    task: str,
    target: np.ndarray,
    subgoal: np.ndarray,
    robot_pos: np.ndarray,
    robot_angle: np.ndarray,
    robot_vel: np.ndarray,
    *,
    d_th: float = DIST_THRESHOLD,
    theta_th: float = ANGLE_THRESHOLD,
    speed_th: float = SPEED_THRESHOLD,
) -> np.ndarray:
    """Success of `task` ("baseline", "proposed" or "obstacle", which succeeds as "proposed").

    Args:
        target, subgoal: (N, 5). robot_pos: (N, 2). robot_angle: (N,). robot_vel: (N, 2).

    Returns:
        (N,) bool.
    """
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; expected one of {TASKS}")
    thresholds = {"d_th": d_th, "theta_th": theta_th, "speed_th": speed_th}
    if task == "baseline":
        return baseline_success(target, robot_pos, robot_angle, robot_vel, **thresholds)
    return proposed_success(target, subgoal, robot_pos, robot_vel, **thresholds)


def collided(robot_pos: np.ndarray, obs_pos: np.ndarray, distance: float = COLLISION_DISTANCE) -> np.ndarray:
    """The robot's centre is closer than `distance` to any obstacle's centre.

    Args:
        robot_pos: (N, 2) m. obs_pos: (N, K, 2) m; K = 0 never collides.

    Returns:
        (N,) bool.
    """
    return nearest_obstacle_distance(robot_pos, obs_pos) < distance
