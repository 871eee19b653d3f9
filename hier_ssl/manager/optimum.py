"""Whether a reward's optimum finishes: hovering inside the thresholds against finishing.

Inside D_th and theta_th the shaping terms pay a bonus every control step (R_d = +10, R_theta = +1), and
they keep paying while the sub-goal (Proposed, Obstacle) or the robot (Baseline) stays there without the
success test being met (the robot not yet stopped on the target, or a sub-goal held a few centimetres
off). Truncation at ``max_steps`` bootstraps, so a learner values that stream as endless: b / (1 - gamma),
b the bonus of one decision (summed over the ``frame_skip`` held control steps, or the last step's alone).

Finishing pays R_t = success_weight * 1000 once. Where the policy can finish now and could also hover k
decisions first, finishing now is optimal for every k exactly when R_t >= b / (1 - gamma): hovering one
decision and then finishing is worth b + gamma * R_t, which R_t beats iff R_t (1 - gamma) >= b, and the
same inequality bounds every longer hover. The in-threshold bonus a finishing decision also collects
before its success step only helps finishing, so leaving it out makes the test conservative.

The paper's public code (gamma 0.99, last step's reward, 11 a decision) gives 1,100 against 1,000: its
optimum hovers, by a little. Summed over 16 held steps (176 a decision) hovering is worth 17,600 at gamma
0.99 and 3,520 at 0.95.
"""

from __future__ import annotations

from hier_ssl.manager.rewards import (
    ANGLE_THRESHOLD,
    DIST_THRESHOLD,
    SUCCESS_REWARD,
    angle_reward,
    distance_reward,
)


def in_threshold_bonus(frame_skip: int, summation: str) -> float:
    """b: what one decision inside both thresholds pays in shaping, ``summation`` "sum" (over the held
    control steps) or "last" (the last step's reward, as the paper's public code)."""
    if summation not in ("sum", "last"):
        raise ValueError(f"unknown frame_skip_reward {summation!r}; expected 'sum' or 'last'")
    per_step = float(distance_reward(0.0, DIST_THRESHOLD) + angle_reward(0.0, ANGLE_THRESHOLD))
    return per_step * (frame_skip if summation == "sum" else 1)


def hover_value(gamma: float, frame_skip: int, summation: str) -> float:
    """b / (1 - gamma): the discounted value of hovering inside the thresholds forever (inf at gamma 1)."""
    bonus = in_threshold_bonus(frame_skip, summation)
    return float("inf") if gamma >= 1.0 else bonus / (1.0 - gamma)


def finish_value(success_weight: float) -> float:
    """R_t: what finishing pays, the in-threshold bonus of the finishing decision left out."""
    return success_weight * SUCCESS_REWARD


def finishing_wins(gamma: float, frame_skip: int, summation: str, success_weight: float) -> bool:
    """Whether finishing now beats hovering for any number of decisions (module docstring)."""
    return finish_value(success_weight) >= hover_value(gamma, frame_skip, summation)


__all__ = ["finish_value", "finishing_wins", "hover_value", "in_threshold_bonus"]
