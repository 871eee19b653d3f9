"""The batched view as a ``gymnasium.vector.VectorEnv`` (numpy, same-step autoreset), and the torch view's
one-row spaces and numpy actions."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gymnasium.utils.performance import benchmark_vector_step
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers.vector import RecordEpisodeStatistics

import hier_ssl


def test_a_short_loop_autoresets_in_the_same_step() -> None:
    env = hier_ssl.manager_vector_env(task="proposed", num_fields=4, frame_skip=16, max_steps=64)
    assert env.metadata["autoreset_mode"] is env.autoreset_mode is AutoresetMode.SAME_STEP
    assert env.observation_space.shape == (4, 13) and env.action_space.shape == (4, 4)
    obs, info = env.reset(seed=0)
    assert info == {} and obs.dtype == np.float32 and env.observation_space.contains(obs)
    first = obs
    for step in range(1, 5):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs) and reward.dtype == np.float32
        assert info["_control_steps"].all() and info["live"].all()
        if step < 4:
            assert not truncated.any() and not info["_task_length"].any()
    # 64 control steps in decisions of 16: the 4th truncates every field, which starts anew at once.
    assert truncated.all() and info["_final_obs"].all() and info["_task_length"].all()
    np.testing.assert_array_equal(info["task_length"], 64)
    np.testing.assert_array_equal(info["task_decisions"], 4)
    assert not np.array_equal(info["final_obs"], obs)  # the old episodes' last observations, kept apart
    assert not np.array_equal(obs, first)  # new starts, not a replay of the seeded ones


def test_the_task_statistics_land_on_the_rows_that_ended() -> None:
    env = hier_ssl.manager_vector_env(task="proposed", num_fields=3, frame_skip=16)
    env.reset(seed=1)
    # Field 1 aims at its own target (the direct sub-goal), the others at a corner.
    target = env.core.target[:, 0]
    half = np.array([env.core.field.half_length, env.core.field.half_width])
    actions = np.tile([0.9, 0.9, 0.0, 1.0], (3, 1))
    actions[1] = [*(target[1, :2] / half), np.sin(target[1, 2]), np.cos(target[1, 2])]
    while True:
        _, _, terminated, truncated, info = env.step(actions)
        if terminated.any():
            break
    assert terminated.tolist() == [False, True, False] and not truncated.any()
    assert info["_task_success"].tolist() == [False, True, False]
    assert info["task_success"].tolist() == [0, 1, 0]
    assert info["_final_obs"].tolist() == [False, True, False]


def test_gymnasium_vector_wrappers_and_benchmark_run_on_it() -> None:
    env = RecordEpisodeStatistics(
        hier_ssl.manager_vector_env(task="obstacle", num_fields=3, frame_skip=16, max_steps=48)
    )
    env.reset(seed=2)
    env.action_space.seed(2)
    for _ in range(9):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        done = terminated | truncated
        if done.any():  # the wrapper's episode and the task's, on the same rows
            assert (info["_episode"] == done).all() and (info["_task_length"] == done).all()
            np.testing.assert_allclose(info["episode"]["r"][done], info["task_return"][done], rtol=1e-5)
            np.testing.assert_array_equal(info["episode"]["l"][done], info["task_decisions"][done])
    assert env.episode_count >= 6
    steps_per_s = benchmark_vector_step(hier_ssl.manager_vector_env(task="proposed", num_fields=2), 0.2)
    assert steps_per_s > 0


def test_it_steps_as_the_torch_view_does() -> None:
    numpy_env = hier_ssl.manager_vector_env("crossing", num_fields=2, num_agents=3, max_steps=160)
    torch_env = hier_ssl.scenario_vector_env("crossing", num_fields=2, num_agents=3, max_steps=160)
    np.testing.assert_array_equal(numpy_env.reset(seed=3)[0], torch_env.reset(seed=3).numpy())
    rng = np.random.default_rng(0)
    for _ in range(12):
        actions = rng.uniform(-1, 1, (6, numpy_env.single_action_space.shape[0])).astype(np.float32)
        a, b = numpy_env.step(actions), torch_env.step(torch.as_tensor(actions))
        for x, y in zip(a[:4], b[:4], strict=True):
            np.testing.assert_array_equal(x, y.numpy())
        np.testing.assert_array_equal(a[4]["live"], b[4]["live"].numpy())
        np.testing.assert_array_equal(a[4]["final_obs"], b[4]["final_obs"].numpy())


def test_bad_actions_are_named() -> None:
    env = hier_ssl.manager_vector_env(task="proposed", num_fields=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions have shape \(2, 3\), expected \(2, 4\)"):
        env.step(np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"actions of rows \[1\] hold NaN"):
        env.step(np.array([[0, 0, 0, 1], [np.nan, 0, 0, 1]]))


def test_the_torch_view_has_one_row_spaces_and_takes_numpy_actions() -> None:
    env, twin = (hier_ssl.vector_env(task="obstacle", num_envs=3, frame_skip=4) for _ in range(2))
    assert env.single_observation_space.shape == (18,) and env.single_action_space.shape == (4,)
    # float32 against float32: numpy < 2 compares a float32 with a Python 1.2 in float64.
    assert env.single_action_space.low.min() == -1.0
    assert env.single_observation_space.high.max() == np.float32(1.2)
    env.reset(seed=4), twin.reset(seed=4)
    actions = np.random.default_rng(1).uniform(-1, 1, (3, 4))
    for _ in range(3):
        a, b = env.step(actions), twin.step(torch.as_tensor(actions, dtype=torch.float32))
        torch.testing.assert_close(a[0], b[0])
        torch.testing.assert_close(a[1], b[1])
