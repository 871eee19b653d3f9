"""The SSL game's scenarios through every view: PettingZoo's API and seed tests, Gymnasium's check_env on
their ids, the vector views, and a seeded episode replayed identically."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

import hier_ssl
from hier_ssl.envs import HierarchicalCore, ManagerEnv, scenario_config
from hier_ssl.envs.game import GameScenario
from hier_ssl.game import KINDS
from hier_ssl.registration import ID_SETTINGS, IDS

GAMES = ("game_stop", "game_free_kick", "game_ball_placement", "game_match")
# Small and short: two of ours against two opponents that decide often, STOP within the first second.
SMALL = {"num_agents": 2, "num_obstacles": 2, "max_steps": 48, "frame_skip": 4}


def _small(name: str, **overrides: object) -> dict[str, object]:
    options = {"command_at": [0.2, 0.6]} if name == "game_stop" else {}
    return {**SMALL, "options": options, **overrides}


@pytest.mark.parametrize("name", GAMES)
def test_each_game_passes_the_parallel_api_and_seed_tests(name: str) -> None:
    env = hier_ssl.scenario_env(name, **_small(name))
    assert isinstance(env.core.scenario, GameScenario)
    assert env.possible_agents == ["manager_0", "manager_1"]
    parallel_api_test(env, num_cycles=20)
    parallel_seed_test(lambda: hier_ssl.scenario_env(name, **_small(name)), num_cycles=5)


@pytest.mark.filterwarnings("ignore:.*is different from the unwrapped version")
@pytest.mark.parametrize("env_id", sorted(ID_SETTINGS))
def test_each_game_id_is_one_robot_of_ours_and_passes_check_env(env_id: str) -> None:
    env = gymnasium.make(env_id, frame_skip=16, max_steps=64)
    assert isinstance(env.unwrapped, ManagerEnv) and IDS[env_id].startswith("game_")
    assert env.spec.kwargs == {"config": IDS[env_id], "num_agents": 1, "frame_skip": 16, "max_steps": 64}
    core = env.unwrapped.env.core
    assert core.num_agents == 1 and core.num_obstacles == (11 if env_id.endswith("GameMatch-v0") else 6)
    check_env(env, skip_render_check=True)


@pytest.mark.parametrize("name", GAMES)
def test_the_vector_views_take_the_games(name: str) -> None:
    import torch

    gym_vec = hier_ssl.manager_vector_env(name, num_fields=2, **_small(name))
    obs, _ = gym_vec.reset(seed=0)
    assert obs.shape == (4, gym_vec.core.obs_dim) and gym_vec.num_envs == 4
    # Past the time limit (12 decisions of 4 control steps): every field resets inside step.
    for _ in range(12):
        obs, _, terminated, truncated, info = gym_vec.step(np.zeros((4, gym_vec.core.act_dim), np.float32))
    assert (terminated | truncated).all() and info["_task_foul"].any()
    assert (gym_vec.core.steps == 0).all() and (gym_vec.core.scenario.way == 0).all()
    torch_vec = hier_ssl.scenario_vector_env(name, num_fields=2, **_small(name))
    obs = torch_vec.reset(seed=0)
    out = torch_vec.step(torch.zeros((4, torch_vec.core.act_dim)))
    assert obs.shape == out[0].shape == (4, torch_vec.core.obs_dim)


def _episode(name: str, seed: int) -> tuple[list[np.ndarray], dict[str, np.ndarray]]:
    """Observations of every decision of a seeded episode on two fields, random actions from the seed,
    and the statistics of the robots as they left."""
    core = HierarchicalCore(scenario_config(name, **_small(name)), 2, autoreset=False)
    rng = np.random.default_rng(seed)
    seen, stats = [core.reset(seed)], []
    while core.active.any():
        result = core.step(rng.uniform(-1, 1, (2, core.num_agents, core.act_dim)))
        seen += [result.obs, core.world.ball.pos.copy(), core.scenario.referee.command.copy()]
        stats.append(result.info["task"])
    return seen, {k: np.concatenate([s[k] for s in stats]) for k in stats[0]}


@pytest.mark.parametrize("name", GAMES)
def test_a_seeded_episode_replays_identically_and_reports_fouls_by_kind(name: str) -> None:
    first, stats = _episode(name, 3)
    again, stats_again = _episode(name, 3)
    assert len(first) == len(again)
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    assert stats.keys() == stats_again.keys() >= {"foul", *(f"foul_{kind}" for kind in KINDS)}
    for key in stats:
        np.testing.assert_array_equal(stats[key], stats_again[key])
    assert len(stats["agent"]) == 4  # every robot of both fields left once
    # A robot leaves one way: success, collision, foul or the time limit.
    assert (stats["success"] + stats["collision"] + stats["foul"] <= 1).all()
    other, _ = _episode(name, 4)
    assert not np.array_equal(first[0], other[0])
