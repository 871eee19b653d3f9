"""The rules every control step applies per controlled robot, and the check of an action where it enters.

``Rules`` binds a task's success, collision and reward rules (the pure functions of ``hier_ssl.manager``)
to one config's thresholds, reward modes and weights, checked once when the core is built; the core scores
every scenario with it, on (field, robot) arrays. ``check_action`` is what the views run on
each agent's action, once, as it enters.
"""

from __future__ import annotations

import numba
import numpy as np

from hier_ssl.config import TaskSettings
from hier_ssl.manager.rewards import (
    RewardOptions,
    angle_reward,
    check_task,
    combine_rewards,
    distance_reward,
    measured_errors,
    obstacle_distance,
    pose_error,
    shaping_term,
)
from hier_ssl.manager.success import collided, pose_reached, robot_settled
from hier_ssl.world.frames import all_finite

# What a decision fixes for its control steps: whether each measured pose names its target (...) bool, and
# R_d + R_theta (...).
Held = tuple[np.ndarray, np.ndarray]


@numba.njit(cache=True)
def _held(
    subgoal: np.ndarray,
    target: np.ndarray,
    d_th: float,
    theta_th: float,
    reached: np.ndarray,
    shaping: np.ndarray,
) -> None:
    """``Rules.hold`` of the action-centric tasks as one compiled loop over the rows (B, 5) of sub-goals
    and targets: whether each sub-goal is on its target (d < d_th, delta < theta_th, as ``pose_reached``)
    and R_d + R_theta, written into ``reached`` and ``shaping`` (B,)."""
    for b in range(target.shape[0]):
        d, delta = pose_error(subgoal[b], target[b])
        reached[b] = d < d_th and delta < theta_th
        shaping[b] = shaping_term(d, delta, d_th, theta_th)


def check_action(name: str, action: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as float64 of ``shape``; a ValueError names ``name`` for a wrong shape, NaN or inf."""
    action = np.asarray(action, dtype=np.float64)
    if action.shape != shape:
        raise ValueError(f"action of {name} has shape {action.shape}, expected {shape}")
    if not all_finite(action):
        raise ValueError(f"action of {name} holds NaN or infinite values: {action.tolist()}")
    return action


class Rules:
    """Success, collision and reward of one control step for ``task`` ("baseline", "proposed" or
    "obstacle": the rules of ``hier_ssl.manager`` that score a robot) with ``config``'s settings.

    The settings are checked here and held as 0-d arrays: a Python float operand costs numpy a conversion
    on every call, and on the few rows of one field the calls are the cost. The action-centric tasks measure
    the sub-goal, which a decision fixes for its control steps: ``hold`` computes that part once a decision.
    """

    def __init__(self, task: str, config: TaskSettings) -> None:
        check_task(task)
        self.task = task
        modes = (config.success_mode, config.hit_mode)
        self.options = RewardOptions(*modes, config.success_weight, config.hit_weight, config.obstacle_from)
        self.d_th, self.theta_th = np.array(config.d_th), np.array(np.deg2rad(config.theta_th_deg))
        self.speed_th = np.array(config.speed_th)
        self.collision_distance = np.array(config.collision_distance)

    def _pose(self, d: np.ndarray, delta: np.ndarray) -> Held:
        reached = pose_reached(d, delta, self.d_th, self.theta_th)
        return reached, distance_reward(d, self.d_th) + angle_reward(delta, self.theta_th)

    def hold(self, target: np.ndarray, subgoal: np.ndarray) -> Held | None:
        """The part of the rules that the sub-goals (..., 5) fix until the next decision, for targets
        (..., 5); None for the Baseline task, which measures the robot every step."""
        if self.task == "baseline":
            return None
        rows = (subgoal.reshape(-1, 5), target.reshape(-1, 5), float(self.d_th), float(self.theta_th))
        reached, shaping = np.empty(target.shape[:-1], dtype=bool), np.empty(target.shape[:-1])
        _held(*rows, reached.reshape(-1), shaping.reshape(-1))
        return reached, shaping

    def __call__(
        self,
        held: Held | None,
        target: np.ndarray,
        subgoal: np.ndarray,
        pos: np.ndarray,
        angle: np.ndarray,
        vel: np.ndarray,
        others: np.ndarray,
        touching: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reward, success and hit (...) of the controlled robots, given ``hold``'s result for these
        sub-goals and targets (None: computed here). The leading axes (...) are the core's (N, M).

        Shapes: target, subgoal (..., 5); pos, vel (..., 2); angle (...); others (..., J, 2), the robots
        each one can hit; touching (...) bool, a contact the physics reported.
        """
        if held is None:
            held = self._pose(*measured_errors(self.task, target, subgoal, pos, angle))
        reached, shaping = held
        # Success needs the measured pose on the target first; the robot is looked at only then.
        success = reached.copy()
        if np.count_nonzero(reached):
            success &= robot_settled(self.task, target, pos, vel, self.d_th, self.speed_th)
        # Without another robot in the field there is nothing to hit.
        hit = collided(pos, others, self.collision_distance) | touching if others.shape[-2] else touching
        # A hit fails the episode, also on the control step that would have been a success.
        success = success > hit
        nearest = None
        if self.task == "obstacle":
            nearest = obstacle_distance(self.options.obstacle_from, subgoal, pos, others)
        reward, _ = combine_rewards({"pose": shaping}, success, self.options, nearest, hit)
        return reward, success, hit


__all__ = ["Held", "Rules", "check_action"]
