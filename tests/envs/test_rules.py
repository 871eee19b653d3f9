"""The core's bound rules (``hier_ssl.envs.rules.Rules``) give, bit for bit, what the pure functions of
``hier_ssl.manager`` give for the same rows, whether the decision terms are computed once a decision or
per step."""

from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.config import EnvConfig
from hier_ssl.envs.rules import Rules
from hier_ssl.manager import collided, task_reward, task_success


def _rows(rng: np.random.Generator, n: int = 64, k: int = 2) -> dict[str, np.ndarray]:
    """Random robots, targets, sub-goals and obstacles; a third of the sub-goals and robots sit on the
    target, still, so that success happens."""
    target = np.zeros((n, 5))
    target[:, 0:3] = rng.uniform(-1, 1, (n, 3))
    subgoal = target + rng.normal(0, 0.5, (n, 5)) * (rng.random((n, 1)) < 0.67)
    pos = target[:, 0:2] + rng.normal(0, 0.3, (n, 2)) * (rng.random((n, 1)) < 0.67)
    vel = rng.normal(0, 0.03, (n, 2))
    others = pos[:, None] + rng.normal(0, 0.3, (n, k, 2))
    angle = target[:, 2] + rng.normal(0, 0.05, n)
    return {"target": target, "subgoal": subgoal, "pos": pos, "angle": angle, "vel": vel, "others": others}


@pytest.mark.parametrize("task", ["baseline", "proposed", "obstacle"])
@pytest.mark.parametrize("modes", [("add", "add", "subgoal"), ("replace", "replace", "robot")])
def test_rules_are_the_pure_functions_bit_for_bit(task: str, modes: tuple[str, str, str]) -> None:
    success_mode, hit_mode, obstacle_from = modes
    config = EnvConfig(
        success_mode=success_mode, hit_mode=hit_mode, obstacle_from=obstacle_from, success_weight=3.0
    )
    rules, rng = Rules(task, config), np.random.default_rng(1)
    r = _rows(rng)
    touching = rng.random(len(r["pos"])) < 0.1
    thresholds = {"d_th": config.d_th, "theta_th": np.deg2rad(config.theta_th_deg)}
    success = task_success(
        task,
        r["target"],
        r["subgoal"],
        r["pos"],
        r["angle"],
        r["vel"],
        speed_th=config.speed_th,
        **thresholds,
    )
    hit = collided(r["pos"], r["others"], config.collision_distance) | touching
    assert (success & hit).any()
    success = success > hit  # a hit fails the episode, also on the step that reached the target
    extra = {"obs_pos": r["others"], "hit": hit} if task == "obstacle" else {}
    options = {"success_mode": success_mode, "hit_mode": hit_mode, "obstacle_from": obstacle_from}
    reward, _ = task_reward(
        task,
        r["target"],
        r["pos"],
        r["angle"],
        r["subgoal"],
        success,
        success_weight=3.0,
        **options,
        **extra,
        **thresholds,
    )
    assert success.any() and not success.all() and hit.any()
    rows = (r["target"], r["subgoal"], r["pos"], r["angle"], r["vel"], r["others"], touching)
    for terms in (rules.decision_terms(r["target"], r["subgoal"]), None):
        got_reward, got_success, got_hit = rules(terms, *rows)
        np.testing.assert_array_equal(got_success, success)
        np.testing.assert_array_equal(got_hit, hit)
        np.testing.assert_array_equal(got_reward, reward)


def test_rules_of_a_robot_alone_hit_only_what_the_physics_reports() -> None:
    rules, r = Rules("proposed", EnvConfig()), _rows(np.random.default_rng(2), n=4, k=0)
    touching = np.array([False, True, False, False])
    rows = (r["target"], r["subgoal"], r["pos"], r["angle"], r["vel"], r["others"], touching)
    _, _, hit = rules(None, *rows)
    np.testing.assert_array_equal(hit, touching)


def test_rules_name_a_bad_task_or_option() -> None:
    with pytest.raises(ValueError, match="dribble"):
        Rules("dribble", EnvConfig())
    with pytest.raises(ValueError, match="hit_weight"):
        Rules("obstacle", EnvConfig().model_copy(update={"hit_weight": -1.0}))
