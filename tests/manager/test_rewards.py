from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.manager.rewards import (
    HIT_REWARD,
    REWARD_TERMS,
    SUCCESS_REWARD,
    RewardOptions,
    angle_reward,
    combine_rewards,
    distance_reward,
    nearest_distance,
    nearest_obstacle_distance,
    obstacle_reward,
    pose_error,
    pose_errors,
    task_reward,
    vector_length,
    wrap_angle,
)
from hier_ssl.world.frames import wrap

GAUSS_0 = 1 / math.sqrt(2 * math.pi)  # 0.398942: N(0; 0, 1)
GAUSS_1 = math.exp(-0.5) / math.sqrt(2 * math.pi)  # 0.241971: N(1; 0, 1)


def test_distance_reward_around_threshold() -> None:
    np.testing.assert_allclose(distance_reward([0.0, 0.05, 0.0501, 1.3]), [10.0, 10.0, -0.0501, -1.3])


def test_angle_reward_around_threshold() -> None:
    five_deg = math.radians(5)
    got = angle_reward([0.0, five_deg, five_deg + 1e-6, math.pi / 2, math.pi])
    np.testing.assert_allclose(got, [1.0, 1.0, -(five_deg + 1e-6) / math.pi, -0.5, -1.0])


def test_obstacle_reward_is_a_negative_standard_gaussian() -> None:
    np.testing.assert_allclose(obstacle_reward([0.0, 1.0, -1.0, np.inf]), [-GAUSS_0, -GAUSS_1, -GAUSS_1, 0.0])


def test_wrap_angle_and_pose_errors() -> None:
    np.testing.assert_allclose(
        wrap_angle([3 * math.pi / 2, -3 * math.pi / 2, 0.25]), [-math.pi / 2, math.pi / 2, 0.25]
    )
    # 170 deg and -170 deg are 20 deg apart across the +-180 seam; (0, 0) to (3, 4) is 5 m
    pose = np.array([[0.0, 0.0, math.radians(170)]])
    pose5 = np.array([[3.0, 4.0, math.radians(-170), 9.0, 9.0]])
    d, delta = pose_errors(pose, pose5)
    np.testing.assert_allclose([d[0], delta[0]], [5.0, math.radians(20)])


def _scene() -> dict[str, np.ndarray]:
    # Target at (1, 0) facing 0. The robot is 3 cm and 0.02 rad off it (inside both thresholds);
    # the sub-goal sits 3 m away facing backwards (outside both).
    return {
        "target": np.array([[1.0, 0.0, 0.0, 0.0, 0.0]]),
        "robot_pos": np.array([[1.0, 0.03]]),
        "robot_angle": np.array([0.02]),
        "subgoal": np.array([[-2.0, 0.0, math.pi, 0.0, 0.0]]),
        "success": np.array([False]),
    }


def test_baseline_measures_the_robot_and_proposed_the_subgoal() -> None:
    total, terms = task_reward("baseline", **_scene())
    np.testing.assert_allclose(total, [11.0])  # +10 + 1
    total, terms = task_reward("proposed", **_scene())
    np.testing.assert_allclose(total, [-4.0])  # -3 m - pi / pi
    np.testing.assert_allclose([terms["distance"][0], terms["angle"][0]], [-3.0, -1.0])


def test_success_step_add_and_replace() -> None:
    scene = _scene() | {"success": np.array([True])}
    total, terms = task_reward("baseline", **scene, success_mode="add")
    np.testing.assert_allclose(total, [10.0 + 1.0 + SUCCESS_REWARD])
    total, terms = task_reward("baseline", **scene, success_mode="replace")
    np.testing.assert_allclose(total, [SUCCESS_REWARD])
    assert terms["distance"][0] == 0.0 and terms["success"][0] == SUCCESS_REWARD


def test_obstacle_terms_per_field_and_hit_modes() -> None:
    # Field 0: sub-goal on the target, nearest obstacle 1 m away (the other 3 m), no hit.
    # Field 1: same, but the robot hit an obstacle.
    scene = {
        "target": np.array([[1.0, 0.0, 0.0, 0.0, 0.0]] * 2),
        "robot_pos": np.zeros((2, 2)),
        "robot_angle": np.zeros(2),
        "subgoal": np.array([[1.0, 0.0, 0.0, 0.0, 0.0]] * 2),
        "success": np.array([False, False]),
        "obs_pos": np.array([[[1.0, 1.0], [4.0, 0.0]]] * 2),
        "hit": np.array([False, True]),
    }
    total, terms = task_reward("obstacle", **scene)
    np.testing.assert_allclose(terms["obstacle"], [-GAUSS_1, -GAUSS_1])
    np.testing.assert_allclose(total, [11.0 - GAUSS_1, 11.0 - GAUSS_1 + HIT_REWARD])
    total, _ = task_reward("obstacle", **scene, hit_mode="replace")
    np.testing.assert_allclose(total, [11.0 - GAUSS_1, HIT_REWARD])
    no_obstacle = scene | {"obs_pos": np.zeros((2, 0, 2))}
    _, terms = task_reward("obstacle", **no_obstacle)
    np.testing.assert_array_equal(terms["obstacle"], [0.0, 0.0])


def test_a_hit_on_the_step_of_a_success_pays_no_success_reward() -> None:
    # Both fields reach the target this step; field 1 also hits: it gets R_hit and no R_t.
    scene = {
        "target": np.array([[1.0, 0.0, 0.0, 0.0, 0.0]] * 2),
        "robot_pos": np.array([[1.0, 0.0]] * 2),
        "robot_angle": np.zeros(2),
        "subgoal": np.array([[1.0, 0.0, 0.0, 0.0, 0.0]] * 2),
        "success": np.array([True, True]),
        "obs_pos": np.array([[[1.15, 0.0]]] * 2),
        "hit": np.array([False, True]),
    }
    total, terms = task_reward("obstacle", **scene)
    np.testing.assert_array_equal(terms["success"], [SUCCESS_REWARD, 0.0])
    np.testing.assert_array_equal(terms["hit"], [0.0, HIT_REWARD])
    np.testing.assert_allclose(total - terms["obstacle"], [11.0 + SUCCESS_REWARD, 11.0 + HIT_REWARD])


def test_terms_always_sum_to_total() -> None:
    rng = np.random.default_rng(2)
    n = 32
    for success_mode in ("add", "replace"):
        for hit_mode in ("add", "replace"):
            total, terms = task_reward(
                "obstacle",
                target=rng.uniform(-1, 1, (n, 5)),
                robot_pos=rng.uniform(-1, 1, (n, 2)),
                robot_angle=rng.uniform(-3, 3, n),
                subgoal=rng.uniform(-1, 1, (n, 5)),
                success=rng.random(n) < 0.5,
                obs_pos=rng.uniform(-1, 1, (n, 2, 2)),
                hit=rng.random(n) < 0.5,
                success_mode=success_mode,
                hit_mode=hit_mode,
            )
            assert set(terms) == set(REWARD_TERMS)
            np.testing.assert_allclose(sum(terms.values()), total)


def test_bad_options_raise() -> None:
    with pytest.raises(ValueError, match="obs_pos"):
        task_reward("obstacle", **_scene())
    with pytest.raises(ValueError, match="'proposed'"):
        task_reward("proposed", **_scene(), hit=np.array([False]), obs_pos=np.zeros((1, 1, 2)))
    with pytest.raises(ValueError, match="walk"):
        task_reward("walk", **_scene())
    with pytest.raises(ValueError, match="'sum'"):
        task_reward("baseline", **_scene(), success_mode="sum")


def test_success_and_hit_weights_scale_their_terms_only() -> None:
    args = {
        "target": np.zeros((2, 5)),
        "robot_pos": np.zeros((2, 2)),
        "robot_angle": np.zeros(2),
        "subgoal": np.zeros((2, 5)),
        "success": np.array([True, False]),
        "obs_pos": np.full((2, 1, 2), 0.5),
        "hit": np.array([False, True]),
    }
    _, plain = task_reward("obstacle", **args)
    total, weighted = task_reward("obstacle", success_weight=20.0, hit_weight=5.0, **args)
    assert weighted["success"].tolist() == [20 * plain["success"][0], 0.0]
    assert weighted["hit"].tolist() == [0.0, 5 * plain["hit"][1]]
    for name in ("distance", "angle", "obstacle"):
        np.testing.assert_array_equal(weighted[name], plain[name])
    np.testing.assert_allclose(total, sum(weighted.values()))
    with pytest.raises(ValueError, match="hit_weight"):
        task_reward("obstacle", hit_weight=-1.0, **args)


def test_obstacle_term_measured_from_the_robot_as_the_public_code() -> None:
    # Sub-goal on the target at (1, 0): nearest obstacle (1, 1) is 1 m away. Robot at the origin: the
    # nearest obstacle is (1, 1) at sqrt(2) m.
    scene = {
        "target": np.array([[1.0, 0.0, 0.0, 0.0, 0.0]]),
        "robot_pos": np.zeros((1, 2)),
        "robot_angle": np.zeros(1),
        "subgoal": np.array([[1.0, 0.0, 0.0, 0.0, 0.0]]),
        "success": np.array([False]),
        "obs_pos": np.array([[[1.0, 1.0], [4.0, 0.0]]]),
        "hit": np.array([False]),
    }
    _, from_subgoal = task_reward("obstacle", **scene)
    _, from_robot = task_reward("obstacle", **scene, obstacle_from="robot")
    np.testing.assert_allclose(from_subgoal["obstacle"], [-GAUSS_1])
    np.testing.assert_allclose(from_robot["obstacle"], [-np.exp(-1.0) / np.sqrt(2 * np.pi)])
    with pytest.raises(ValueError, match="obstacle_from"):
        task_reward("obstacle", **scene, obstacle_from="target")


def test_vector_length_is_numpys_norm_bit_for_bit() -> None:
    xy = np.random.default_rng(3).normal(0, 10, (7, 5, 2)) ** 3
    np.testing.assert_array_equal(vector_length(xy), np.linalg.norm(xy, axis=-1))


@pytest.mark.parametrize(
    "modes", [("add", "add"), ("replace", "add"), ("add", "replace"), ("replace", "replace")]
)
def test_a_summed_shaping_term_gives_the_same_total_bit_for_bit(modes: tuple[str, str]) -> None:
    rng = np.random.default_rng(4)
    n = 256
    d, delta = rng.uniform(0, 0.1, n), rng.uniform(0, 0.2, n)
    success, hit, nearest = rng.random(n) < 0.3, rng.random(n) < 0.3, rng.uniform(0, 2, n)
    options = RewardOptions(*modes, success_weight=7.0, hit_weight=0.5)
    parts = {"distance": distance_reward(d), "angle": angle_reward(delta)}
    summed = {"pose": parts["distance"] + parts["angle"]}
    for extra in ((), (nearest, hit)):
        total, terms = combine_rewards(parts, success, options, *extra)
        np.testing.assert_array_equal(combine_rewards(summed, success, options, *extra)[0], total)
        np.testing.assert_allclose(sum(terms.values()), total)


def test_the_scalar_geometry_of_the_compiled_loops_is_the_array_functions_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-4, 4, (500, 5)), rng.uniform(-4, 4, (500, 5))
    a[:50, 0:3] = b[:50, 0:3]  # on the target
    a[50:60, 2] = b[50:60, 2] + math.pi  # half a turn away
    edges = [-math.pi, math.pi, 0.0, -0.0, 3 * math.pi, -3 * math.pi]
    turns = np.concatenate([rng.uniform(-20, 20, 500), edges])
    assert [wrap(t) for t in turns] == wrap_angle(turns).tolist()
    d, delta = pose_errors(a, b)
    pairs = list(zip(d.tolist(), delta.tolist(), strict=True))
    assert [pose_error(x, y) for x, y in zip(a, b, strict=True)] == pairs


def test_the_nearest_distance_is_the_least_centre_distance_and_inf_without_obstacles() -> None:
    rng = np.random.default_rng(5)
    points, others = rng.uniform(-4, 4, (50, 2)), rng.uniform(-4, 4, (50, 3, 2))
    nearest = nearest_obstacle_distance(points, others)
    np.testing.assert_allclose(nearest, np.linalg.norm(others - points[:, None], axis=-1).min(axis=1))
    assert nearest_obstacle_distance(points, np.zeros((50, 0, 2))).tolist() == [math.inf] * 50
    assert nearest_distance(0.0, 0.0, np.zeros((0, 2))) == math.inf
