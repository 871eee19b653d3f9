"""The manager's reward terms (paper section 3, SPEC "Rewards") as vectorised pure functions.

R = R_d + R_theta + R_t (+ R_obst + R_hit in the obstacle task), with d and delta the
distance and angle difference to the target, measured on the robot (Baseline) or on the
manager's sub-goal (Proposed, Obstacle: "action-centric").

The paper prints R_t = 1000 "if dist > D_th and delta > theta_th", an evident sign slip:
R_t is paid on the success step, whose predicate lives in `hier_ssl.manager.success`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

DIST_THRESHOLD = 0.05  # D_th, m
ANGLE_THRESHOLD = math.radians(5.0)  # theta_th, rad
DIST_BONUS = 10.0  # R_d inside D_th
ANGLE_BONUS = 1.0  # R_theta inside theta_th
SUCCESS_REWARD = 1000.0
HIT_REWARD = -1000.0

TASKS = ("baseline", "proposed", "obstacle")
SUCCESS_MODES = ("add", "replace")
HIT_MODES = ("add", "replace")
# Where R_obst measures its distance to the nearest obstacle: the paper's text says the sub-goal, its public
# code the robot.
OBSTACLE_FROM = ("subgoal", "robot")
REWARD_TERMS = ("distance", "angle", "success", "obstacle", "hit")


def wrap_angle(angle: ArrayLike) -> np.ndarray:
    """Angles (any shape, rad) wrapped into [-pi, pi)."""
    return np.mod(np.asarray(angle, dtype=np.float64) + np.pi, 2.0 * np.pi) - np.pi


def pose_errors(pose_a: np.ndarray, pose_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance and absolute angle difference between two batches of poses.

    Args:
        pose_a, pose_b: (N, 3) x, y, theta or (N, 5) x, y, theta, vx, vy; only x, y, theta
            are read, so sub-goals and targets can be passed as they are.

    Returns:
        distance (N,) in m and delta (N,) in [0, pi] rad.
    """
    distance = np.linalg.norm(pose_a[:, 0:2] - pose_b[:, 0:2], axis=1)
    delta = np.abs(wrap_angle(pose_a[:, 2] - pose_b[:, 2]))
    return distance, delta


def nearest_obstacle_distance(point: np.ndarray, obs_pos: np.ndarray) -> np.ndarray:
    """Centre distance from each field's point to its nearest obstacle.

    Args:
        point: (N, 2) m. obs_pos: (N, K, 2) m, K >= 0.

    Returns:
        (N,) m; +inf where K = 0, so thresholds and Gaussians of it read "no obstacle".
    """
    distances = np.linalg.norm(obs_pos - point[:, None, :], axis=2)
    return np.min(distances, axis=1, initial=np.inf)


def distance_reward(d: ArrayLike, d_th: float = DIST_THRESHOLD) -> np.ndarray:
    """R_d: -d where d > d_th, else +10. d: any shape, m."""
    d = np.asarray(d, dtype=np.float64)
    return np.where(d > d_th, -d, DIST_BONUS)


def angle_reward(delta: ArrayLike, theta_th: float = ANGLE_THRESHOLD) -> np.ndarray:
    """R_theta: -delta / pi where delta > theta_th, else +1. delta: any shape, rad in [0, pi]."""
    delta = np.asarray(delta, dtype=np.float64)
    return np.where(delta > theta_th, -delta / np.pi, ANGLE_BONUS)


def obstacle_reward(o: ArrayLike) -> np.ndarray:
    """R_obst = -N(o; 0, 1) = -exp(-o^2 / 2) / sqrt(2 pi). o: any shape, m (may be +inf)."""
    o = np.asarray(o, dtype=np.float64)
    return -np.exp(-0.5 * o**2) / math.sqrt(2.0 * math.pi)


def task_reward(
    task: str,
    target: np.ndarray,
    robot_pos: np.ndarray,
    robot_angle: np.ndarray,
    subgoal: np.ndarray,
    success: np.ndarray,
    *,
    obs_pos: np.ndarray | None = None,
    hit: np.ndarray | None = None,
    success_mode: str = "add",
    hit_mode: str = "add",
    success_weight: float = 1.0,
    hit_weight: float = 1.0,
    obstacle_from: str = "subgoal",
    d_th: float = DIST_THRESHOLD,
    theta_th: float = ANGLE_THRESHOLD,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Reward of one control step in N fields for the Baseline, Proposed or Obstacle task.

    Args:
        task: "baseline" (d, delta of the robot), "proposed" (d, delta of the sub-goal) or
            "obstacle" (proposed, plus R_obst on the sub-goal's distance to the nearest
            obstacle and R_hit).
        target: (N, 5) target pose. robot_pos: (N, 2). robot_angle: (N,) rad. Arrays of these shapes are
            trusted (the views and the world check what enters).
        subgoal: (N, 5) the manager's decoded sub-goal.
        success: (N,) bool, this step reached the task's success predicate.
        obs_pos: (N, K, 2) obstacle positions; required by, and only accepted for, "obstacle".
        hit: (N,) bool, the robot collided this step; same rule as obs_pos.
        success_mode: "add" (paper text: R_d + R_theta + 1000 on success) or "replace"
            (public code: 1000 instead of R_d + R_theta on success; R_obst still added).
        hit_mode: "add" (paper text: R_hit = -1000 added to the other terms) or "replace"
            (public code: the step's reward is -1000 alone).
        success_weight, hit_weight: multiply R_t (+1000) and R_hit (-1000); 1 is the paper's. A detour's
            shaping cost can exceed the expected cost of driving into an obstacle, and the in-threshold
            bonuses summed over a frame-skip period can pay more for dithering near the target than R_t
            pays for finishing: these re-price both.
        obstacle_from: "subgoal" (paper text) or "robot" (public code): the point R_obst measures from.
        d_th, theta_th: thresholds of R_d (m) and R_theta (rad).

    Returns:
        total (N,) and a dict of the (N,) terms named in REWARD_TERMS, zero where a term does
        not apply, so that the terms always sum to the total and can be logged as they are.
    """
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; expected one of {TASKS}")
    if success_mode not in SUCCESS_MODES:
        raise ValueError(f"unknown success_mode {success_mode!r}; expected one of {SUCCESS_MODES}")
    if hit_mode not in HIT_MODES:
        raise ValueError(f"unknown hit_mode {hit_mode!r}; expected one of {HIT_MODES}")
    if obstacle_from not in OBSTACLE_FROM:
        raise ValueError(f"unknown obstacle_from {obstacle_from!r}; expected one of {OBSTACLE_FROM}")
    for name, weight in (("success_weight", success_weight), ("hit_weight", hit_weight)):
        if not math.isfinite(weight) or weight < 0:
            raise ValueError(f"{name} must be finite and >= 0, got {weight}")
    n = target.shape[0]
    if task == "obstacle":
        if obs_pos is None or hit is None:
            raise ValueError("task 'obstacle' needs obs_pos and hit")
    elif obs_pos is not None or hit is not None:
        raise ValueError(f"obs_pos and hit are only used by task 'obstacle', not {task!r}")

    measured = np.column_stack([robot_pos, robot_angle]) if task == "baseline" else subgoal
    d, delta = pose_errors(measured, target)
    terms = {
        "distance": distance_reward(d, d_th),
        "angle": angle_reward(delta, theta_th),
        "success": np.where(success, success_weight * SUCCESS_REWARD, 0.0),
        "obstacle": np.zeros(n),
        "hit": np.zeros(n),
    }
    if success_mode == "replace":
        for name in ("distance", "angle"):
            terms[name] = np.where(success, 0.0, terms[name])
    if task == "obstacle":
        point = subgoal[:, 0:2] if obstacle_from == "subgoal" else robot_pos
        terms["obstacle"] = obstacle_reward(nearest_obstacle_distance(point, obs_pos))
        terms["hit"] = np.where(hit, hit_weight * HIT_REWARD, 0.0)
        if hit_mode == "replace":
            for name in ("distance", "angle", "success", "obstacle"):
                terms[name] = np.where(hit, 0.0, terms[name])
    total = np.sum([terms[name] for name in REWARD_TERMS], axis=0)
    return total, terms
