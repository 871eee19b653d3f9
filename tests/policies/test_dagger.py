from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from hier_ssl.config import ConfigError
from hier_ssl.config_files import config_dir, load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.evaluate import evaluate
from hier_ssl.manager.planners import make_planner
from hier_ssl.policies.actor import load_actor, load_policy
from hier_ssl.policies.dagger import soft_choice
from hier_ssl.train import resume_config, train

SHIPPED = load_yaml(config_dir() / "obstacle" / "candidates.yaml")


def _config(**dagger: object) -> dict:
    return {**SHIPPED, "eval_episodes": 40, "dagger": {**SHIPPED["dagger"], "hidden": [64, 64], **dagger}}


def test_the_soft_choice_peaks_on_the_planners_own_choice() -> None:
    config = parse_config(SHIPPED).task_config
    planner = make_planner("sampling", config)
    core = HierarchicalCore(config, 64)
    obs = core.reset(3).reshape(-1, core.obs_dim)
    scene = planner.read(obs)
    cand, soft = soft_choice(planner, scene, tau=0.05)
    np.testing.assert_allclose(soft.sum(1), 1.0, rtol=1e-9)
    chosen = cand[np.arange(len(cand)), soft.argmax(1)]
    np.testing.assert_allclose(planner.subgoals(scene, chosen), planner.plan(scene))
    # At a high temperature the choice spreads over the planner's best tier (where it has more than one).
    sharp, spread = soft.max(1), soft_choice(planner, scene, tau=10.0)[1].max(1)
    assert (spread <= sharp + 1e-12).all() and (spread < 0.9).sum() > len(obs) // 2


def test_dagger_learns_to_pass_the_obstacle_where_the_direct_sub_goal_collides(
    tmp_path: Path, one_thread: None
) -> None:
    run = tmp_path / "run"
    summary = train(parse_config(_config(rounds=5, episodes=100, epochs=20)), run, progress=False)
    task = parse_config(SHIPPED).task_config
    direct = evaluate(make_planner("direct", task), task, 40, seed=20_000)
    # The direct sub-goal drives into the midpoint obstacle (about 6 % success); the classifier, five
    # short rounds from the planner's choices, goes round it in most episodes.
    assert direct["success_rate"] < 0.2
    assert summary["success_rate"] > 0.7 and summary["collision_rate"] < 0.3, summary
    steps = [int(row.split(",")[0]) for row in (run / "curve.csv").read_text().splitlines()[1:]]
    assert steps == [1, 2, 3, 4, 5]


def test_a_dagger_run_resumes_after_its_last_round_and_plays_as_a_policy(tmp_path: Path) -> None:
    run = tmp_path / "run"
    train(parse_config(_config(rounds=2, episodes=10)), run, progress=False)
    saved = yaml.safe_load((run / "config.yaml").read_text())
    (run / "config.yaml").write_text(yaml.safe_dump({**saved, "dagger": {**saved["dagger"], "rounds": 3}}))
    train(resume_config(run), run, resume=True, progress=False)
    rows = (run / "curve.csv").read_text().splitlines()[1:]
    assert [int(row.split(",")[0]) for row in rows] == [1, 2, 3]
    assert int(rows[2].split(",")[1]) > int(rows[1].split(",")[1])  # round 3 added labelled states
    core = HierarchicalCore(parse_config(saved).task_config, 8)
    obs = core.reset(1).reshape(-1, core.obs_dim)
    for which in ("best", "final"):
        actions = load_policy(run, which=which)(obs)
        assert actions.shape == (8, core.act_dim) and np.abs(actions).max() <= 1.0
    first, again = (load_policy(run, sample=True, seed=5)(obs) for _ in range(2))
    np.testing.assert_array_equal(first, again)
    with pytest.raises(ConfigError, match="algo 'dagger'.*does not|no stand-alone actor"):
        load_actor(run)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"algo": "sac", "dagger": {"rounds": 3}}, "dagger: only read with algo 'dagger'"),
        ({"dagger": {"rounds": 0}}, "dagger.rounds"),
        ({"dagger": {"tau": 0}}, "dagger.tau"),
    ],
)
def test_dagger_config_errors_name_the_key(change: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_config({**SHIPPED, **change})


def test_a_dagger_scenario_run_shares_its_classifier_between_the_robots(tmp_path: Path) -> None:
    data = load_yaml(config_dir() / "scenarios" / "formation.yaml")
    config = {**data, "algo": "dagger", "eval_episodes": 3, "dagger": {"rounds": 1, "episodes": 3}}
    summary = train(parse_config(config), tmp_path / "run", progress=False)
    assert summary["task"] == "formation" and summary["robots"] == 6 * 3 and summary["episodes"] == 3
