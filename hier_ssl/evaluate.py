"""Seeded, batched evaluation of a manager: one episode per field, all fields stepped together."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from hier_ssl.config import EnvConfig
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.manager import min_time_to_pose, summarize
from hier_ssl.world.physics import RobotSpec

Policy = Callable[[np.ndarray], np.ndarray]
"""Manager observations (N, obs_dim) -> actions (N, act_dim) in [-1, 1]."""


def evaluate(
    policy: Policy, config: EnvConfig, episodes: int, seed: int = 0, record: Sequence[int] = ()
) -> dict[str, object]:
    """Run ``episodes`` episodes (one per field, seeded: the same starts, targets and obstacle motion for
    every policy given the same seed) and summarise them.

    The policy sees only the fields whose episode is still running (its input has fewer rows as episodes
    end), so a row-wise policy costs nothing for finished episodes.

    Returns success_rate, collision_rate, episode_length and cpad as {median, q1, q3, min, max},
    optimal_ratio_median (episode time over the analytic rest-to-rest minimum time to the target under
    the robot's speed and acceleration limits, successful episodes only), time_to_target_s_median
    (successful episodes, seconds), the raw per-episode arrays
    under "per_episode", and eval_wall_s. With ``record`` (episode indices), "trajectories" holds one
    dict per recorded episode, every control step of it (see ``Recorder.episode``).
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    start = time.perf_counter()
    core = HierarchicalCore(config, episodes, autoreset=False)
    ends = play(core, policy, seed, record)
    length, success, collision, cpad = ends["length"], ends["success"], ends["collision"], ends["cpad"]
    distance = ends["distance"]
    solved, nan = bool(success.any()), float("nan")
    summary: dict[str, object] = {
        "episodes": episodes,
        "success_rate": float(success.mean()),
        "collision_rate": float(collision.mean()),
        "episode_length": summarize(length),
        "cpad": summarize(cpad),
        "optimal_ratio_median": optimal_ratio_median(length, success, distance, core.robot, config.dt),
        "time_to_target_s_median": float(np.median(length[success]) * config.dt) if solved else nan,
        "per_episode": {
            "length": length,
            "success": success,
            "collision": collision,
            "cpad": cpad,
            "distance": distance,
        },
    }
    if record:
        summary["trajectories"] = ends["trajectories"]
    summary["eval_wall_s"] = time.perf_counter() - start
    return summary


def play(core: Any, policy: Policy, seed: int, record: Sequence[int] = ()) -> dict[str, Any]:
    """Reset a core built without auto-reset with ``seed`` (one episode per field) and play every episode
    to its end; the policy acts for the live rows only (its input shrinks as episodes end). One loop for
    ``HierarchicalCore`` (a row per field, shape (N,)) and ``MultiRobotCore`` (a row per robot, (N, M)).

    Returns length (control steps), success, collision, cpad and distance (start to target, m), arrays of
    ``core.active``'s shape, and "trajectories": the ``record`` fields' episodes (``Recorder.episode``).
    """
    record = check_record(record, core.num_fields)
    obs = core.reset(seed)
    recorder = Recorder(core, record) if record else None
    shape = core.active.shape
    target = core.target.reshape(core.num_fields, -1, 5)
    start = core.world.state.pos[:, : target.shape[1]]
    distance = np.linalg.norm(start - target[..., 0:2], axis=2).reshape(shape)
    ends = {
        "length": np.zeros(shape, dtype=np.int64),
        "success": np.zeros(shape, dtype=bool),
        "collision": np.zeros(shape, dtype=bool),
        "cpad": np.zeros(shape),
    }
    action = np.zeros(shape + (core.act_dim,))
    while core.active.any():
        live = core.active
        action[live] = policy(obs[live])
        result = core.step(action)
        episode = result.info["episode"]
        at = tuple(episode[key] for key in ("field", "agent") if key in episode)
        for key in ends:
            ends[key][at] = episode[key] > 0 if ends[key].dtype == bool else episode[key]
        obs = result.obs
    # A field's control steps stop counting when its last robot leaves: the recorded episode's length.
    trajectories = [recorder.episode(j, int(core.steps[i])) for j, i in enumerate(record)] if recorder else []
    return {**ends, "distance": distance, "trajectories": trajectories}


def check_record(record: Sequence[int], episodes: int) -> list[int]:
    """Episode indices to record, as ints; ValueError naming them if any is out of range."""
    record = [int(i) for i in record]
    if any(not 0 <= i < episodes for i in record):
        raise ValueError(f"record: episode indices must be in [0, {episodes}), got {record}")
    return record


def optimal_ratio_median(
    length: np.ndarray, success: np.ndarray, distance: np.ndarray, robot: RobotSpec, dt: float
) -> float:
    """Median, over successful robots, of time to the target over the analytic rest-to-rest minimum
    under the robot's speed and acceleration limits (NaN when none succeeded). Same-shape arrays:
    length in control steps, success, and the start-to-target distance in m."""
    if not success.any():
        return float("nan")
    bound = min_time_to_pose(distance[success], robot.max_speed, robot.max_accel)
    return float(np.median(length[success] * dt / np.maximum(bound, 1e-9)))


class Recorder:
    """Poses and sub-goals of chosen fields after every control step, by wrapping a core's
    ``control_step`` (the batched path of ``step`` is unchanged; the copies are of a few rows). Works for
    ``HierarchicalCore`` (one controlled robot) and ``MultiRobotCore`` (M, robots 0..M-1)."""

    def __init__(self, core: Any, fields: Sequence[int]) -> None:
        self.core, self.fields = core, np.asarray(fields)
        n = len(self.fields)
        self.target = core.target[self.fields].reshape(n, -1, 5).copy()
        s = core.world.state
        self.pos, self.angle, self.subgoal = [s.pos[self.fields]], [s.angle[self.fields]], []
        self._step = core.control_step
        core.control_step = self.control_step  # instance attribute: only this core is affected

    def control_step(self, live: np.ndarray, *args: object, **kwargs: object) -> tuple:
        out = self._step(live, *args, **kwargs)
        s = self.core.world.state  # replaced by every world step; fancy indexing copies
        self.pos.append(s.pos[self.fields])
        self.angle.append(s.angle[self.fields])
        self.subgoal.append(self.core.subgoal[self.fields].reshape(len(self.fields), -1, 5))
        return out

    def episode(self, j: int, length: int) -> dict[str, object]:
        """Recorded field ``j`` over its ``length`` control steps, M controlled robots (robots 0..M-1) of
        R: ``controlled`` M; target (M, 5); robots (T+1, R, 2) and angles (T+1, R) from the reset on;
        subgoal (T, M, 5), the sub-goals in force at each control step. Metres, radians, field frame."""
        return {
            "field": int(self.fields[j]),
            "controlled": self.target.shape[1],
            "target": self.target[j],
            "robots": np.stack([p[j] for p in self.pos[: length + 1]]),
            "angles": np.stack([a[j] for a in self.angle[: length + 1]]),
            "subgoal": np.stack([g[j] for g in self.subgoal[:length]]).reshape(length, -1, 5),
        }
