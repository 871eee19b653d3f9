from __future__ import annotations

import numpy as np
import pytest
import torch

from hier_ssl.envs import make_scenario, parse_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.planners import make_planner
from hier_ssl.manager.encounter import ENCOUNTER_DIM, encounter_columns
from hier_ssl.manager.neighbours import drop_encounters, neighbour_obs_dim, neighbour_observation


def _columns(rel_pos, rel_vel, robot_vel, to_target) -> np.ndarray:
    args = [np.asarray(a, dtype=np.float64)[None] for a in (rel_pos, rel_vel, robot_vel, to_target)]
    return np.stack(encounter_columns(*args, max_pos=1.0, clip=10.0), axis=2)[0]


def test_encounter_columns_by_hand() -> None:
    # Robot at rest heading for a target 4 m along +x; neighbour A 2 m ahead, 0.5 m to the left, crossing
    # down at 1 m/s; neighbour B 1 m behind, still.
    cols = _columns([[2.0, 0.5], [-1.0, 0.0]], [[0.0, -1.0], [0.0, 0.0]], [[0.0, 0.0]], [[4.0, 0.0]])
    # A, constant velocities: closest at t = 0.5 s, distance 2 m. Straight at 2 m/s: relative velocity
    # (-2, -1), t = -(2*-2 + 0.5*-1) / 5 = 0.9 s, gap (2 - 1.8, 0.5 - 0.9) = (0.2, -0.4).
    want_a = [0.5 / 3.0, 2.0, 0.9 / 3.0, np.hypot(0.2, -0.4), 2.0, 0.5]
    # B: still relative to a still robot (no approach: t = 0, d = 1); the robot drives away from it.
    want_b = [0.0, 1.0, 0.0, 1.0, -1.0, 0.0]
    np.testing.assert_allclose(cols, [want_a, want_b], atol=1e-9)


def test_closest_approach_times_are_capped() -> None:
    # Head-on at 0.1 m/s, 10 m apart: the approach is at 100 s, reported at the 3 s horizon; driving 1 m to
    # the target at 2 m/s, the straight-line one stops at the arrival, 0.5 s.
    cols = _columns([[10.0, 0.0]], [[-0.1, 0.0]], [[0.0, 0.0]], [[1.0, 0.0]])
    np.testing.assert_allclose(cols[0, [0, 1, 2, 3]], [1.0, 9.7, 0.5 / 3.0, 10.0 - 0.05 - 1.0], atol=1e-9)


def test_numpy_and_torch_give_the_same_columns() -> None:
    rng = np.random.default_rng(0)
    arrays = [rng.normal(size=shape) for shape in ((5, 3, 2), (5, 3, 2), (5, 1, 2), (5, 1, 2))]
    want = encounter_columns(*arrays, max_pos=3.8, clip=1.2)
    got = encounter_columns(*(torch.from_numpy(a) for a in arrays), max_pos=3.8, clip=1.2)
    for w, g in zip(want, got, strict=True):
        np.testing.assert_allclose(g.numpy(), w, rtol=0, atol=1e-12)
        assert np.abs(w).max() <= 1.2


def test_encounters_layout_appends_zero_padded_columns() -> None:
    target = np.array([[2.0, 0.0, 0.0, 0.0, 0.0]])
    own = (target, np.array([[0.0, 0.0]]), np.zeros(1), np.zeros((1, 2)), np.zeros(1))
    others = (np.array([[[1.0, 0.2]]]), np.zeros((1, 1, 2)), np.zeros((1, 1), dtype=bool))
    plain = neighbour_observation(*own, *others, 2)
    obs = neighbour_observation(*own, *others, 2, encounters=True)
    assert obs.shape == (1, neighbour_obs_dim(2, encounters=True)) == (1, 13 + 12 * 2)
    np.testing.assert_array_equal(drop_encounters(obs), plain)
    extra = obs[0, 13 + 6 * 2 :].reshape(2, ENCOUNTER_DIM)
    np.testing.assert_array_equal(extra[1], 0.0)  # the padding slot
    # The robot passes 0.2 m from the still neighbour, 1 m along the line, after 0.5 s at 2 m/s.
    np.testing.assert_allclose(extra[0, 2:], [0.5 / 3.0, 0.2 / 3.8, 1.0 / 3.8, 0.2 / 3.8], atol=1e-6)
    with pytest.raises(ValueError, match="13 \\+ 12k columns"):
        drop_encounters(obs[:, :-1])


def test_core_and_planner_read_the_encounters_layout() -> None:
    settings = {"task": "obstacle", "neighbours": 1, "action_frame": "target"}
    plain = parse_config({"env": {**settings, "observation": "neighbours"}}).task_config
    config = parse_config({"env": {**settings, "observation": "encounters"}}).task_config
    assert make_scenario(config).obs_dim == 25
    obs = HierarchicalCore(config, 4).reset(seed=3)[:, 0]
    same = HierarchicalCore(plain, 4).reset(seed=3)[:, 0]
    np.testing.assert_array_equal(obs[:, :19], same)
    np.testing.assert_array_equal(
        make_planner("sampling", config)(obs), make_planner("sampling", plain)(same)
    )
