from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, render_test

import hier_ssl

SETTINGS = [
    {"task": "baseline"},
    {"task": "proposed", "frame_skip": 16},
    {"task": "obstacle", "frame_skip": 4},
    {"task": "obstacle", "expose_worker": True, "expose_obstacles": True, "frame_skip": 4},
    {"task": "proposed", "action_form": "pose6"},
]


@pytest.mark.parametrize("settings", SETTINGS)
def test_pettingzoo_parallel_api(settings: dict) -> None:
    parallel_api_test(hier_ssl.parallel_env(**settings), num_cycles=100)


@pytest.mark.parametrize("settings", SETTINGS[1:3])
def test_pettingzoo_seed(settings: dict) -> None:
    parallel_seed_test(lambda: hier_ssl.parallel_env(**settings), num_cycles=20)


def test_aec_api_and_render() -> None:
    api_test(hier_ssl.env(task="proposed", frame_skip=16), num_cycles=20)
    render_test(
        lambda render_mode=None: hier_ssl.env(task="obstacle", frame_skip=16, render_mode=render_mode)
    )


def test_gymnasium_single_agent_view() -> None:
    check_env(hier_ssl.manager_env(task="proposed", frame_skip=16), skip_render_check=True)


def test_spaces_are_the_same_object_every_call() -> None:
    env = hier_ssl.parallel_env(task="obstacle", expose_worker=True)
    for agent in env.possible_agents:
        assert env.observation_space(agent) is env.observation_space(agent)
        assert env.action_space(agent) is env.action_space(agent)
    assert env.possible_agents == ["manager_0", "worker_0"]


def test_frame_skip_gives_75_decisions_per_timed_out_episode() -> None:
    env = hier_ssl.parallel_env(task="proposed", frame_skip=16)
    env.reset(seed=3)
    # Sub-goal far from the target: the episode can only time out.
    obs, _ = env.reset(seed=3)
    away = -np.sign(obs["manager_0"][:2]) * 0.9
    action = np.array([away[0], away[1], 0.0, 1.0], dtype=np.float32)
    decisions, steps = 0, 0
    while env.agents:
        _, _, _, truncs, infos = env.step({"manager_0": action})
        decisions += 1
        steps += infos["manager_0"]["control_steps"]
    assert truncs["manager_0"]
    assert decisions == 75 and steps == 1200
    assert infos["manager_0"]["task"]["length"] == 1200


def test_bad_actions_raise_naming_the_agent() -> None:
    env = hier_ssl.parallel_env(task="proposed")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="manager_0.*shape"):
        env.step({"manager_0": np.zeros(3)})
    with pytest.raises(ValueError, match="manager_0.*NaN"):
        env.step({"manager_0": np.array([np.nan, 0, 0, 1])})
    with pytest.raises(ValueError, match="does not have.*worker_0"):
        env.step({"manager_0": np.zeros(4), "worker_0": np.zeros(3)})
    # The rejected steps changed nothing: the same seed still gives the same first step.
    obs_a = env.step({"manager_0": np.array([0.5, 0.5, 0.0, 1.0])})[0]
    env.reset(seed=0)
    obs_b = env.step({"manager_0": np.array([0.5, 0.5, 0.0, 1.0])})[0]
    np.testing.assert_array_equal(obs_a["manager_0"], obs_b["manager_0"])


def test_out_of_range_actions_are_clipped_and_counted() -> None:
    env = hier_ssl.parallel_env(task="proposed")
    env.reset(seed=0)
    _, _, _, _, infos = env.step({"manager_0": np.array([3.0, -2.0, 0.0, 1.0])})
    assert infos["manager_0"]["action_clipped"] == 2
    np.testing.assert_allclose(infos["manager_0"]["subgoal"][:2], [3.0, -2.0])


def test_a_step_after_the_last_agent_left_returns_five_empty_dicts() -> None:
    env = hier_ssl.parallel_env(task="proposed", max_steps=2)
    with pytest.raises(RuntimeError, match="reset"):
        env.step({"manager_0": np.zeros(4)})
    env.reset(seed=0)
    while env.agents:
        env.step({"manager_0": np.zeros(4)})
    # As PettingZoo's converted envs answer (SuperSuit's black_death_v3 and RLlib rely on it).
    assert env.step({}) == ({}, {}, {}, {}, {})
    assert env.step({"manager_0": np.zeros(4)}) == ({}, {}, {}, {}, {})
    gym_env = hier_ssl.manager_env(task="proposed", max_steps=2, frame_skip=2)
    gym_env.reset(seed=0)
    gym_env.step(np.zeros(4))
    with pytest.raises(RuntimeError, match="reset"):
        gym_env.step(np.zeros(4))


def test_actions_for_agents_that_have_left_are_ignored() -> None:
    # One env is sent an action for every agent each step, as TorchRL's wrapper does; its twin only the
    # live agents'. Robots leave one by one, and the two play the same episode.
    env, twin = (hier_ssl.scenario_env("crossing", num_agents=3) for _ in range(2))
    env.reset(seed=0)
    twin.reset(seed=0)
    rng = np.random.default_rng(0)
    live_counts = []
    while env.agents:
        every = {a: rng.uniform(-1, 1, 4).astype(np.float32) for a in env.possible_agents}
        obs, rewards, terms, truncs, infos = env.step(every)
        want = twin.step({a: every[a] for a in twin.agents})
        for got, expected in zip((obs, rewards, terms, truncs), want[:4], strict=True):
            assert got.keys() == expected.keys()
            for agent in expected:
                np.testing.assert_array_equal(got[agent], expected[agent])
        live_counts.append(len(env.agents))
    assert len(set(live_counts)) > 1  # some agents left before others


def test_render_rgb_array() -> None:
    env = hier_ssl.parallel_env(task="obstacle", render_mode="rgb_array")
    env.reset(seed=1)
    env.step({"manager_0": np.zeros(4)})
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert frame.std() > 0
