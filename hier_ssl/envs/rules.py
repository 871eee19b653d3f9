"""The rules every control step applies per controlled robot, and the check of an action where it enters.

``Rules`` binds a task's success, collision and reward rules (the pure functions of ``hier_ssl.manager``)
to one config's thresholds, reward modes and weights, checked once when the core is built; the core scores
every scenario with it, on (field, robot) arrays. ``check_action`` is what the views run on
each agent's action, once, as it enters.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hier_ssl.config import TaskSettings
from hier_ssl.manager.rewards import (
    HIT_REWARD,
    SUCCESS_REWARD,
    RewardOptions,
    angle_reward,
    check_task,
    distance_reward,
    measured_errors,
    nearest_distance,
    pose_error,
    reward_terms,
    shaping_term,
)
from hier_ssl.manager.success import pose_reached, settled
from hier_ssl.world.frames import all_finite

# The decision terms: what a decision fixes for its control steps, whether each measured pose names its
# target (...) bool, and R_d + R_theta (...).
DecisionTerms = tuple[np.ndarray, np.ndarray]


@numba.njit(cache=True)
def _decision_terms(
    subgoal: np.ndarray,
    target: np.ndarray,
    d_th: float,
    theta_th: float,
    reached: np.ndarray,
    shaping: np.ndarray,
) -> None:
    """``Rules.decision_terms`` of the action-centric tasks as one compiled loop over the sub-goals and
    targets (N, M, 5): whether each sub-goal is on its target (``pose_reached``) and R_d + R_theta, written
    into ``reached`` and ``shaping`` (N, M)."""
    for f in range(reached.shape[0]):
        for i in range(reached.shape[1]):
            d, delta = pose_error(subgoal[f, i], target[f, i])
            reached[f, i] = pose_reached(d, delta, d_th, theta_th)
            shaping[f, i] = shaping_term(d, delta, d_th, theta_th)


def _as_pairs(lead: tuple[int, ...], arrays: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """``arrays`` with the leading axes ``lead`` on the two the compiled loops run over: themselves for
    the core's (N, M), views (B, 1, ...) of any others."""
    if len(lead) == 2:
        return arrays
    size = math.prod(lead)
    return tuple(a.reshape(size, 1, *a.shape[len(lead) :]) for a in arrays)


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

    The settings are checked here (``RewardOptions``) and held in the form the compiled loops below take:
    on the few rows of one field numpy's per-call overhead, not the arithmetic, is the cost, so each of
    ``decision_terms`` and ``__call__`` is one loop over the robots. The action-centric tasks measure the
    sub-goal, which a decision fixes for its control steps: ``decision_terms`` computes that part once a
    decision.
    """

    def __init__(self, task: str, config: TaskSettings) -> None:
        check_task(task)
        self.task = task
        modes = (config.success_mode, config.hit_mode)
        self.options = RewardOptions(*modes, config.success_weight, config.hit_weight, config.obstacle_from)
        self.d_th, self.theta_th = np.array(config.d_th), np.array(np.deg2rad(config.theta_th_deg))
        self._thresholds = (float(self.d_th), float(self.theta_th))
        paid = (config.success_weight * SUCCESS_REWARD, config.hit_weight * HIT_REWARD)
        self._settings = np.array([config.d_th, config.speed_th, config.collision_distance, *paid])
        replace = (config.success_mode == "replace", config.hit_mode == "replace")
        task_flags = (task != "baseline", replace[0], task == "obstacle", config.obstacle_from == "robot")
        self._flags = (*task_flags, replace[1])

    def _pose(self, d: np.ndarray, delta: np.ndarray) -> DecisionTerms:
        reached = pose_reached(d, delta, self.d_th, self.theta_th)
        return reached, distance_reward(d, self.d_th) + angle_reward(delta, self.theta_th)

    def decision_terms(self, target: np.ndarray, subgoal: np.ndarray) -> DecisionTerms | None:
        """The part of the rules that the sub-goals (..., 5) fix until the next decision, for targets
        (..., 5); None for the Baseline task, which measures the robot every step."""
        if self.task == "baseline":
            return None
        lead = target.shape[:-1]
        reached, shaping = np.empty(lead, dtype=bool), np.empty(lead)
        subgoal, target, *out = _as_pairs(lead, (subgoal, target, reached, shaping))
        _decision_terms(subgoal, target, *self._thresholds, *out)
        return reached, shaping

    def __call__(
        self,
        terms: DecisionTerms | None,
        target: np.ndarray,
        subgoal: np.ndarray,
        pos: np.ndarray,
        angle: np.ndarray,
        vel: np.ndarray,
        others: np.ndarray,
        touching: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reward, success and hit (...) of the controlled robots, given ``decision_terms``' result for these
        sub-goals and targets (None: computed here). The leading axes (...) are the core's (N, M).

        Shapes: target, subgoal (..., 5); pos, vel (..., 2); angle (...); others (..., J, 2), the robots
        each one can hit; touching (...) bool, a contact the physics reported.
        """
        if terms is None:
            terms = self._pose(*measured_errors(self.task, target, subgoal, pos, angle))
        lead = target.shape[:-1]
        reward, success, hit = np.empty(lead), np.empty(lead, dtype=bool), np.empty(lead, dtype=bool)
        rows = _as_pairs(lead, (*terms, target, subgoal, pos, vel, others, touching, reward, success, hit))
        _score(*rows[:8], self._settings, self._flags, *rows[8:])
        return reward, success, hit


@numba.njit(cache=True)
def _score(
    reached: np.ndarray,
    shaping: np.ndarray,
    target: np.ndarray,
    subgoal: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    others: np.ndarray,
    touching: np.ndarray,
    settings: np.ndarray,
    flags: tuple[bool, bool, bool, bool, bool],
    reward: np.ndarray,
    success: np.ndarray,
    hit: np.ndarray,
) -> None:
    """``Rules.__call__`` as one compiled loop over the robots (N, M), calling the rules of
    ``hier_ssl.manager`` on each: ``settled``, ``nearest_distance`` and ``reward_terms``.

    Shapes: reached, shaping, touching (N, M); target, subgoal (N, M, 5); pos, vel (N, M, 2); others
    (N, M, J, 2).
    ``settings``: d_th, speed_th, collision distance, R_t paid, R_hit paid; ``flags``: success needs the
    robot near the target (action-centric tasks), success replaces the shaping, the obstacle task's
    terms, R_obst measured from the robot (not the sub-goal), a hit replaces the other terms.
    """
    d_th, speed_th, collision_distance, success_paid, hit_paid = settings
    near_target, replace_success, obstacle_task, from_robot, replace_hit = flags
    paid_modes = (success_paid, hit_paid, replace_success, replace_hit, obstacle_task)
    for f in range(reward.shape[0]):
        for i in range(reward.shape[1]):
            x, y = pos[f, i, 0], pos[f, i, 1]
            nearest = nearest_distance(x, y, others[f, i])  # +inf without another robot
            hit[f, i] = nearest < collision_distance or touching[f, i]
            # Success needs the measured pose on the target and the robot settled; a hit fails it.
            done = reached[f, i] and not hit[f, i]
            if done:
                tx, ty = target[f, i, 0], target[f, i, 1]
                done = settled(x, y, vel[f, i, 0], vel[f, i, 1], tx, ty, d_th, speed_th, near_target)
            success[f, i] = done
            if obstacle_task and not from_robot:
                nearest = nearest_distance(subgoal[f, i, 0], subgoal[f, i, 1], others[f, i])
            keep, paid, obstacle, hit_term = reward_terms(done, hit[f, i], nearest, *paid_modes)
            pose = shaping[f, i] if keep else 0.0
            reward[f, i] = pose + paid + obstacle + hit_term if obstacle_task else pose + paid


__all__ = ["DecisionTerms", "Rules", "check_action"]
