from __future__ import annotations

import pytest
import torch

import hier_ssl
from hier_ssl.envs import RslRlVecEnv


def test_vector_env_shapes_autoreset_and_final_obs() -> None:
    env = hier_ssl.vector_env(task="proposed", num_envs=8, max_steps=3)
    obs = env.reset(seed=0)
    assert obs.shape == (8, 13) and obs.dtype == torch.float32
    actions = torch.zeros(8, 4)
    actions[:, 3] = 1.0
    for _ in range(2):
        obs, reward, terminated, truncated, info = env.step(actions)
        assert reward.shape == (8,) and not truncated.any()
        assert torch.equal(info["final_obs"], obs)
    obs, reward, terminated, truncated, info = env.step(actions)
    assert truncated.all() and not terminated.any()
    assert len(info["task"]["length"]) == 8
    assert torch.all(info["task"]["length"] == 3)
    # Auto-reset: the returned observation starts a new episode, the final one is kept apart.
    assert not torch.equal(info["final_obs"], obs)


def test_rsl_rl_adapter() -> None:
    env = RslRlVecEnv(hier_ssl.vector_env(task="obstacle", num_envs=4, frame_skip=16))
    td = env.get_observations()
    assert td["policy"].shape == (4, 18)
    td, reward, dones, extras = env.step(torch.zeros(4, 4))
    assert reward.shape == (4,) and dones.shape == (4,)
    assert extras["time_outs"].shape == (4,)


def test_bad_actions_are_named_and_change_nothing() -> None:
    env, twin = (hier_ssl.vector_env(task="proposed", num_envs=3, frame_skip=4) for _ in range(2))
    env.reset(seed=1), twin.reset(seed=1)
    with pytest.raises(ValueError, match=r"actions have shape \(3, 3\), expected \(3, 4\)"):
        env.step(torch.zeros(3, 3))
    nan = torch.zeros(3, 4)
    nan[2, 1] = float("nan")
    with pytest.raises(ValueError, match=r"actions of rows \[2\] hold NaN"):
        env.step(nan)
    action = torch.full((3, 4), 0.5)
    assert torch.equal(env.step(action)[0], twin.step(action)[0])
