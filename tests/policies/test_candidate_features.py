from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.manager.planners import SamplingPlanner
from hier_ssl.policies.candidate_features import (
    candidate_features,
    closest_approach_,
    feature_dim,
    inner_layout,
    path_model,
    two_legs,
)
from hier_ssl.policies.candidate_graph import candidate_geometry
from hier_ssl.world.field import get_field

MODEL = path_model(SamplingPlanner(get_field("division_b"), hold=0.4))
# Features of a few reset states of each task, computed by the numpy implementation these replaced
# (hier_ssl/manager/candidate_features.py at commit 094eea9, complex float64 arrays).
NUMPY_FEATURES = Path(__file__).parent / "data" / "numpy_candidate_features.npz"
# Features of a few states of each task met on the way (moving obstacles, parked and held robots), computed
# by the first torch implementation (commit f97018c), before it was made ten times as fast.
TORCH_FEATURES = Path(__file__).parent / "data" / "torch_candidate_features.npz"
TASKS = ["obstacle/scorer", "scenarios/crowd_scorer", "scenarios/formation_scorer"]


def test_the_closest_approach_is_the_smallest_distance_over_the_interval() -> None:
    rng = np.random.default_rng(0)
    sx, sy, vx, vy = (torch.from_numpy(rng.normal(size=200)) for _ in range(4))
    t0 = torch.from_numpy(rng.uniform(0, 1, 200))
    t1 = t0 + torch.from_numpy(rng.uniform(0, 2, 200))
    s = torch.stack([sx, sy])
    distance, when = closest_approach_(s.clone(), torch.stack([vx, vy]), t0, t1)
    grid = torch.linspace(0.0, 1.0, 20_001, dtype=torch.float64)[:, None] * (t1 - t0)
    brute = ((sx + vx * grid) ** 2 + (sy + vy * grid) ** 2).sqrt().amin(0)
    torch.testing.assert_close(distance, brute, rtol=0, atol=1e-6)
    assert ((when >= t0) & (when <= t1)).all()
    at = ((sx + vx * (when - t0)) ** 2 + (sy + vy * (when - t0)) ** 2).sqrt()
    torch.testing.assert_close(at, distance, rtol=1e-12, atol=0)
    # An interval of one point has it as its closest; a still pair keeps its distance.
    point = closest_approach_(s.clone(), torch.stack([vx, vy]), t0, t0)
    torch.testing.assert_close(point, (s.norm(dim=0), t0), rtol=1e-12, atol=0)
    still = closest_approach_(s.clone(), torch.zeros_like(s), t0, t1)
    torch.testing.assert_close(still, (s.norm(dim=0), t0), rtol=1e-12, atol=0)


def _scene(obstacles: list[tuple[float, float, float, float]], robot=(0.0, 0.0)) -> dict:
    moving = torch.tensor(obstacles, dtype=torch.float64).reshape(1, len(obstacles), 4)
    return {
        "target": torch.tensor([[2.0, 0.0]], dtype=torch.float64),
        "robot": torch.tensor([robot], dtype=torch.float64),
        "obstacles": moving[..., 0:2],
        "velocities": moving[..., 2:4],
    }


def _features(scene: dict, cand: list[tuple[float, float]]) -> torch.Tensor:
    points = torch.tensor([cand], dtype=torch.float64)
    velocity = torch.zeros(1, 2, dtype=torch.float64)
    s = scene
    return candidate_features(
        MODEL, s["target"], s["robot"], velocity, s["obstacles"], s["velocities"], points
    )


def _column(name: str, k: int) -> int:
    """Index of a named column among the last 11 of ``candidate_features``."""
    names = (
        "t1",
        "tp",
        "t2",
        "arrival",
        "behind",
        "behind_safe",
        "clear",
        "hard",
        "safe",
        "close",
        "any_safe",
    )
    return feature_dim(k) - 11 + names.index(name)


def test_a_path_through_a_still_obstacle_is_not_clear_and_one_around_it_is() -> None:
    scene = _scene([(1.0, 0.0, 0.0, 0.0)])
    cand = [(2.0, 0.0), (1.0, 0.8), (1.0, -0.8)]  # the target, then a sub-goal on either side
    features = _features(scene, cand)
    assert features.shape == (1, 3, feature_dim(1)) and features.isfinite().all()
    close, safe = features[0, :, _column("close", 1)], features[0, :, _column("safe", 1)]
    assert close.tolist() == [0.0, 1.0, 1.0] and safe.tolist() == [0.0, 1.0, 1.0]
    # The straight path passes the obstacle's centre at t = 1 m / speed; the detours are longer.
    s, still = scene, torch.zeros(1, 2, dtype=torch.float64)
    g, p, _, q, u, c = inner_layout(
        s["target"], s["robot"], still, s["obstacles"], s["velocities"], torch.tensor([cand])
    )
    legs = two_legs(MODEL, g, p, q, u, c)  # d1, s1 (pieces, obstacles, scenes, candidates)
    d, when = legs["d1"][:, 0, 0, 0], legs["s1"][:, 0, 0, 0]
    assert d.min() < 1e-6 and abs(when[d.argmin()] - 1.0 / MODEL.speed) < 1e-6
    arrival = features[0, :, _column("arrival", 1)]
    assert arrival[0] < arrival[1] and abs(arrival[1] - arrival[2]) < 1e-6


def test_an_obstacle_that_leaves_the_line_in_time_clears_the_direct_path() -> None:
    # On the line 1 m ahead, leaving it at 3 m/s: gone before the robot gets there (0.77 m at the closest,
    # against a fixed safety distance of 0.28 m); the same obstacle standing still blocks the path.
    leaving = _features(_scene([(1.0, 0.0, 0.0, 3.0)]), [(2.0, 0.0)])
    staying = _features(_scene([(1.0, 0.0, 0.0, 0.0)]), [(2.0, 0.0)])
    assert leaving[0, 0, _column("close", 1)] == 1.0 and staying[0, 0, _column("close", 1)] == 0.0


def test_features_without_obstacles_say_every_path_is_safe() -> None:
    features = _features(_scene([]), [(2.0, 0.0), (1.0, 1.0)])
    assert features.shape == (1, 2, feature_dim(0)) and features.isfinite().all()
    assert (features[0, :, _column("safe", 0)] == 1.0).all()


def test_a_robot_on_its_target_has_finite_features() -> None:
    features = _features(_scene([(1.0, 0.0, 0.0, 0.0)], robot=(2.0, 0.0)), [(2.0, 0.0), (1.0, 1.0)])
    assert features.isfinite().all()


def _stored_and_computed(name: str, path: Path) -> tuple[np.ndarray, np.ndarray, int]:
    """The features of the observations stored in ``path`` for task ``name``, as computed now and as
    stored, and the feature count's k."""
    config = parse_config(load_yaml(config_dir() / f"{name}.yaml"))
    geometry = candidate_geometry(config, make_planner("sampling", config.task_config))
    stored = np.load(path)
    key = name.split("/")[1]
    with torch.no_grad():
        got = geometry.features(geometry(torch.from_numpy(stored[f"{key}_obs"]))).numpy()
    want = stored[f"{key}_features"]
    assert got.dtype == np.float32 and got.shape == want.shape
    return got, want, geometry.k


@pytest.mark.parametrize("name", TASKS)
def test_the_features_of_observations_are_the_numpy_implementations(name: str) -> None:
    got, want, k = _stored_and_computed(name, NUMPY_FEATURES)
    # Computed in float32, the numpy ones in float64: arrival times of a few seconds differ in the last
    # places, nothing near the float16 DAgger stores them in; the flags are the same.
    np.testing.assert_allclose(got, want, rtol=0, atol=5e-4)
    flags = slice(feature_dim(k) - 3, None)
    np.testing.assert_array_equal(got[..., flags], want[..., flags])


@pytest.mark.parametrize("name", TASKS)
def test_the_features_of_observations_are_the_first_torch_implementations(name: str) -> None:
    got, want, k = _stored_and_computed(name, TORCH_FEATURES)
    # Both float32, in another order of operations: within a few float32 steps of values of a few m or s,
    # but the time of a leg's nearest approach, which a nearly still obstacle leaves loose (the distance
    # hardly changes over an interval; 6e-4 s apart on 3,000 random states).
    when = [feature_dim(k) - 17, feature_dim(k) - 13]
    loose = np.zeros(got.shape[-1], dtype=bool)
    loose[when] = True
    np.testing.assert_allclose(got[..., ~loose], want[..., ~loose], rtol=0, atol=1e-5)
    np.testing.assert_allclose(got[..., loose], want[..., loose], rtol=0, atol=1e-3)
    flags = slice(feature_dim(k) - 3, None)
    np.testing.assert_array_equal(got[..., flags], want[..., flags])
