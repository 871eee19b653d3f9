"""The ``sampling`` planner's candidate sub-goals as one linear map of the scene's points, for the planner
(numpy) and the candidate managers (torch, ``hier_ssl.policies.candidate_graph``) alike.

Every candidate is a weighted sum of the target, the robot and the obstacles, plus a turn of the unit
vector of the robot -> target line (a ring point left of an obstacle stays left of it in every field). So
the candidates of N scenes are ``weights @ points + unit @ turns``, clipped to the field: one matrix
product, written with the operators numpy arrays and torch tensors share, as
``hier_ssl.manager.encounter`` is. ``candidate_weights`` builds the two constant matrices in numpy; the
torch side holds them as buffers.

Order of the M = 2 + R K + S + E candidates: the target; the robot's own position (stop); R ring points
around each obstacle (obstacle-major); S points sampled in the frame of the line; E escape points on a ring
around the robot.
"""

from __future__ import annotations

import numpy as np


def candidate_weights(
    ring: np.ndarray, along: np.ndarray, across: np.ndarray, escape: np.ndarray, num_obstacles: int
) -> tuple[np.ndarray, np.ndarray]:
    """The maps of ``candidate_points`` for ``num_obstacles`` obstacles: weights (M, 2 + K) of the points
    and turns (M, 2, 2) of the line's unit vector, float64.

    Args:
        ring: (R,) complex offsets around an obstacle in the line's frame (x along the line, y to its left).
        along: (S,) fractions of the way to the target; across: (S,) m to the left of the line.
        escape: (E,) complex offsets around the robot in the line's frame.
    """
    if num_obstacles < 0:
        raise ValueError(f"num_obstacles must be >= 0, got {num_obstacles}")
    r, s, e, k = len(ring), len(along), len(escape), num_obstacles
    weights = np.zeros((2 + r * k + s + e, 2 + k))
    turn = np.zeros(2 + r * k + s + e, dtype=complex)  # the unit vector times this, as a complex product
    weights[0, 0] = weights[1, 1] = 1.0
    for j in range(k):
        rows = slice(2 + r * j, 2 + r * (j + 1))
        weights[rows, 2 + j] = 1.0
        turn[rows] = ring
    sampled = slice(2 + r * k, 2 + r * k + s)
    weights[sampled, 0], weights[sampled, 1] = along, 1.0 - along
    turn[sampled] = 1j * np.asarray(across)
    weights[2 + r * k + s :, 1] = 1.0
    turn[2 + r * k + s :] = escape
    # (x, y) times a + ib is (x, y) @ [[a, b], [-b, a]].
    turns = np.stack([np.stack([turn.real, turn.imag], -1), np.stack([-turn.imag, turn.real], -1)], -2)
    return weights, turns


def candidate_points(points, weights, turns, low, high):
    """Candidate sub-goals (N, M, 2) of scenes ``points`` (N, 2 + K, 2): the target, the robot, the
    obstacles (m); ``weights`` (M, 2 + K) and ``turns`` (M, 2, 2) from ``candidate_weights``; clipped to
    [low, high] (2,), the field. Numpy in, numpy out; torch in, torch out (all of one kind)."""
    (n, k, _), m = points.shape, len(weights)
    line = points[:, 0] - points[:, 1]  # (N, 2)
    length = ((line * line).sum(-1) ** 0.5).clip(min=1e-9)
    unit = line / length[:, None]
    # Two matrix products over the whole batch (not one small product a scene, as a broadcast matmul
    # runs): the turns as (2, M 2), the points as (2 + K, N 2).
    turned = (unit @ turns.swapaxes(0, 1).reshape(2, 2 * m)).reshape(n, m, 2)
    cand = turned + (weights @ points.swapaxes(0, 1).reshape(k, 2 * n)).reshape(m, n, 2).swapaxes(0, 1)
    return cand.clip(min=low, max=high)


__all__ = ["candidate_points", "candidate_weights"]
