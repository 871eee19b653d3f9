"""The batched torch views of the core (auto-reset) and their rsl-rl-lib ``VecEnv`` adapter.

Rows are (field, controlled robot) pairs, row = field * M + robot, so one policy acts for every robot
(with M = 1, a row is a field; ``hier_ssl.envs.rows``). This is the protocol
``hier_ssl.policies.sac_runner.VectorEnv`` describes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from hier_ssl.config import TaskConfig
from hier_ssl.envs.rows import RowView
from hier_ssl.envs.shards import Threads, batched_core, close_core

_NUMPY_DTYPES = {torch.float32: np.float32, torch.bool: np.bool_, torch.int64: np.int64}


class TorchView(RowView):
    """A numpy core with auto-reset, seen through torch tensors: ``step(actions (rows, A) in [-1, 1])``,
    a tensor or any array-like, returns obs (rows, O) float32, reward (rows,), terminated (rows,),
    truncated (rows,), info, as tensors on ``device``.

    The rows and their info are ``RowView``'s: finished episodes are reset inside the step (``obs`` is
    already the new episode's first observation, ``info["final_obs"]`` the last one of the old episode),
    ``info["task"]`` holds one 1-D tensor entry per finished episode, ``info["live"]`` marks the rows
    whose transition is real where the core reports it (rows of robots that have left are absorbing).
    ``single_observation_space`` and ``single_action_space`` are one row's Boxes.
    """

    def __init__(
        self,
        core: Any,
        num_obs: int,
        action_shape: tuple[int, ...],
        max_episode_length: int,
        device: str | torch.device = "cpu",
    ) -> None:
        super().__init__(core, num_obs, action_shape, max_episode_length)
        self.device = torch.device(device)

    def _tensor(self, array: np.ndarray, dtype: torch.dtype = torch.float32) -> torch.Tensor:
        # numpy's conversion under torch.from_numpy: 1.5-2 us against 3-5 us for torch.as_tensor(...).to(),
        # of which a step makes 14 (np.require's checks cost as much again). A read-only array is copied:
        # torch would share it writable.
        want = _NUMPY_DTYPES[dtype]
        if array.dtype != want or not array.flags.writeable:
            array = array.astype(want)
        tensor = torch.from_numpy(array)
        return tensor if self.device.type == "cpu" else tensor.to(self.device)

    def reset(self, seed: int | None = None) -> torch.Tensor:
        return self._tensor(self.reset_rows(seed))

    def observe(self) -> torch.Tensor:
        return self._tensor(self.observe_rows())

    def check_actions(self, actions: Any) -> np.ndarray:
        if isinstance(actions, torch.Tensor):
            actions = actions.detach().to("cpu", torch.float64).numpy()
        return super().check_actions(actions)

    def step(
        self, actions: torch.Tensor | np.ndarray
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.step_rows(actions)
        out = {
            "final_obs": self._tensor(info["final_obs"]),
            "task": {k: self._tensor(v) for k, v in info["task"].items()},
        }
        if "live" in info:
            out["live"] = self._tensor(info["live"], torch.bool)
        for key in self.PER_ROW:
            if key in info:
                out[key] = self._tensor(info[key], torch.int64)
        return (
            self._tensor(obs),
            self._tensor(reward),
            self._tensor(terminated, torch.bool),
            self._tensor(truncated, torch.bool),
            out,
        )


class TorchVectorEnv(TorchView):
    """N fields of any task or scenario for one shared policy, managers acting and workers and obstacles
    scripted; ``num_envs`` = N x M rows.

    ``info`` besides "final_obs" (rows, O) and "task" (per robot that left: return, length in control
    steps, decisions, success, collision, cpad): "live" (rows,) bool, the rows whose transition is real,
    for learners that can mask; "control_steps" and "action_clipped" (rows,). A field resets once all its
    robots have left.

    ``threads`` (an int, or "auto": the cores this process may use) steps the fields' shards on that many
    cores (``hier_ssl.envs.shards``), with the same results for every count; ``close()`` stops the worker
    processes that takes.
    """

    def __init__(
        self,
        config: TaskConfig,
        num_fields: int,
        device: str | torch.device = "cpu",
        worker: Any = None,
        threads: Threads = 1,
    ) -> None:
        core = batched_core(config, num_fields, autoreset=True, worker=worker, threads=threads)
        self.config = core.config
        decisions = -(-self.config.max_steps // self.config.frame_skip)
        shape = (num_fields, core.num_agents, core.act_dim)
        super().__init__(core, core.obs_dim, shape, decisions, device)

    def close(self) -> None:
        """Stop the shards' worker processes, if any."""
        close_core(self.core)


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
