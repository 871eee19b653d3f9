from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from hier_ssl.checkpoints.actor import load_actor
from hier_ssl.config import ConfigError
from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.envs import parse_config, shards
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.planners import make_planner
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.policies import candidates
from hier_ssl.policies.actor import load_policy
from hier_ssl.policies.candidate_graph import as_points, candidate_geometry
from hier_ssl.policies.candidate_nets import Scorer, chooser_from_state, soft_choice
from hier_ssl.policies.candidates import CandidateLearner, candidate_manager
from hier_ssl.runs.train import resume_config, train

SHIPPED = load_yaml(config_dir() / "obstacle" / "candidates.yaml")


def _config(ppo: dict | None = None, **dagger: object) -> dict:
    section = {"hidden": [64, 64], **dagger, "ppo": {"iterations": 0, **(ppo or {})}}
    return {**SHIPPED, "eval_episodes": 40, "candidates": section}


def test_the_soft_choice_peaks_on_the_planners_own_choice() -> None:
    config = parse_config(SHIPPED).task_config
    planner = make_planner("sampling", config)
    core = HierarchicalCore(config, 64)
    obs = core.reset(3).reshape(-1, core.obs_dim)
    scene = planner.read(obs)
    # The candidates the network chooses among (torch, from the observation) are the planner's own.
    cand = as_points(candidate_geometry(parse_config(SHIPPED), planner)(torch.as_tensor(obs))[5])
    np.testing.assert_allclose(cand, planner.candidates(scene), rtol=0, atol=1e-12)
    soft = soft_choice(planner, obs, cand, tau=0.05)
    np.testing.assert_allclose(soft.sum(1), 1.0, rtol=1e-9)
    chosen = cand[np.arange(len(cand)), soft.argmax(1)]
    np.testing.assert_allclose(planner.subgoals(scene, chosen), planner.plan(scene))
    # At a high temperature the choice spreads over the planner's best tier (where it has more than one).
    sharp, spread = soft.max(1), soft_choice(planner, obs, cand, tau=10.0).max(1)
    assert (spread <= sharp + 1e-12).all() and (spread < 0.9).sum() > len(obs) // 2


def test_dagger_alone_learns_to_pass_the_obstacle_where_the_direct_sub_goal_collides(
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


def test_a_scorer_learns_from_fewer_states_than_the_classifier_and_reloads_as_saved(
    tmp_path: Path, one_thread: None
) -> None:
    run = tmp_path / "run"
    summary = train(parse_config(_config(network="scorer", rounds=2, episodes=40)), run, progress=False)
    # Two rounds of 40 episodes: the classifier needs five of 100 (above) to pass the obstacle this often.
    assert summary["success_rate"] > 0.7 and summary["collision_rate"] < 0.3, summary
    state = torch.load(run / "model.pt")["net"]
    net = chooser_from_state(state)
    # Rebuilt from the weights alone: the configured layers, loaded strictly.
    assert isinstance(net, Scorer)
    assert [m.out_features for m in net.body if isinstance(m, torch.nn.Linear)] == [64, 64, 1]
    task = parse_config(SHIPPED).task_config
    planner = make_planner("sampling", task)
    obs = HierarchicalCore(task, 16).reset(5).reshape(16, -1)
    manager = candidate_manager(parse_config(SHIPPED), net)
    logits = net(manager.decide(obs)[3])
    assert logits.shape == (16, planner.candidates(planner.read(obs)).shape[1])
    assert torch.isfinite(logits).all() and (logits.std(1) > 0).all()
    played = evaluate(load_policy(run, which="final"), task, 40, seed=20_000)
    assert played["success_rate"] > 0.7, played


def _more(run: Path, **changes: object) -> None:
    """Raise the run's budget in its config.yaml, as a user continuing a finished run would."""
    saved = yaml.safe_load((run / "config.yaml").read_text())
    section = saved["candidates"]
    section |= {k: v for k, v in changes.items() if k != "ppo"}
    section["ppo"] |= changes.get("ppo", {})
    (run / "config.yaml").write_text(yaml.safe_dump(saved))


def _steps(run: Path) -> list[int]:
    return [int(row.split(",")[0]) for row in (run / "curve.csv").read_text().splitlines()[1:]]


def test_a_candidates_run_resumes_in_either_phase_and_plays_as_a_policy(tmp_path: Path) -> None:
    run = tmp_path / "run"
    train(parse_config(_config(rounds=2, episodes=10)), run, progress=False)
    _more(run, rounds=3)
    saved = torch.load(run / "model.pt")
    torch.save({k: v for k, v in saved.items() if k != "labels"}, tmp_path / "model.pt")
    (tmp_path / "model.pt").replace(run / "model.pt")
    with pytest.raises(ConfigError, match=r"model.pt lacks \['labels'\]"):
        train(resume_config(run), run, resume=True, progress=False)
    torch.save(saved, run / "model.pt")
    train(resume_config(run), run, resume=True, progress=False)
    rows = (run / "curve.csv").read_text().splitlines()[1:]
    assert _steps(run) == [1, 2, 3]
    assert int(rows[2].split(",")[1]) > int(rows[1].split(",")[1])  # round 3 added labelled states
    # PPO on top: scored every 2 iterations and at the last; a resumed PPO phase goes on from its last save.
    ppo = {"iterations": 3, "fields": 8, "horizon": 4, "value_warmup": 1, "eval_interval": 2, "anneal": True}
    _more(run, ppo=ppo)
    train(resume_config(run), run, resume=True, progress=False)
    saved = torch.load(run / "model.pt")
    assert _steps(run) == [1, 2, 3, 5, 6] and saved["phase"] == "ppo"
    # Annealed: the last iteration (index 2 of 3) stepped at a third of each rate.
    rates = [group["param_groups"][0]["lr"] for group in saved["optimizers"]]
    assert rates == pytest.approx([1e-4 / 3, 1e-3 / 3])
    _more(run, ppo={"iterations": 4})
    train(resume_config(run), run, resume=True, progress=False)
    assert _steps(run) == [1, 2, 3, 5, 6, 7]
    rates = [group["param_groups"][0]["lr"] for group in torch.load(run / "model.pt")["optimizers"]]
    assert rates == pytest.approx([1e-4 / 4, 1e-3 / 4])
    core = HierarchicalCore(resume_config(run).task_config, 8)
    obs = core.reset(1).reshape(-1, core.obs_dim)
    for which in ("best", "final"):
        actions = load_policy(run, which=which)(obs)
        assert actions.shape == (8, core.act_dim) and np.abs(actions).max() <= 1.0
    first, again = (load_policy(run, sample=True, seed=5)(obs) for _ in range(2))
    np.testing.assert_array_equal(first, again)

    with pytest.raises(ConfigError, match="algo 'candidates'.*no stand-alone actor"):
        load_actor(run)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"algo": "sac", "candidates": {"rounds": 3}}, "candidates: only read with algo 'candidates'"),
        ({"candidates": {"rounds": 0}}, "candidates.rounds"),
        ({"candidates": {"tau": 0}}, "candidates.tau"),
        ({"candidates": {"ppo": {"gamma": 1.5}}}, "candidates.ppo.gamma"),
        ({"candidates": {"hidden": []}}, "candidates.hidden"),
        ({"candidates": {"ppo": {"value_hidden": [64, 0]}}}, "candidates.ppo.value_hidden"),
    ],
)
def test_candidates_config_errors_name_the_key(change: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_config({**SHIPPED, **change})


def test_a_dagger_scenario_run_shares_its_classifier_between_the_robots(tmp_path: Path) -> None:
    data = load_yaml(config_dir() / "scenarios" / "formation.yaml")
    # value_warmup 0: the policy moves in the first iteration, over rows of robots that leave at
    # different times (masked as they go).
    section = {
        "rounds": 1,
        "episodes": 3,
        "ppo": {"iterations": 2, "fields": 2, "horizon": 8, "value_warmup": 0},
    }
    config = {**data, "algo": "candidates", "eval_episodes": 3, "candidates": section}
    summary = train(parse_config(config), tmp_path / "run", progress=False)
    assert summary["task"] == "formation" and summary["robots"] == 6 * 3 and summary["episodes"] == 3


def test_the_ppo_reward_prices_time_success_and_collisions() -> None:
    from hier_ssl.config.learners import CandidatePPOConfig
    from hier_ssl.policies.ppo import outcome_reward

    settings = CandidatePPOConfig(time_cost=2.0, success_reward=10.0, collision_cost=30.0)
    steps = np.array([16, 16, 7, 16])
    reward = outcome_reward(settings, steps, np.array([1, 2]), np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    np.testing.assert_allclose(reward, [-0.32, -0.32 + 10.0, -0.14 - 30.0, -0.32], rtol=1e-6)


def test_the_near_miss_cost_grows_inside_the_band_and_skips_ended_rows() -> None:
    from hier_ssl.config.learners import CandidatePPOConfig
    from hier_ssl.manager.neighbours import nearest_gap, neighbour_obs_slice
    from hier_ssl.policies.ppo import outcome_reward

    settings = CandidatePPOConfig(time_cost=0.0, near_cost=2.0, near_distance=0.4)
    # Nearest others at 0.1, 0.3, 0.5 m and a padding slot; row 1 ended this decision (a success).
    obs = np.zeros((4, 13 + 6), np.float32)
    slots = [[0.01, 0, 0, 0, 0, 1], [0, -0.03, 0, 0, 1, 1], [0.03, 0.04, 0, 0, 0, 1]]
    obs[:3, neighbour_obs_slice(0)] = slots
    gap = nearest_gap(obs, 10.0)
    np.testing.assert_allclose(gap, [0.1, 0.3, 0.5, np.inf], rtol=1e-6)
    reward = outcome_reward(settings, np.full(4, 1), np.array([1]), np.array([1.0]), np.array([0.0]), gap)
    np.testing.assert_allclose(reward, [-2.0 * 0.75, 10.0, 0.0, 0.0], rtol=1e-6)


def test_the_near_miss_cost_needs_a_neighbour_observation() -> None:
    data = load_yaml(config_dir() / "obstacle" / "scorer.yaml")
    data["env"] = {**data.get("env", {}), "observation": "paper"}
    ppo = {**data["candidates"].get("ppo", {}), "near_cost": 1.0}
    data["candidates"] = {**data["candidates"], "ppo": ppo}
    with pytest.raises(ConfigError, match="near_cost reads the nearest neighbour; 'paper' has none"):
        parse_config(data)


def test_ppo_takes_the_classifier_past_the_obstacle_where_imitation_left_it(
    tmp_path: Path, one_thread: None
) -> None:
    import csv

    ppo = {"iterations": 40, "fields": 32, "horizon": 16, "value_warmup": 5, "eval_interval": 10}
    config = _config(ppo={**ppo, "learning_rate": 1e-3, "kl_weight": 0.0}, rounds=2, episodes=30, epochs=20)
    run = tmp_path / "run"
    summary = train(parse_config({**config, "eval_episodes": 100}), run, progress=False)
    curve = {
        int(row["step"]): float(row["success_rate"]) for row in csv.DictReader((run / "curve.csv").open())
    }
    # Two small DAgger rounds leave it at the direct sub-goal's success; PPO's outcomes alone lift it.
    assert curve[2] < 0.2 and curve[42] > 0.7, curve
    assert summary["final"]["success_rate"] > 0.7, summary


def test_a_ppo_update_over_rows_that_do_not_split_evenly_stays_finite(tmp_path: Path) -> None:
    from hier_ssl.policies.networks import mlp

    learner = CandidateLearner(parse_config(_config()), tmp_path, progress=False)
    learner.net, learner.reference, learner.value = mlp(6, (8,), 4), mlp(6, (8,), 4), mlp(6, (8,), 1)
    learner.optimizers = tuple(torch.optim.Adam(m.parameters()) for m in (learner.net, learner.value))
    # Five live rows in four minibatches (a scenario whose robots left at different times).
    batch = [
        torch.randn(5, 6),
        torch.tensor([0, 1, 2, 3, 0]),
        torch.full((5,), -1.4),
        torch.randn(5),
        torch.randn(5),
    ]
    learner.update([*batch, batch[0]], moving=True)  # a classifier reads the observations
    assert all(torch.isfinite(p).all() for p in learner.net.parameters())


def test_sampling_draws_from_the_logits_and_greedy_takes_the_highest() -> None:
    from hier_ssl.policies.candidates import candidate_planner
    from hier_ssl.policies.networks import mlp

    config = parse_config(SHIPPED)
    planner = candidate_planner(config)
    core = HierarchicalCore(config.task_config, 64)
    obs = core.reset(2).reshape(-1, core.obs_dim)
    width = planner.candidates(planner.read(obs)).shape[1]
    net = mlp(core.obs_dim, (8,), width)
    torch.nn.init.zeros_(net[-1].weight)
    torch.nn.init.zeros_(net[-1].bias)
    with torch.no_grad():
        net[-1].bias[7] = 1.0  # candidate 7 is the most likely, but with uniform logits elsewhere not sure
    manager = candidate_manager(config, net)
    greedy, log_prob, action, read = manager.decide(obs)
    assert torch.equal(read, torch.as_tensor(obs, dtype=torch.float32))
    assert (greedy == 7).all() and torch.allclose(log_prob, torch.full((64,), log_prob[0].item()))
    # The greedy action is the forward pass's (the exported graph's) and names the planner's candidate 7.
    np.testing.assert_array_equal(action, manager(torch.as_tensor(obs)).numpy())
    scene = planner.read(obs)
    chosen = planner.subgoals(scene, planner.candidates(scene)[:, 7])
    np.testing.assert_allclose(action, planner.action(scene, chosen), rtol=0, atol=1e-6)
    drawn = [manager.decide(obs, torch.Generator().manual_seed(seed))[0] for seed in (1, 1, 2)]
    assert torch.equal(drawn[0], drawn[1]) and not torch.equal(drawn[0], drawn[2])
    assert (drawn[0] != 7).any()


def test_a_resumed_dagger_phase_ends_with_the_weights_of_an_uninterrupted_run(tmp_path: Path) -> None:
    whole, halves = tmp_path / "whole", tmp_path / "halves"
    train(parse_config(_config(rounds=2, episodes=8)), whole, progress=False)
    train(parse_config(_config(rounds=1, episodes=8)), halves, progress=False)
    _more(halves, rounds=2)
    train(resume_config(halves), halves, resume=True, progress=False)
    # The saved RNG state is restored after the network is rebuilt (its initialisation draws from it), so
    # the resumed round shuffles its minibatches as the uninterrupted one did.
    for key, value in torch.load(whole / "model.pt")["net"].items():
        torch.testing.assert_close(torch.load(halves / "model.pt")["net"][key], value, rtol=0, atol=0)


def test_a_candidate_learner_stops_at_its_step_budget_and_goes_on_from_there(tmp_path: Path) -> None:
    from hier_ssl.policies.candidates import CandidateLearner

    ppo = {"iterations": 2, "fields": 8, "horizon": 4, "value_warmup": 1, "eval_interval": 1}
    config = parse_config(_config(ppo=ppo, rounds=2, episodes=10))
    steps: list[int] = []
    CandidateLearner(config, tmp_path, progress=False).learn(1, lambda c: steps.append(c.step))
    assert steps == [1] and torch.load(tmp_path / "model.pt")["round"] == 0  # one DAgger round of two
    later = CandidateLearner(config, tmp_path, progress=False)
    later.load(tmp_path)
    later.learn(3, lambda c: steps.append(c.step))  # the second round, then one PPO iteration of two
    saved = torch.load(tmp_path / "model.pt")
    assert steps == [1, 2, 3] and saved["phase"] == "ppo" and saved["iteration"] == 1


def test_dagger_collects_the_same_states_and_labels_on_one_and_two_cores(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # 70 episodes in shards of one block are two shards (hier_ssl.envs.shards): the second plays in a worker
    # process on two cores (the shipped shards of four blocks would need 257 episodes for two).
    monkeypatch.setattr(shards, "SHARD_BLOCKS", 1)
    collected = []
    for threads in (1, 2):
        data = {**_config(rounds=1, episodes=70), "threads": threads}
        data["env"] = {**SHIPPED["env"], "max_steps": 160}
        learner = CandidateLearner(parse_config(data), tmp_path / str(threads), progress=False)
        learner.dagger({}, 1)
        learner.writer.close()
        collected.append((learner.dagger_obs, learner.dagger_labels))
    (obs, labels), (obs_2, labels_2) = collected
    assert len(obs) > 70 and torch.equal(obs, obs_2) and torch.equal(labels, labels_2)


def test_the_candidate_learner_plays_on_one_torch_thread_and_fits_on_the_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, torch_threads_seen
) -> None:
    """DAgger's episodes and PPO's rollouts at one torch thread (hier_ssl.policies.learner), the fits and
    updates at the run's."""
    seen, counted = torch_threads_seen
    for name in ("play", "fit_chooser"):
        monkeypatch.setattr(candidates, name, counted(name, getattr(candidates, name)))
    for name in ("rollout", "update"):
        monkeypatch.setattr(CandidateLearner, name, counted(name, getattr(CandidateLearner, name)))
    ppo = {"iterations": 1, "fields": 4, "horizon": 4, "value_warmup": 0, "eval_interval": 1}
    CandidateLearner(parse_config(_config(ppo=ppo, rounds=1, episodes=4)), tmp_path, progress=False).learn(2)
    assert seen == {"play": {1}, "fit_chooser": {2}, "rollout": {1}, "update": {2}}
