"""The rules every control step applies per controlled robot, and the check of an action where it enters.

``score_control_step`` runs the pure functions of ``hier_ssl.manager`` (success, collision, reward) on the
(field, robot) pairs as rows, with a task config's thresholds, reward modes and weights: the core scores
every scenario with it. ``check_action`` is what the views run on each agent's action, once, as it enters.
"""

from __future__ import annotations

import numpy as np

from hier_ssl.config import TaskSettings
from hier_ssl.manager import collided, task_reward, task_success


def check_action(name: str, action: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as float64 of ``shape``; a ValueError names ``name`` for a wrong shape, NaN or inf."""
    action = np.asarray(action, dtype=np.float64)
    if action.shape != shape:
        raise ValueError(f"action of {name} has shape {action.shape}, expected {shape}")
    if not np.isfinite(action).all():
        raise ValueError(f"action of {name} holds NaN or infinite values: {action.tolist()}")
    return action


def score_control_step(
    task: str,
    config: TaskSettings,
    target: np.ndarray,
    subgoal: np.ndarray,
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    others: np.ndarray,
    touching: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Success, collision and reward of one control step of B controlled robots (rows), by the pure
    functions of ``hier_ssl.manager`` with ``config``'s thresholds, reward modes and weights.

    Shapes: target, subgoal (B, 5); pos, vel (B, 2); angle (B,); others (B, J, 2), the robots each one can
    hit; touching (B,) bool, a contact the physics reported. Returns reward, success, hit (B,) and the
    reward terms.
    """
    thresholds = {"d_th": config.d_th, "theta_th": np.deg2rad(config.theta_th_deg)}
    success = task_success(task, target, subgoal, pos, angle, vel, speed_th=config.speed_th, **thresholds)
    hit = collided(pos, others, config.collision_distance) | touching
    extra = {"obs_pos": others, "hit": hit} if task == "obstacle" else {}
    reward, terms = task_reward(
        task,
        target,
        pos,
        angle,
        subgoal,
        success,
        success_mode=config.success_mode,
        hit_mode=config.hit_mode,
        success_weight=config.success_weight,
        hit_weight=config.hit_weight,
        obstacle_from=config.obstacle_from,
        **extra,
        **thresholds,
    )
    return reward, success, hit, terms


__all__ = ["check_action", "score_control_step"]
