"""The residual candidates network: the sampling planner's ranking plus a learned correction. Untrained it
is the planner; a tiny PPO run moves it and keeps it playing; it rebuilds from its weights and refuses to
export. With ``candidates.zone_features`` it also reads how far each leg keeps from the game's zones."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import torch

from hier_ssl.checkpoints.actor import BEST_ACTOR_FILE, CONFIG_FILE
from hier_ssl.checkpoints.tensors import save_checkpoint
from hier_ssl.config import ConfigError, dump_config
from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.planners import make_planner
from hier_ssl.envs.play import play
from hier_ssl.envs.shards import batched_core, close_core
from hier_ssl.game.legal import segment_clearance
from hier_ssl.manager.game_observation import ruled_read
from hier_ssl.policies.actor import load_candidate_manager, load_policy
from hier_ssl.policies.candidate_graph import RememberingPolicy, ResidualManager, candidate_policy
from hier_ssl.policies.candidate_nets import build_chooser, chooser_from_state
from hier_ssl.policies.candidate_residual import (
    MEMORY_FEATURES,
    RESIDUAL_FEATURES,
    ZONE_FEATURES,
    Residual,
    residual_inputs,
    residual_planner,
    zone_clearances,
)
from hier_ssl.policies.candidates import candidate_manager, candidate_planner
from hier_ssl.policies.export import export_manager
from hier_ssl.policies.ppo import categorical_kl
from hier_ssl.runs.train import train

SHIPPED = load_yaml(config_dir() / "game" / "stop_residual.yaml")
ZONED = {**SHIPPED, "candidates": {**SHIPPED["candidates"], "zone_features": True}}
REMEMBERING = {**SHIPPED, "candidates": {**SHIPPED["candidates"], "memory": True}}


def _fresh(hidden: tuple[int, ...] = (16, 16), zone_features: bool = False) -> Residual:
    torch.manual_seed(0)
    net = build_chooser("residual", hidden, None, 0, SHIPPED["candidates"]["tau"], 0.0, zone_features)
    assert isinstance(net, Residual)
    return net


@pytest.mark.parametrize(
    ("zone_features", "spec"), [(False, "sampling"), (True, "sampling"), (False, "sampling+trapped=brake")]
)
def test_the_untrained_residual_chooses_as_the_sampling_planner_on_game_stop_states(
    zone_features: bool, spec: str
) -> None:
    shipped = ZONED if zone_features else SHIPPED
    config = parse_config({**shipped, "candidates": {**shipped["candidates"], "planner": spec}})
    planner = candidate_planner(config)
    assert planner.trapped == ("brake" if "brake" in spec else "evade")
    manager = candidate_manager(config, _fresh(zone_features=zone_features))
    assert manager.zone_features == zone_features
    # Its correction starts at zero: the logits are the planner's score / tau, nothing else.
    last = manager.net.body[-1]
    assert not last.weight.any() and not last.bias.any()
    compared, moved = [], []
    max_pos = planner.max_pos or planner.field.max_pos

    def policy(obs: np.ndarray) -> np.ndarray:
        # Every state of the whole episode, the residual playing (STOP comes after 1-4 s).
        action = planner(obs)
        _, _, chosen, inputs = manager.decide(obs)
        assert inputs.shape[2] == 2 + RESIDUAL_FEATURES + ZONE_FEATURES * zone_features
        logits = manager.net(inputs)
        prior = inputs[..., 0] / manager.net.tau
        assert torch.equal(torch.isinf(logits), torch.isinf(prior))
        torch.testing.assert_close(logits[torch.isfinite(prior)], prior[torch.isfinite(prior)])
        compared.append(np.abs(chosen - action).max(1))
        # Where the rules moved the target (a zone over it): the planner's candidates are around the
        # moved one, and so must the residual's be.
        ruled = ruled_read(planner, obs)[0].target[:, 0:2]
        moved.append(np.hypot(*(ruled - obs[:, 0:2] * max_pos).T) > 1e-3)
        return chosen

    core = batched_core(config.task_config, 4, False, threads=1)
    ends = play(core, policy, 1)  # a seed whose fields put targets in zones (35 states; seed 3 none)
    close_core(core)
    gaps, moved = np.concatenate(compared), np.concatenate(moved)
    assert len(gaps) > 2000 and moved.sum() >= 10 and ends["success"].mean() > 0.5, (len(gaps), moved.sum())
    # 100 % of the planner's own choices, to the float32 of the actions.
    assert (gaps < 1e-6).all(), (
        f"{(gaps >= 1e-6).sum()} of {len(gaps)} differ, {(gaps[moved] >= 1e-6).sum()} moved"
    )


def test_the_candidates_planner_is_sampling_with_the_settings_it_names() -> None:
    def config(spec: str) -> dict:
        return {**SHIPPED, "candidates": {**SHIPPED["candidates"], "planner": spec}}

    with pytest.raises(
        ValueError, match="candidates.planner: planner 'sampling.brake=1': sampling has no setting"
    ):
        candidate_planner(parse_config(config("sampling+brake=1")))
    with pytest.raises(ConfigError, match="candidates.planner"):
        parse_config(config("trajectory"))  # its candidates are not a fixed set to choose among


def test_a_nonzero_last_layer_is_no_longer_the_planner() -> None:
    config = parse_config(SHIPPED)
    core = HierarchicalCore(config.task_config, 4)
    obs = core.reset(5).reshape(-1, core.obs_dim)
    planner = candidate_planner(config)
    net = _fresh()
    torch.nn.init.normal_(net.body[-1].weight, std=10.0)
    moved = candidate_manager(config, net).decide(obs)[2]
    assert np.abs(moved - planner(obs)).max() > 1e-3


@pytest.mark.parametrize("memory", [False, True])
def test_a_tiny_residual_run_moves_the_correction_and_keeps_the_planners_level(
    tmp_path: Path, memory: bool
) -> None:
    data = REMEMBERING if memory else SHIPPED
    ppo = {**data["candidates"]["ppo"], "iterations": 4, "fields": 4, "horizon": 16, "value_warmup": 1}
    section = {**data["candidates"], "hidden": [16, 16], "ppo": {**ppo, "eval_interval": 2}}
    scenario = {**data["scenario"], "frame_skip": 4}  # a quarter of the decisions: a test's time
    config = {**data, "scenario": scenario, "eval_episodes": 8, "candidates": section, "seed": 0}
    run = tmp_path / "run"
    summary = train(parse_config(config), run, progress=False)
    steps = [int(row["step"]) for row in csv.DictReader((run / "curve.csv").open())]
    assert steps == [0, 2, 4]  # step 0 is the planner itself, for model selection to keep
    saved = torch.load(run / "model.pt")
    assert saved["phase"] == "ppo" and saved["net"]["body.4.weight"].abs().sum() > 0
    assert saved["net"]["body.0.weight"].shape[1] == RESIDUAL_FEATURES + MEMORY_FEATURES * memory
    # Rebuilt from its weights alone (tau, layer sizes); played at the planner's level or near it (the
    # planner: 83 % of these 48 robots at frame skip 4).
    net = chooser_from_state(saved["net"])
    assert isinstance(net, Residual) and float(net.tau) == pytest.approx(data["candidates"]["tau"])
    assert float(net.keep) == pytest.approx(data["candidates"]["keep"])
    assert summary["final"]["success_rate"] >= 0.7, summary
    core = HierarchicalCore(parse_config(config).task_config, 2)
    obs = core.reset(1).reshape(12, -1)
    assert load_policy(run, which="final")(obs).shape == (12, core.act_dim)
    with pytest.raises(ValueError, match="residual candidates manager cannot be exported.*rollouts"):
        export_manager(run, "torchscript")


def test_the_dead_band_keeps_the_planners_tie_break_against_a_small_correction() -> None:
    config = parse_config(SHIPPED)
    planner = candidate_planner(config)
    seen = []

    def policy(obs: np.ndarray) -> np.ndarray:
        seen.append(obs[::4])
        return planner(obs)

    core = batched_core(config.task_config, 2, False, threads=1)
    play(core, policy, 1)
    close_core(core)
    obs = np.concatenate(seen[::10])
    moved = {}
    for keep in (0.0, 1.0):
        net = _fresh()
        net.keep.fill_(keep)
        # A correction of a few tenths between candidates: enough to re-break every exact tie of the
        # planner's ranking, less than the band.
        torch.nn.init.normal_(net.body[-1].weight, std=0.3)
        moved[keep] = np.abs(candidate_manager(config, net).decide(obs)[2] - planner(obs)).max(1)
    assert (moved[0.0] > 1e-3).sum() >= 5, moved[0.0]  # the ties and near-ties, no longer the planner's
    assert (moved[1.0] > 1e-3).sum() < (moved[0.0] > 1e-3).sum() / 2, moved


def test_the_kl_to_the_start_skips_what_the_planner_rules_out() -> None:
    start = torch.tensor([[0.0, -1.0, -torch.inf], [0.0, -torch.inf, -torch.inf]])
    logits = (start + torch.tensor([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])).requires_grad_()
    kl = categorical_kl(torch.log_softmax(logits, 1), torch.log_softmax(start, 1))
    kl.backward()
    assert 0 < kl.item() < 0.1 and torch.isfinite(logits.grad).all()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"rounds": 3}, r"candidates.rounds: 3 with network 'residual'"),
        ({"network": "ranker"}, r"candidates.network"),
        ({"keep": -1.0}, r"candidates.keep"),
        (
            {"network": "scorer", "rounds": 2, "zone_features": True},
            r"candidates\.zone_features: True adds to a residual's inputs; network is 'scorer'",
        ),
        (
            {"network": "classifier", "rounds": 2, "memory": True},
            r"candidates\.memory: True adds to a residual's inputs; network is 'classifier'",
        ),
        (
            {"network": "scorer", "rounds": 2, "keep": 1.0},
            r"keep: 1.0 is a residual's dead band; network is 'scorer'",
        ),
    ],
)
def test_residual_config_errors_name_the_value(change: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_config({**SHIPPED, "candidates": {**SHIPPED["candidates"], **change}})


def test_a_residual_needs_the_sampling_planner_and_a_known_kind() -> None:
    config = parse_config(SHIPPED)
    with pytest.raises(ValueError, match="sampling planner's ranking; got DirectPlanner"):
        residual_planner(make_planner("direct", config.task_config))
    residual_planner(candidate_planner(config))  # the game's RuledPlanner over sampling
    with pytest.raises(ValueError, match="unknown candidates.network 'ranker'"):
        build_chooser("ranker", (8,), None, 0)
    assert _fresh().body[0].in_features == RESIDUAL_FEATURES


def _game_stop_inputs() -> tuple:
    """A few game_stop states' planner, observations, scene, rules, candidates and both inputs."""
    config = parse_config(ZONED)
    planner = candidate_planner(config)
    core = HierarchicalCore(config.task_config, 8)
    obs = core.reset(5).reshape(-1, core.obs_dim)
    scene, rules = ruled_read(planner, obs)
    cand = planner.candidates(scene)
    return planner, obs, scene, rules, cand, residual_inputs(planner, obs, cand, True)


def test_the_zone_features_are_each_legs_least_clearance_from_the_rows_zones() -> None:
    planner, obs, scene, rules, cand, zoned = _game_stop_inputs()
    plain = residual_inputs(planner, obs, cand)
    # Off: what a residual read before the option; on: the same, then the two legs' clearances.
    assert plain.shape[2] == 2 + RESIDUAL_FEATURES and zoned.shape[2] == plain.shape[2] + ZONE_FEATURES
    assert torch.equal(zoned[..., : plain.shape[2]], plain)
    first, second = zoned[..., -2].numpy(), zoned[..., -1].numpy()
    assert np.isfinite(zoned[..., 2:].numpy()).all() and first.min() >= -1.0 and first.max() <= 3.0
    # A row where some candidates' first legs run through a zone and others keep clear of every zone.
    row = int(np.flatnonzero((first < 0).any(1) & (first > 0.2).any(1))[0])
    through, away = int(np.argmin(first[row])), int(np.argmax(first[row]))
    robot, target = scene.robot_pos[row], scene.target[row, 0:2]
    zones = rules.zones.take(row)
    for j, sign in ((through, -1.0), (away, 1.0)):
        point = np.array([cand[row, j].real, cand[row, j].imag])
        expected = np.clip(segment_clearance(zones, robot, point).min(), -1.0, 3.0)
        assert np.sign(expected) == sign and first[row, j] == pytest.approx(expected, abs=1e-5)
        expected = np.clip(segment_clearance(zones, point, target).min(), -1.0, 3.0)
        assert second[row, j] == pytest.approx(expected, abs=1e-5)
    # The planner's own verdict agrees: a candidate whose first leg breaks a zone (the robot outside all
    # of them) is not clear.
    clear = zoned[..., 7].numpy()  # the planner's own clear (RESIDUAL_FEATURES' sixth)
    assert clear[row, through] == 0.0
    # Without rules (a task outside the game) nothing is near: both columns at their ceiling.
    far = zone_clearances(None, scene.robot_pos @ np.array([1.0, 1j]), scene.target[:, 0] + 0j, cand)
    assert len(far) == ZONE_FEATURES and all((column == 3.0).all() for column in far)


def test_the_inputs_read_a_ranking_the_caller_already_has() -> None:
    planner, obs, scene, rules, cand, zoned = _game_stop_inputs()
    score, (arrival, clearance, hard, near), clear = planner.ranking(scene, cand, rules)
    given = (score, (arrival, clearance, hard, near), clear)
    assert torch.equal(residual_inputs(planner, obs, cand, True, ranked=given), zoned)
    # The ranking given is the one read, not computed again: a later arrival shows in its column.
    later = (score, (arrival + 1.0, clearance, hard, near), clear)
    shifted = residual_inputs(planner, obs, cand, True, ranked=later)[..., 2]
    assert torch.allclose(shifted, torch.as_tensor(arrival + 1.0, dtype=torch.float32).clip(0.0, 10.0))


def test_a_zone_featured_residual_reloads_with_its_runs_config(tmp_path: Path) -> None:
    config = parse_config(ZONED)
    net = _fresh(zone_features=True)
    assert net.body[0].in_features == RESIDUAL_FEATURES + ZONE_FEATURES
    torch.nn.init.normal_(net.body[-1].weight, std=1.0)
    run = tmp_path / "run"
    run.mkdir()
    (run / CONFIG_FILE).write_text(dump_config(config))
    save_checkpoint({"net": net.state_dict(), "step": 1}, run / BEST_ACTOR_FILE)
    manager = load_candidate_manager(run)
    assert isinstance(manager, ResidualManager) and manager.zone_features
    obs = _game_stop_inputs()[1]
    expected = candidate_manager(config, net).decide(obs)[2]
    np.testing.assert_array_equal(manager.decide(obs)[2], expected)
    # The same weights under a config without the key (11 features built for 13 read) are refused by name.
    (run / CONFIG_FILE).write_text(dump_config(parse_config(SHIPPED)))
    with pytest.raises(ValueError, match=r"reads 13 features a candidate, candidates.zone_features: False"):
        load_candidate_manager(run)


def test_the_memory_features_are_the_distances_to_the_last_sub_goal() -> None:
    planner, obs, scene, _, cand, _ = _game_stop_inputs()
    plain = residual_inputs(planner, obs, cand)
    last = cand[:, 3].copy()
    last[0] = np.nan  # row 0's robot has decided nothing yet this episode
    remembered = residual_inputs(planner, obs, cand, last=last)
    # Off: what a residual read before the option; on: the same, then the two distances.
    assert remembered.shape[2] == plain.shape[2] + MEMORY_FEATURES
    assert torch.equal(remembered[..., : plain.shape[2]], plain)
    to_last, robot_to_last = remembered[..., -2].numpy(), remembered[..., -1].numpy()
    assert (to_last[0] == 5.0).all() and (robot_to_last[0] == 5.0).all()
    assert np.abs(to_last[1:, 3]).max() < 1e-6  # the remembered candidate itself
    np.testing.assert_allclose(to_last[1:], np.abs(cand - last[:, None])[1:].clip(max=5.0), atol=1e-5)
    robot = scene.robot_pos @ np.array([1.0, 1j])
    np.testing.assert_allclose(robot_to_last[1:, 7], np.abs(robot - last)[1:].clip(max=5.0), atol=1e-5)


def test_a_residual_with_memory_starts_as_the_planner_and_remembers_each_robots_sub_goal() -> None:
    config = parse_config(REMEMBERING)
    planner = candidate_planner(config)
    tau = SHIPPED["candidates"]["tau"]
    net = build_chooser("residual", (16, 16), None, 0, tau, 0.0, False, True)
    assert net.body[0].in_features == RESIDUAL_FEATURES + MEMORY_FEATURES
    policy = candidate_policy(candidate_manager(config, net))
    assert isinstance(policy, RememberingPolicy)
    core = HierarchicalCore(config.task_config, 4)
    obs = core.reset(5).reshape(-1, core.obs_dim)
    policy.forget(len(obs) + 3)
    rows = np.arange(len(obs)) + 3
    action = policy(obs, rows=rows)
    np.testing.assert_allclose(action, planner(obs), atol=1e-6)  # no correction yet: the planner
    # Each robot's row now holds the sub-goal it was handed (m); the rows not asked for hold nothing.
    high = np.array([planner.field.half_length, planner.field.half_width])
    remembered = np.stack([policy.last[rows].real, policy.last[rows].imag], 1)
    np.testing.assert_allclose(remembered, action[:, 0:2] * high, atol=1e-5)
    assert np.isnan(policy.last[:3]).all()
    # Trained, what it remembers changes what it chooses.
    torch.nn.init.normal_(net.body[-1].weight, std=10.0)
    manager = candidate_manager(config, net)
    far = manager.decide(obs, last=np.full(len(obs), 4.0 + 2.9j))[2]
    near = manager.decide(obs, last=policy.last[rows])[2]
    assert np.abs(far - near).max() > 1e-3
    with pytest.raises(ValueError, match=r"keeps no memory \(candidates.memory: false\)"):
        candidate_manager(parse_config(SHIPPED), _fresh()).decide(obs, last=policy.last[rows])
