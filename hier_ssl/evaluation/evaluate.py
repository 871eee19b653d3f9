"""Seeded, batched evaluation of a manager: one episode per field, all fields stepped together, the
figures of the paper's tables per controlled robot.

With the same seed every manager meets the same starts, targets and obstacle motion. A paper task has one
robot per field (the figures are per episode); a multi-robot scenario's robots are each one sample.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from hier_ssl.config import TaskConfig
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.play import Policy, play
from hier_ssl.game import KINDS
from hier_ssl.manager import min_time_to_pose, summarize
from hier_ssl.world.physics import RobotSpec


def evaluate(
    policy: Policy,
    config: TaskConfig,
    episodes: int,
    seed: int = 0,
    record: Sequence[int] = (),
    worker: Any = None,
    progress: str | None = None,
) -> dict[str, object]:
    """Run ``episodes`` episodes of the task or scenario ``config`` and summarise them per robot, driven by
    ``worker`` (a spec, or an object, class or factory of the worker protocol) where given, else by the
    worker ``config`` names.

    The policy sees only the robots still in their episode (its input has fewer rows as they leave), so a
    row-wise policy costs nothing for finished ones.

    Returns success_rate and collision_rate (shares of robots), field_success_rate (share of episodes in
    which every robot succeeded), episode_length (control steps until each robot left; max_steps for a
    timeout), cpad and cpad_public (the paper's public code's variant, ``play``) as {median, q1, q3, min,
    max}, optimal_ratio_median (time to the target over the analytic rest-to-rest minimum under the robot's
    speed and acceleration limits, robots that succeeded), time_to_target_s_median (robots that
    succeeded, seconds), robots (episodes x M), the per-robot arrays (E, M) under "per_robot" (length,
    success, collision, cpad, cpad_public, distance; foul in a game scenario), in a game scenario
    foul_rate (share of robots that left for a foul; collision_rate then counts contacts alone) and fouls
    (every foul committed, by kind of ``hier_ssl.game.KINDS``), and
    eval_wall_s. With ``progress`` (its label) a progress bar shows on stderr (``play``). With ``record``
    (episode indices), "trajectories" holds one dict per recorded episode
    (``hier_ssl.envs.play.Recorder.episode``), every control step of it.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    start = time.perf_counter()
    core = HierarchicalCore(config, episodes, autoreset=False, worker=worker)
    ends = play(core, policy, seed, record, progress)
    length, success, collision, cpad = ends["length"], ends["success"], ends["collision"], ends["cpad"]
    distance, dt = ends["distance"], core.config.dt
    solved, nan = bool(success.any()), float("nan")
    summary: dict[str, object] = {
        "episodes": episodes,
        "robots": int(success.size),
        "success_rate": float(success.mean()),
        "collision_rate": float(collision.mean()),
        "field_success_rate": float(success.all(axis=1).mean()),
        # Episodes that began inside the collision distance (they end as collisions at once).
        "start_contact_rate": float((ends["start_gap"] < core.config.collision_distance).mean()),
        "episode_length": summarize(length.ravel()),
        "cpad": summarize(cpad.ravel()),
        "cpad_public": summarize(ends["cpad_public"].ravel()),
        "optimal_ratio_median": optimal_ratio_median(length, success, distance, core.robot, dt),
        "time_to_target_s_median": float(np.median(length[success]) * dt) if solved else nan,
        "per_robot": {
            "length": length,
            "success": success,
            "collision": collision,
            "cpad": cpad,
            "cpad_public": ends["cpad_public"],
            "distance": distance,
        },
    }
    if "foul" in ends:  # a game scenario: robots that left for a foul, and every foul by kind
        summary["foul_rate"] = float(ends["foul"].mean())
        summary["fouls"] = {kind: int(ends[f"foul_{kind}"].sum()) for kind in KINDS}
        summary["per_robot"]["foul"] = ends["foul"] > 0
    if record:
        summary["trajectories"] = ends["trajectories"]
    summary["eval_wall_s"] = time.perf_counter() - start
    return summary


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


__all__ = ["Policy", "evaluate", "optimal_ratio_median"]
