"""The batched torch views of the core (auto-reset) and their rsl-rl-lib ``VecEnv`` adapter.

Rows are (field, controlled robot) pairs, row = field * M + robot, so one policy acts for every robot
(with M = 1, a row is a field). This is the protocol ``hier_ssl.policies.sac_runner.VectorEnv`` describes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from hier_ssl.config import TaskConfig
from hier_ssl.envs.core import HierarchicalCore, StepResult


class TorchView:
    """A numpy core with auto-reset, seen through torch tensors: ``step(actions (rows, A) in [-1, 1])``
    returns obs (rows, O) float32, reward (rows,), terminated (rows,), truncated (rows,), info.

    Finished episodes are reset inside the step: ``obs`` is already the new episode's first observation
    and ``info["final_obs"]`` the last one of the old episode; ``info["task"]`` holds one 1-D tensor
    entry per finished episode. A core whose results carry ``info["live"]`` (per robot) marks the rows
    whose transition is real; a robot that has left while its field plays on is a row in an absorbing
    state: observation all zeros (no live observation is: it holds sin and cos of two angles), reward 0,
    terminated every step, so learners that store every row learn a value of 0 there and never bootstrap
    into it.
    """

    # Per-row info arrays a core may report besides "final_obs" and "task", passed on as tensors.
    _PER_ROW = ("control_steps", "action_clipped")

    def __init__(
        self,
        core: Any,
        num_obs: int,
        action_shape: tuple[int, ...],
        max_episode_length: int,
        device: str | torch.device = "cpu",
    ) -> None:
        self.core = core
        self.num_fields = core.num_fields
        self.action_shape = action_shape  # what the core's step takes: (N, A), or (N, M, A)
        self.num_envs = int(np.prod(action_shape[:-1]))  # rows
        self.num_obs, self.num_actions = num_obs, action_shape[-1]
        self.max_episode_length = max_episode_length
        self.device = torch.device(device)

    def _tensor(self, array: np.ndarray, dtype: torch.dtype = torch.float32) -> torch.Tensor:
        return torch.as_tensor(array, device=self.device).to(dtype)

    def _rows(self, array: np.ndarray, keep: np.ndarray | None = None) -> torch.Tensor:
        """Per-robot values (N, M, ...) or (N, ...) as rows (rows, ...); zeros where not ``keep``."""
        array = array.reshape(self.num_envs, -1)
        if keep is not None:
            array = np.where(keep.reshape(self.num_envs, 1), array, array.dtype.type(0))
        return self._tensor(array)

    def reset(self, seed: int | None = None) -> torch.Tensor:
        return self._rows(self.core.reset(seed))

    def _active(self) -> np.ndarray | None:
        """Which rows are in an episode (rows of the core's shape); None: all of them."""
        return None

    def observe(self) -> torch.Tensor:
        return self._rows(self.core.observe(), self._active())

    def _check(self, actions: torch.Tensor) -> np.ndarray:
        action = actions.detach().to("cpu", torch.float64).numpy()
        if action.shape != (self.num_envs, self.num_actions):
            expected = (self.num_envs, self.num_actions)
            raise ValueError(f"actions have shape {tuple(action.shape)}, expected {expected}")
        if not np.isfinite(action).all():
            rows = np.flatnonzero(~np.isfinite(action).all(axis=1))
            raise ValueError(f"actions of rows {rows.tolist()} hold NaN or infinite values")
        return action

    def step(
        self, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        action = self._check(actions)
        result: StepResult = self.core.step(action.reshape(self.action_shape))
        info, live = result.info, result.info.get("live")
        keys = [k for k in info["task"] if k not in ("field", "agent")]
        out = {
            "final_obs": self._rows(info["final_obs"], live),
            "task": {k: self._tensor(info["task"][k]) for k in keys},
        }
        if live is not None:
            out["live"] = self._tensor(live.ravel(), torch.bool)
        for key in self._PER_ROW:
            if key in info:
                out[key] = self._tensor(info[key].ravel(), torch.int64)
        terminated = result.terminated if live is None else result.terminated | ~live
        return (
            self._rows(result.obs, self._active()),
            self._tensor(result.reward.ravel()),
            self._tensor(terminated.ravel(), torch.bool),
            self._tensor(result.truncated.ravel(), torch.bool),
            out,
        )


class TorchVectorEnv(TorchView):
    """N fields of any task or scenario for one shared policy, managers acting and workers and obstacles
    scripted; ``num_envs`` = N x M rows.

    ``info`` besides "final_obs" (rows, O) and "task" (per robot that left: return, length in control
    steps, decisions, success, collision, cpad): "live" (rows,) bool, the rows whose transition is real,
    for learners that can mask; "control_steps" and "action_clipped" (rows,). A field resets once all its
    robots have left.
    """

    def __init__(
        self, config: TaskConfig, num_fields: int, device: str | torch.device = "cpu", worker: Any = None
    ) -> None:
        core = HierarchicalCore(config, num_fields, autoreset=True, worker=worker)
        self.config = core.config
        decisions = -(-self.config.max_steps // self.config.frame_skip)
        shape = (num_fields, core.num_agents, core.act_dim)
        super().__init__(core, core.obs_dim, shape, decisions, device)

    def _active(self) -> np.ndarray:
        return self.core.active


class RslRlVecEnv(VecEnv):
    """rsl-rl-lib 5.x's VecEnv over a torch view: observations as a TensorDict with group "policy",
    ``extras["time_outs"]`` for truncation, episode means in ``extras["log"]``. The first reset takes
    ``seed``, so a run's episodes follow its seed."""

    def __init__(self, env: TorchView, seed: int | None = None) -> None:
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
        log = {f"/episode/{k}": v.mean() for k, v in info["task"].items() if v.numel()}
        extras = {"time_outs": truncated, "log": log}
        return self._group(obs), reward, dones.long(), extras


__all__ = ["RslRlVecEnv", "TorchVectorEnv", "TorchView"]
