from __future__ import annotations

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
    assert len(info["episode"]["length"]) == 8
    assert torch.all(info["episode"]["length"] == 3)
    # Auto-reset: the returned observation starts a new episode, the final one is kept apart.
    assert not torch.equal(info["final_obs"], obs)


def test_rsl_rl_adapter() -> None:
    env = RslRlVecEnv(hier_ssl.vector_env(task="obstacle", num_envs=4, frame_skip=16))
    td = env.get_observations()
    assert td["policy"].shape == (4, 18)
    td, reward, dones, extras = env.step(torch.zeros(4, 4))
    assert reward.shape == (4,) and dones.shape == (4,)
    assert extras["time_outs"].shape == (4,)
