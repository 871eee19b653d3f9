from __future__ import annotations

import numpy as np
import pytest
import torch

from hier_ssl.manager.candidate_points import candidate_points, candidate_weights

RING = np.array([0.5, 0.5j])  # ahead of the obstacle along the line, and to its left
ALONG, ACROSS = np.array([0.5]), np.array([1.0])
ESCAPE = np.array([-0.6])  # behind the robot
HALF = np.array([3.0, 2.0])


def test_candidates_are_named_in_the_frame_of_the_robot_to_target_line() -> None:
    # Robot at the origin, target straight up (+y): "along" is +y and "left" is -x.
    points = np.array([[[0.0, 2.0], [0.0, 0.0], [1.0, 1.0]]])
    weights, turns = candidate_weights(RING, ALONG, ACROSS, ESCAPE, 1)
    cand = candidate_points(points, weights, turns, -HALF, HALF)
    want = [[0.0, 2.0], [0.0, 0.0], [1.0, 1.5], [0.5, 1.0], [-1.0, 1.0], [0.0, -0.6]]
    np.testing.assert_allclose(cand[0], want, atol=1e-15)
    # Clipped to the field: a target beyond the touch line stays on it.
    far = candidate_points(points * 3.0, weights, turns, -HALF, HALF)
    np.testing.assert_allclose(far[0, 0], [0.0, 2.0])


def test_torch_tensors_give_the_numpy_candidates() -> None:
    rng = np.random.default_rng(0)
    points = rng.uniform(-3, 3, (50, 5, 2))
    weights, turns = candidate_weights(RING, ALONG, ACROSS, ESCAPE, 3)
    want = candidate_points(points, weights, turns, -HALF, HALF)
    as_torch = [torch.from_numpy(a) for a in (points, weights, turns, -HALF, HALF)]
    np.testing.assert_allclose(candidate_points(*as_torch).numpy(), want, rtol=0, atol=1e-15)


def test_a_negative_obstacle_count_is_an_error() -> None:
    with pytest.raises(ValueError, match="num_obstacles must be >= 0, got -1"):
        candidate_weights(RING, ALONG, ACROSS, ESCAPE, -1)
