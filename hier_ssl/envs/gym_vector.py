"""The batched core as a ``gymnasium.vector.VectorEnv``: numpy in and out, for vector-env learners
(CleanRL-style loops, Gymnasium's vector wrappers) without glue and without torch.

Rows, auto-reset and absorbing rows are ``hier_ssl.envs.rows``'s. The core resets a finished field inside
``step`` and returns the new episode's first observation, the old one's last in ``info["final_obs"]``:
Gymnasium's same-step autoreset, declared as ``metadata["autoreset_mode"]``. Infos follow Gymnasium's
vector convention, an array over the rows per key and a boolean ``_key`` array saying which rows hold
one:

- ``final_obs`` (rows, O), ``_final_obs`` the rows whose episode ended (terminated or truncated);
- ``task_return``, ``task_length`` (control steps), ``task_decisions``, ``task_success``,
  ``task_collision``, ``task_cpad``: the task statistics, each (rows,) float64, its ``_task_...`` mask the
  rows whose robot left its episode this step. Flat keys, not one nested dict: clients that stack infos
  into tensors (TorchRL) take arrays, not dicts of them. ``final_info`` holds them again (``_final_info``
  as ``_final_obs``), where Gymnasium's own vector envs put a finished episode's last infos;
- ``live`` (rows,) bool, the rows whose transition is real; ``control_steps``, ``action_clipped``
  (rows,) ints; each with a ``_key`` array that is all True.

With M > 1 controlled robots a field (a multi-robot scenario) the rows of robots that have left while
their field plays on are absorbing (zero observation and reward, terminated every step, ``live``
False, no ``task_...`` entry) until the field resets: per-row episode trackers such as
``gymnasium.wrappers.vector.RecordEpisodeStatistics`` count each such step as an episode of its own,
so read the ``task_...`` keys (or mask with ``live``) there. The paper's tasks and one-robot scenarios
(M = 1) have none.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from hier_ssl.config import TaskConfig
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.rows import RowView
from hier_ssl.envs.shards import ShardedCore, Threads, batched_core, close_core


class ManagerVectorEnv(VectorEnv):
    """``num_fields`` fields of a task or scenario for one shared manager policy; ``num_envs`` = N x M
    rows. ``step(actions (rows, A) in [-1, 1])``; see the module docstring for the infos. ``threads`` (an
    int, or "auto") steps the fields' shards on that many cores (``hier_ssl.envs.shards``), the same
    results for every count; ``close()`` stops the worker processes that takes."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}
    # Gymnasium's own vector envs also carry the mode as an attribute, and clients (TorchRL) read that.
    autoreset_mode = AutoresetMode.SAME_STEP

    def __init__(self, config: TaskConfig, num_fields: int, worker: Any = None, threads: Threads = 1) -> None:
        core = batched_core(config, num_fields, autoreset=True, worker=worker, threads=threads)
        self.config = core.config
        decisions = -(-self.config.max_steps // self.config.frame_skip)
        self.rows = RowView(core, core.obs_dim, (num_fields, core.num_agents, core.act_dim), decisions)
        self.num_envs = self.rows.num_envs
        self.single_observation_space = self.rows.single_observation_space
        self.single_action_space = self.rows.single_action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    @property
    def core(self) -> HierarchicalCore | ShardedCore:
        return self.rows.core

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the shards' worker processes, if any (Gymnasium's ``close`` calls this)."""
        close_core(self.core)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every field anew (all of them: the core resets finished fields itself)."""
        super().reset(seed=seed)
        if seed is not None:
            self.action_space.seed(seed)
        return self.rows.reset_rows(seed), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.rows.step_rows(actions)
        n, every = self.num_envs, np.ones(self.num_envs, dtype=bool)
        rows = info["task_rows"]
        ended = np.zeros(n, dtype=bool)
        ended[rows] = True
        over = terminated | truncated
        out: dict[str, Any] = {"final_obs": info["final_obs"], "_final_obs": over}
        for key, values in info["task"].items():
            out[f"task_{key}"], out[f"_task_{key}"] = np.zeros(n), ended
            out[f"task_{key}"][rows] = values
        # Gymnasium's place for the last step's infos of the episodes that ended, where clients that treat
        # an ended row's infos as the new episode's (TorchRL) look for them.
        out["final_info"] = {k: v for k, v in out.items() if k.lstrip("_").startswith("task_")}
        out["_final_info"] = over
        for key in ("live", *RowView.PER_ROW):
            if key in info:
                out[key], out[f"_{key}"] = info[key], every
        return obs, reward, terminated, truncated, out


__all__ = ["ManagerVectorEnv"]
