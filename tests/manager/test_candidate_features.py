from __future__ import annotations

import numpy as np

from hier_ssl.manager.candidate_features import candidate_features, closest_approach, feature_dim, two_legs
from hier_ssl.manager.planners import SamplingPlanner, Scene
from hier_ssl.world.field import get_field

PLANNER = SamplingPlanner(get_field("division_b"), hold=0.4)


def test_the_closest_approach_is_the_smallest_distance_over_the_interval() -> None:
    rng = np.random.default_rng(0)
    start = rng.normal(size=200) + 1j * rng.normal(size=200)
    velocity = rng.normal(size=200) + 1j * rng.normal(size=200)
    t0 = rng.uniform(0, 1, 200)
    t1 = t0 + rng.uniform(0, 2, 200)
    distance, when = closest_approach(start, velocity, t0, t1)
    grid = np.linspace(0.0, 1.0, 20_001)[:, None] * (t1 - t0)
    brute = np.abs(start + velocity * grid).min(0)
    np.testing.assert_allclose(distance, brute, atol=1e-6)
    assert ((when >= t0) & (when <= t1)).all()
    np.testing.assert_allclose(np.abs(start + velocity * (when - t0)), distance, rtol=1e-12)
    # An empty interval has no closest point.
    assert np.isinf(closest_approach(start[:1], velocity[:1], np.ones(1), np.zeros(1))[0]).all()


def _scene(obstacles: list[tuple[float, float, float, float]]) -> Scene:
    k = len(obstacles)
    moving = np.array(obstacles, dtype=float).reshape(1, k, 4)
    return Scene(
        target=np.array([[2.0, 0.0, 0.0, 0.0, 0.0]]),
        robot_pos=np.zeros((1, 2)),
        robot_vel=np.zeros((1, 2)),
        obstacle_pos=moving[..., 0:2],
        obstacle_vel=moving[..., 2:4],
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
    cand = np.array([[2.0 + 0j, 1.0 + 0.8j, 1.0 - 0.8j]])  # the target, then a sub-goal on either side
    features = candidate_features(PLANNER, scene, cand)
    assert features.shape == (1, 3, feature_dim(1)) and np.isfinite(features).all()
    close, safe = features[0, :, _column("close", 1)], features[0, :, _column("safe", 1)]
    assert close.tolist() == [0.0, 1.0, 1.0] and safe.tolist() == [0.0, 1.0, 1.0]
    # The straight path passes the obstacle's centre at t = 1 m / speed; the detours are longer.
    legs = two_legs(PLANNER, scene, cand)
    assert legs["d1"][0, 0, 0] < 1e-9 and abs(legs["s1"][0, 0, 0] - 1.0 / PLANNER.speed) < 1e-9
    arrival = features[0, :, _column("arrival", 1)]
    assert arrival[0] < arrival[1] and abs(arrival[1] - arrival[2]) < 1e-9


def test_an_obstacle_that_leaves_the_line_in_time_clears_the_direct_path() -> None:
    # On the line 1 m ahead, leaving it at 3 m/s: gone before the robot gets there (0.77 m at the closest,
    # against a fixed safety distance of 0.28 m); the same obstacle standing still blocks the path.
    leaving = candidate_features(PLANNER, _scene([(1.0, 0.0, 0.0, 3.0)]), np.array([[2.0 + 0j]]))
    staying = candidate_features(PLANNER, _scene([(1.0, 0.0, 0.0, 0.0)]), np.array([[2.0 + 0j]]))
    assert leaving[0, 0, _column("close", 1)] == 1.0 and staying[0, 0, _column("close", 1)] == 0.0


def test_features_without_obstacles_say_every_path_is_safe() -> None:
    scene = _scene([])
    cand = np.array([[2.0 + 0j, 1.0 + 1.0j]])
    features = candidate_features(PLANNER, scene, cand)
    assert features.shape == (1, 2, feature_dim(0)) and np.isfinite(features).all()
    assert (features[0, :, _column("safe", 0)] == 1.0).all()


def test_a_robot_on_its_target_has_finite_features() -> None:
    scene = _scene([(1.0, 0.0, 0.0, 0.0)])
    scene = Scene(
        scene.target, scene.target[:, 0:2].copy(), scene.robot_vel, scene.obstacle_pos, scene.obstacle_vel
    )
    features = candidate_features(PLANNER, scene, np.array([[2.0 + 0j, 1.0 + 1.0j]]))
    assert np.isfinite(features).all()
