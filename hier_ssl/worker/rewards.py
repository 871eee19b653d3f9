"""Reward terms of the goToPoint task, where the worker is the learner, as vectorised pure functions.

R = R_progress + R_time + R_smooth + R_success per control step:

- R_progress = phi(s) - phi(s'), with phi = d + angle_weight * delta / pi (d in m, delta in rad): a
  potential-based shaping term (Ng et al. 1999), so it pays for getting closer without changing which
  policy is optimal, and it sums over an episode to the pose error removed.
- R_time = -time_cost per step: the only term that rewards *quick* arrival.
- R_smooth = -smooth_cost * ||a_t - a_{t-1}||^2 on the normalised command: *smooth* driving.
- R_success = +success_bonus on the step the robot is within D_th, theta_th and slower than speed_th
  (``hier_ssl.manager.baseline_success``); the episode ends there.

The manager's R_d and R_theta are not reused: their +10 / +1 inside the thresholds would pay a worker
for hovering in the goal area faster than speed_th, forever, rather than for stopping there once. The
pose error itself is the manager's ``pose_errors``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

GOTOPOINT_REWARD_TERMS = ("progress", "time", "smooth", "success")


def pose_potential(d: ArrayLike, delta: ArrayLike, angle_weight: float) -> np.ndarray:
    """phi = d + angle_weight * delta / pi: distance (m) and angle error (rad, [0, pi]) as one cost."""
    return np.asarray(d, dtype=np.float64) + angle_weight * np.asarray(delta, dtype=np.float64) / np.pi


def progress_reward(phi_before: ArrayLike, phi_after: ArrayLike) -> np.ndarray:
    """R_progress = phi_before - phi_after: positive when the step reduced the pose error."""
    return np.asarray(phi_before, dtype=np.float64) - np.asarray(phi_after, dtype=np.float64)


def smooth_penalty(action: np.ndarray, prev_action: np.ndarray, cost: float) -> np.ndarray:
    """R_smooth = -cost * ||action - prev_action||^2. Shapes (N, 3) normalised commands -> (N,)."""
    return -cost * np.sum(np.square(action - prev_action), axis=1)


def gotopoint_reward(
    phi_before: ArrayLike,
    phi_after: ArrayLike,
    action: ArrayLike,
    prev_action: ArrayLike,
    success: ArrayLike,
    *,
    time_cost: float,
    smooth_cost: float,
    success_bonus: float,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Reward of one control step in N fields.

    Args:
        phi_before, phi_after: (N,) ``pose_potential`` before and after the step.
        action, prev_action: (N, 3) this step's and the previous step's normalised command.
        success: (N,) bool, the robot reached the sub-goal this step.
        time_cost, smooth_cost, success_bonus: the weights of the module docstring.

    Returns:
        total (N,) and the (N,) terms named in GOTOPOINT_REWARD_TERMS, which sum to the total.
    """
    n = len(action)
    terms = {
        "progress": progress_reward(phi_before, phi_after),
        "time": np.full(n, -time_cost),
        "smooth": smooth_penalty(action, prev_action, smooth_cost),
        "success": np.where(success, success_bonus, 0.0),
    }
    total = np.sum([terms[name] for name in GOTOPOINT_REWARD_TERMS], axis=0)
    return total, terms


__all__ = [
    "GOTOPOINT_REWARD_TERMS",
    "gotopoint_reward",
    "pose_potential",
    "progress_reward",
    "smooth_penalty",
]
