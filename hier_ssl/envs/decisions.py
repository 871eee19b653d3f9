"""A manager decision's per-robot book-keeping in the core: the sub-goals taken, the decisions counted, the
CPAD grown and the action values clipped, as one compiled loop over the robots (at one field numpy's
per-call overhead, not the arithmetic, was the cost of the dozen array operations this replaces)."""

from __future__ import annotations

import numba
import numpy as np

from hier_ssl.manager.rewards import pose_error


@numba.njit(cache=True)
def take_decisions(
    action: np.ndarray,
    decoded: np.ndarray,
    live: np.ndarray,
    subgoal: np.ndarray,
    decisions: np.ndarray,
    cpad: np.ndarray,
    clipped: np.ndarray,
) -> None:
    """The ``live`` (N, M) robots take their ``decoded`` sub-goals (N, M, 5) in place of ``subgoal``: their
    ``decisions`` count one more, ``cpad`` grows by the sub-goal's move (``cpad_increment``; not at a
    robot's first decision, whose held sub-goal was its own start pose) and ``clipped`` (N, M) counts the
    values of ``action`` (N, M, A) outside [-1, 1] (0 where not live). One compiled loop over the robots."""
    for f in range(live.shape[0]):
        for i in range(live.shape[1]):
            clipped[f, i] = 0
            if not live[f, i]:
                continue
            for value in action[f, i]:
                clipped[f, i] += abs(value) > 1.0
            if decisions[f, i] > 0:
                cpad[f, i] += pose_error(decoded[f, i], subgoal[f, i])[0]
            subgoal[f, i] = decoded[f, i]
            decisions[f, i] += 1


__all__ = ["take_decisions"]
