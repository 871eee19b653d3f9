"""Episode metrics of the paper's section 6 as pure functions.

CPAD (Cumulative Pairwise Action Distance) = sum over the episode of the distance between
consecutive (x, y) sub-goals, one sub-goal per control step. Lower is steadier.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from hier_ssl.manager.observation import check_array
from hier_ssl.manager.rewards import vector_length

CPAD_VARIANTS = ("paper", "public_code")


def cpad(subgoals_xy: ArrayLike, variant: str = "paper") -> float:
    """CPAD of one episode.

    Args:
        subgoals_xy: (T, 2) the (x, y) sub-goal in force at each of the T control steps, m.
            Under frame skip a sub-goal held for 16 steps appears 16 times and its repeats
            add 0, so the value is comparable with and without frame skip.
        variant: "paper" (the paper's definition, sum_i ||a_{i+1} - a_i||) or "public_code":
            the paper's code takes the Frobenius norm of the (T-1, 2) difference matrix,
            sqrt(sum_i ||a_{i+1} - a_i||^2), which never exceeds the paper's sum and equals
            it only when at most one step moves. Its tables were produced that way.

    Returns:
        CPAD in m; 0 for T < 2.
    """
    if variant not in CPAD_VARIANTS:
        raise ValueError(f"unknown CPAD variant {variant!r}; expected one of {CPAD_VARIANTS}")
    subgoals_xy = check_array("subgoals_xy", subgoals_xy, (None, 2))
    steps = np.linalg.norm(np.diff(subgoals_xy, axis=0), axis=1)
    if variant == "paper":
        return float(np.sum(steps))
    return float(np.sqrt(np.sum(steps**2)))


def cpad_increment(prev_xy: np.ndarray, new_xy: np.ndarray) -> np.ndarray:
    """One control step's contribution to the paper's CPAD, in N fields at once.

    A vector env adds this to a per-field accumulator every control step (sub-steps of a
    frame skip included: a held sub-goal adds 0) and zeroes the accumulator at reset. At an
    episode's first step there is no previous sub-goal: pass new_xy as prev_xy to add 0.
    The "public_code" variant accumulates the squares of these increments and takes the
    square root at the episode's end.

    Args:
        prev_xy, new_xy: (..., 2) the previous and the current (x, y) sub-goal, m.

    Returns:
        (...) m.
    """
    return vector_length(new_xy - prev_xy)


def summarize(values: ArrayLike) -> dict[str, float]:
    """The paper's table entry for one metric over test episodes: median (Q1 - Q3), max, min.

    Args:
        values: (E,) one value per episode, E >= 1.

    Returns:
        {"median", "q1", "q3", "min", "max"} as floats; quartiles by numpy's default
        (linear) percentile interpolation.
    """
    values = check_array("values", values, (None,))
    if values.size == 0:
        raise ValueError("values must hold at least one episode, got an empty array")
    q1, median, q3 = np.percentile(values, [25.0, 50.0, 75.0])
    return {
        "median": float(median),
        "q1": float(q1),
        "q3": float(q3),
        "min": float(np.min(values)),
        "max": float(np.max(values)),
    }


def min_time_to_pose(distance: ArrayLike, v_max: float, a_max: float) -> np.ndarray:
    """Shortest time of a rest-to-rest straight-line move under speed and acceleration limits.

    Accelerating at a_max and braking at a_max covers v_max^2 / a_max before reaching v_max.
    Shorter moves never reach it (triangular profile): t = 2 sqrt(d / a_max). Longer ones
    cruise at v_max in between (trapezoidal profile): t = d / v_max + v_max / a_max. The two
    agree at d = v_max^2 / a_max. A lower bound on episode duration to judge learned paths by.

    Args:
        distance: any shape, m, >= 0. v_max: m/s, > 0. a_max: m/s^2, > 0.

    Returns:
        times in s, shaped like distance.
    """
    if not v_max > 0:
        raise ValueError(f"v_max must be > 0, got {v_max}")
    if not a_max > 0:
        raise ValueError(f"a_max must be > 0, got {a_max}")
    distance = np.asarray(distance, dtype=np.float64)
    if np.any(distance < 0):
        raise ValueError(f"distance must be >= 0, got min {np.min(distance)}")
    triangular = 2.0 * np.sqrt(distance / a_max)
    trapezoidal = distance / v_max + v_max / a_max
    return np.where(distance < v_max**2 / a_max, triangular, trapezoidal)
