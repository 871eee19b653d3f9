"""The batched vector view (torch tensors, auto-reset) and its rsl-rl-lib ``VecEnv`` adapter."""

from __future__ import annotations

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from hier_ssl.config import EnvConfig
from hier_ssl.envs.core import HierarchicalCore


class VectorEnv:
    """N fields of one task; managers act, scripted workers and obstacles run inside.

    ``step(actions (N, A) in [-1, 1])`` returns obs (N, O) float32, reward (N,), terminated (N,),
    truncated (N,), info. Finished fields are reset inside the step: ``obs`` is already the new
    episode's first observation and ``info["final_obs"]`` the last one of the old episode;
    ``info["episode"]`` holds one 1-D tensor entry per finished episode (return, length in control
    steps, success, collision, cpad).
    """

    def __init__(self, config: EnvConfig, num_envs: int, device: str | torch.device = "cpu") -> None:
        self.config = config
        self.core = HierarchicalCore(config, num_envs, autoreset=True)
        self.num_envs = num_envs
        self.num_obs = self.core.obs_dim
        self.num_actions = self.core.act_dim
        self.device = torch.device(device)
        self.max_episode_length = -(-config.max_steps // config.frame_skip)  # in decisions

    def _tensor(self, array: np.ndarray, dtype: torch.dtype = torch.float32) -> torch.Tensor:
        return torch.as_tensor(array, device=self.device).to(dtype)

    def reset(self, seed: int | None = None) -> torch.Tensor:
        return self._tensor(self.core.reset(seed))

    def observe(self) -> torch.Tensor:
        return self._tensor(self.core.observe())

    def step(
        self, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict]:
        result = self.core.step(actions.detach().to("cpu", torch.float64).numpy())
        info = result.info
        episode = {k: self._tensor(v, torch.float32) for k, v in info["episode"].items() if k != "field"}
        out = {
            "final_obs": self._tensor(info["final_obs"]),
            "episode": episode,
            "control_steps": self._tensor(info["control_steps"], torch.int64),
            "action_clipped": self._tensor(info["action_clipped"], torch.int64),
        }
        return (
            self._tensor(result.obs),
            self._tensor(result.reward),
            self._tensor(result.terminated, torch.bool),
            self._tensor(result.truncated, torch.bool),
            out,
        )


class RslRlVecEnv(VecEnv):
    """rsl-rl-lib 5.x's VecEnv over the vector view: observations as a TensorDict with group "policy",
    ``extras["time_outs"]`` for truncation, episode means in ``extras["log"]``."""

    def __init__(self, env: VectorEnv) -> None:
        self.env = env
        self.num_envs = env.num_envs
        self.num_actions = env.num_actions
        self.max_episode_length = env.max_episode_length
        self.device = env.device
        self.cfg = env.config.model_dump()
        self.episode_length_buf = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self._obs = env.reset()

    def _group(self, obs: torch.Tensor) -> TensorDict:
        return TensorDict({"policy": obs}, batch_size=[self.num_envs], device=self.device)

    def get_observations(self) -> TensorDict:
        return self._group(self._obs)

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        # rsl-rl's Gaussian policy is unbounded; the env's action space is [-1, 1].
        obs, reward, terminated, truncated, info = self.env.step(actions.clamp(-1.0, 1.0))
        self._obs = obs
        dones = terminated | truncated
        self.episode_length_buf += 1
        self.episode_length_buf[dones] = 0
        log = {f"/episode/{k}": v.mean() for k, v in info["episode"].items() if v.numel()}
        extras = {"time_outs": truncated, "log": log}
        return self._group(obs), reward, dones.long(), extras
