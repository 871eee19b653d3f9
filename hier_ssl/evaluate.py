"""Seeded, batched evaluation of a manager: one episode per field, all fields stepped together."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from hier_ssl.config import EnvConfig
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.manager import min_time_to_pose, summarize

Policy = Callable[[np.ndarray], np.ndarray]
"""Manager observations (N, obs_dim) -> actions (N, act_dim) in [-1, 1]."""


def evaluate(policy: Policy, config: EnvConfig, episodes: int, seed: int = 0) -> dict[str, object]:
    """Run ``episodes`` episodes (one per field, seeded: the same starts, targets and obstacle motion for
    every policy given the same seed) and summarise them.

    Returns success_rate, collision_rate, episode_length and cpad as {median, q1, q3, min, max},
    optimal_ratio_median (episode time over the analytic rest-to-rest minimum time to the target under
    the robot's speed and acceleration limits, successful episodes only), the raw per-episode arrays
    under "per_episode", and eval_wall_s.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    start = time.perf_counter()
    core = HierarchicalCore(config, episodes, autoreset=False)
    obs = core.reset(seed)
    distance = np.linalg.norm(core.state.pos[:, 0] - core.target[:, :2], axis=1)
    length = np.zeros(episodes, dtype=np.int64)
    success, collision, cpad = np.zeros(episodes, bool), np.zeros(episodes, bool), np.zeros(episodes)
    while not core.done.all():
        result = core.step(policy(obs))
        episode = result.info["episode"]
        idx = episode["field"]
        length[idx] = episode["length"]
        success[idx] = episode["success"] > 0
        collision[idx] = episode["collision"] > 0
        cpad[idx] = episode["cpad"]
        obs = result.obs
    robot = core.robot
    bound = min_time_to_pose(distance, robot.max_speed, robot.max_accel)
    ratio = length * config.dt / np.maximum(bound, 1e-9)
    return {
        "episodes": episodes,
        "success_rate": float(success.mean()),
        "collision_rate": float(collision.mean()),
        "episode_length": summarize(length),
        "cpad": summarize(cpad),
        "optimal_ratio_median": float(np.median(ratio[success])) if success.any() else float("nan"),
        "per_episode": {
            "length": length,
            "success": success,
            "collision": collision,
            "cpad": cpad,
            "distance": distance,
        },
        "eval_wall_s": time.perf_counter() - start,
    }
