"""The batched vector view (torch tensors, auto-reset) and its rsl-rl-lib ``VecEnv`` adapter."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from hier_ssl.config import EnvConfig
from hier_ssl.envs.core import HierarchicalCore


class TorchView:
    """A numpy core with auto-reset, seen through torch tensors; the cores' shared vector protocol.

    ``step(actions (N, A) in [-1, 1])`` returns obs (N, O) float32, reward (N,), terminated (N,),
    truncated (N,), info. Finished fields are reset inside the step: ``obs`` is already the new
    episode's first observation and ``info["final_obs"]`` the last one of the old episode;
    ``info["episode"]`` holds one 1-D tensor entry per finished episode.
    """

    # Per-field info arrays a core may report besides "final_obs" and "episode", passed on as tensors.
    _PER_FIELD = ("control_steps", "action_clipped")

    def __init__(
        self,
        core: Any,
        num_obs: int,
        num_actions: int,
        max_episode_length: int,
        device: str | torch.device = "cpu",
    ) -> None:
        self.core = core
        self.num_envs = core.num_fields
        self.num_obs, self.num_actions = num_obs, num_actions
        self.max_episode_length = max_episode_length
        self.device = torch.device(device)

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
        out = {
            "final_obs": self._tensor(info["final_obs"]),
            "episode": {k: self._tensor(v) for k, v in info["episode"].items() if k != "field"},
        }
        for key in self._PER_FIELD:
            if key in info:
                out[key] = self._tensor(info[key], torch.int64)
        return (
            self._tensor(result.obs),
            self._tensor(result.reward),
            self._tensor(result.terminated, torch.bool),
            self._tensor(result.truncated, torch.bool),
            out,
        )


class VectorEnv(TorchView):
    """N fields of one paper task; managers act, scripted workers and obstacles run inside.

    ``info["episode"]`` entries: return, length in control steps, decisions, success, collision, cpad.
    """

    def __init__(self, config: EnvConfig, num_envs: int, device: str | torch.device = "cpu") -> None:
        self.config = config
        core = HierarchicalCore(config, num_envs, autoreset=True)
        decisions = -(-config.max_steps // config.frame_skip)
        super().__init__(core, core.obs_dim, core.act_dim, decisions, device)


class RslRlVecEnv(VecEnv):
    """rsl-rl-lib 5.x's VecEnv over the vector view: observations as a TensorDict with group "policy",
    ``extras["time_outs"]`` for truncation, episode means in ``extras["log"]``. The first reset takes
    ``seed``, so a run's episodes follow its seed."""

    def __init__(self, env: VectorEnv, seed: int | None = None) -> None:
        self.env = env
        self.num_envs = env.num_envs
        self.num_actions = env.num_actions
        self.max_episode_length = env.max_episode_length
        self.device = env.device
        self.cfg = env.config.model_dump()
        self.episode_length_buf = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self._obs = env.reset(seed)

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
