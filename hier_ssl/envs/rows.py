"""A batched core with auto-reset as rows of numpy arrays: what the torch view and the Gymnasium vector
view both show, each in its own types.

Rows are (field, controlled robot) pairs, row = field * M + robot, so one policy acts for every robot
(with M = 1, a row is a field). Finished episodes are reset inside ``step``: the observation returned is
already the new episode's first one and ``info["final_obs"]`` the last one of the old episode
(Gymnasium's same-step autoreset). A core whose results carry ``info["live"]`` (per robot) marks the rows
whose transition is real; a robot that has left while its field plays on is a row in an absorbing state:
observation all zeros (no live observation is: it holds sin and cos of two angles), reward 0, terminated
every step, so learners that store every row learn a value of 0 there and never bootstrap into it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from hier_ssl.world.frames import all_finite

OBS_BOUND = 1.2  # every observation value is clipped to +-1.2


class RowView:
    """``core`` (``HierarchicalCore`` or ``GoToPointCore``, auto-reset) as rows: ``reset(seed)`` and
    ``step(actions (rows, A) in [-1, 1])`` give obs (rows, O) float32, reward (rows,) float32,
    terminated and truncated (rows,) bool, and info:

    - "final_obs" (rows, O): the observation before any auto-reset (equal to obs where nothing ended);
    - "task": the task statistics of the episodes that ended, one entry per robot that left (1-D arrays:
      return, length in control steps, ... as the core reports them), and "task_rows" (E,) their rows;
    - "live" (rows,) bool where the core reports it; per-row ints "control_steps", "action_clipped".

    ``single_observation_space`` and ``single_action_space`` are the spaces of one row.
    """

    # Per-row info arrays a core may report besides "final_obs" and "task", passed on as they are.
    PER_ROW = ("control_steps", "action_clipped")

    def __init__(
        self, core: Any, num_obs: int, action_shape: tuple[int, ...], max_episode_length: int
    ) -> None:
        self.core = core
        self.num_fields = core.num_fields
        self.action_shape = action_shape  # what the core's step takes: (N, A), or (N, M, A)
        self.num_envs = int(np.prod(action_shape[:-1]))  # rows
        self.robots = self.num_envs // self.num_fields  # M, rows of a field
        self.num_obs, self.num_actions = num_obs, action_shape[-1]
        self.max_episode_length = max_episode_length  # env steps (decisions) before a truncation
        box = {"dtype": np.float32}
        self.single_observation_space = spaces.Box(-OBS_BOUND, OBS_BOUND, (num_obs,), **box)
        self.single_action_space = spaces.Box(-1.0, 1.0, (self.num_actions,), **box)

    def rows(self, array: np.ndarray, keep: np.ndarray | None = None) -> np.ndarray:
        """Per-robot values (N, M, ...) or (N, ...) as rows (rows, ...); zeros where not ``keep``."""
        array = array.reshape(self.num_envs, -1)
        if keep is not None:
            # A copy with the few rows not kept zeroed: a third of the time of np.where over every value.
            array = array.copy()
            array[~keep.ravel()] = 0
        return array

    def active(self) -> np.ndarray | None:
        """Which rows are in an episode (rows of the core's shape); None: all of them."""
        return getattr(self.core, "active", None)

    def reset_rows(self, seed: int | None = None) -> np.ndarray:
        """Start every field anew; the observations (rows, O) float32."""
        return self.rows(self.core.reset(seed))

    def observe_rows(self) -> np.ndarray:
        return self.rows(self.core.observe(), self.active())

    def check_actions(self, actions: Any) -> np.ndarray:
        """``actions`` (rows, A), any array-like, as float64; a ValueError names a wrong shape or the rows
        holding NaN or infinite values."""
        action = np.asarray(actions, dtype=np.float64)
        if action.shape != (self.num_envs, self.num_actions):
            expected = (self.num_envs, self.num_actions)
            raise ValueError(f"actions have shape {tuple(action.shape)}, expected {expected}")
        if not all_finite(action):
            rows = np.flatnonzero(~np.isfinite(action).all(axis=1))
            raise ValueError(f"actions of rows {rows.tolist()} hold NaN or infinite values")
        return action

    def step_rows(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One step of every field with ``actions`` (rows, A); see the class docstring."""
        result = self.core.step(self.check_actions(actions).reshape(self.action_shape))
        info, live = result.info, result.info.get("live")
        stats = info["task"]
        agent = stats.get("agent", 0)
        out: dict[str, Any] = {
            "final_obs": self.rows(info["final_obs"], live),
            "task": {k: v for k, v in stats.items() if k not in ("field", "agent")},
            "task_rows": stats["field"] * self.robots + agent,
        }
        if live is not None:
            out["live"] = live.ravel()
        for key in self.PER_ROW:
            if key in info:
                out[key] = info[key].ravel()
        terminated = result.terminated if live is None else result.terminated | ~live
        return (
            self.rows(result.obs, self.active()),
            result.reward.ravel(),
            terminated.ravel(),
            result.truncated.ravel(),
            out,
        )


__all__ = ["OBS_BOUND", "RowView"]
