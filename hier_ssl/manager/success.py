"""Success and failure predicates of the manager's tasks (docs/paper.md "Tasks and when an episode succeeds").

Comparisons are strict (d < D_th), as in the public code; the reward's bonus applies at
d <= D_th, a difference only on a set of measure zero.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hier_ssl.manager.rewards import (
    ANGLE_THRESHOLD,
    DIST_THRESHOLD,
    check_task,
    measured_errors,
    nearest_obstacle_distance,
)

SPEED_THRESHOLD = 0.05  # m/s: the robot counts as stopped below this
COLLISION_DISTANCE = 0.2  # m, centre to centre: two robot radii of 0.09 m plus a margin


@numba.vectorize(["boolean(float64, float64, float64, float64)"], cache=True)
def pose_reached(d: float, delta: float, d_th: float, theta_th: float) -> bool:
    """The measured pose is within d_th of the target and theta_th of its heading: d, delta (any shape) ->
    bool. A ufunc over arrays and, inside compiled code, a function of one value (the core's scoring)."""
    return d < d_th and delta < theta_th


@numba.vectorize(
    ["boolean(float64, float64, float64, float64, float64, float64, float64, float64, boolean)"], cache=True
)
def settled(
    x: float, y: float, vx: float, vy: float, tx: float, ty: float, d_th: float, speed_th: float, near: bool
) -> bool:
    """The robot at (x, y) moving at (vx, vy) is slower than speed_th and, if ``near``, within d_th of the
    target point (tx, ty). A ufunc, as ``pose_reached``."""
    if not math.sqrt(vx * vx + vy * vy) < speed_th:
        return False
    dx, dy = x - tx, y - ty
    return not near or math.sqrt(dx * dx + dy * dy) < d_th


def robot_settled(
    task: str, target: np.ndarray, robot_pos: np.ndarray, robot_vel: np.ndarray, d_th: float, speed_th: float
) -> np.ndarray:
    """``settled``: in the action-centric tasks the robot must also be within d_th of the target (its
    heading is not checked: docs/paper.md, public code).
    target (N, 5); robot_pos, robot_vel (N, 2) -> (N,) bool."""
    x, y, vx, vy = robot_pos[..., 0], robot_pos[..., 1], robot_vel[..., 0], robot_vel[..., 1]
    return settled(x, y, vx, vy, target[..., 0], target[..., 1], d_th, speed_th, task != "baseline")


def task_success(
    task: str,
    target: np.ndarray,
    subgoal: np.ndarray | None,
    robot_pos: np.ndarray,
    robot_angle: np.ndarray | None,
    robot_vel: np.ndarray,
    *,
    d_th: float = DIST_THRESHOLD,
    theta_th: float = ANGLE_THRESHOLD,
    speed_th: float = SPEED_THRESHOLD,
) -> np.ndarray:
    """Success of `task`: "baseline", the robot within d_th and theta_th of the target and slower than
    speed_th; "proposed" or "obstacle", the sub-goal within d_th and theta_th of the target and the robot
    within d_th of it and slower than speed_th (its heading is not checked).

    Args:
        target: (N, 5). subgoal: (N, 5), not read by "baseline". robot_pos: (N, 2). robot_angle: (N,),
            read by "baseline" only. robot_vel: (N, 2).

    Returns:
        (N,) bool.
    """
    check_task(task)
    d, delta = measured_errors(task, target, subgoal, robot_pos, robot_angle)
    settled = robot_settled(task, target, robot_pos, robot_vel, d_th, speed_th)
    return pose_reached(d, delta, d_th, theta_th) & settled


def baseline_success(
    target: np.ndarray,
    robot_pos: np.ndarray,
    robot_angle: np.ndarray,
    robot_vel: np.ndarray,
    **thresholds: float,
) -> np.ndarray:
    """``task_success`` of the Baseline task: target (N, 5), robot_pos (N, 2), robot_angle (N,),
    robot_vel (N, 2) -> (N,) bool."""
    return task_success("baseline", target, None, robot_pos, robot_angle, robot_vel, **thresholds)


def proposed_success(
    target: np.ndarray, subgoal: np.ndarray, robot_pos: np.ndarray, robot_vel: np.ndarray, **thresholds: float
) -> np.ndarray:
    """``task_success`` of the Proposed task: target, subgoal (N, 5), robot_pos, robot_vel (N, 2) -> (N,)
    bool."""
    return task_success("proposed", target, subgoal, robot_pos, None, robot_vel, **thresholds)


def collided(robot_pos: np.ndarray, obs_pos: np.ndarray, distance: float = COLLISION_DISTANCE) -> np.ndarray:
    """The robot's centre is closer than `distance` to any obstacle's centre.

    Args:
        robot_pos: (N, 2) m. obs_pos: (N, K, 2) m; K = 0 never collides.

    Returns:
        (N,) bool.
    """
    return nearest_obstacle_distance(robot_pos, obs_pos) < distance
