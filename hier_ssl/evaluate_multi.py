"""Seeded, batched evaluation of a shared manager on a multi-robot scenario (scripted planners act on it
through ``hier_ssl.manager.planners.make_planner``, which reads the scenario's neighbour observations).

One episode per field, all fields stepped together; every controlled robot is one sample of the per-robot
figures. With the same seed every manager meets the same starts, targets and obstacle motion.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

from hier_ssl.envs.multi import MultiRobotCore
from hier_ssl.envs.scenarios import ScenarioConfig
from hier_ssl.evaluate import Policy, optimal_ratio_median, play
from hier_ssl.manager import summarize


def evaluate_scenario(
    policy: Policy, config: ScenarioConfig, episodes: int, seed: int = 0, record: Sequence[int] = ()
) -> dict[str, object]:
    """Run ``episodes`` episodes of the scenario and summarise them per robot.

    Returns success_rate and collision_rate (shares of robots), field_success_rate (share of episodes in
    which every robot succeeded), episode_length (control steps until each robot left; max_steps for a
    timeout) and cpad as {median, q1, q3, min, max}, optimal_ratio_median (time to the target over the
    analytic rest-to-rest minimum, robots that succeeded), per-robot arrays (E, M) under "per_robot", and
    eval_wall_s. With ``record`` (episode indices), "trajectories" holds one dict per recorded episode
    (``hier_ssl.evaluate.Recorder.episode``), every control step of it.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    start = time.perf_counter()
    core = MultiRobotCore(config, episodes, autoreset=False)
    ends = play(core, policy, seed, record)
    length, success, collision, cpad = ends["length"], ends["success"], ends["collision"], ends["cpad"]
    distance = ends["distance"]
    summary: dict[str, object] = {
        "episodes": episodes,
        "robots": int(success.size),
        "success_rate": float(success.mean()),
        "collision_rate": float(collision.mean()),
        "field_success_rate": float(success.all(axis=1).mean()),
        "episode_length": summarize(length.ravel()),
        "cpad": summarize(cpad.ravel()),
        "optimal_ratio_median": optimal_ratio_median(length, success, distance, core.robot, config.dt),
        "per_robot": {"length": length, "success": success, "collision": collision, "cpad": cpad},
    }
    if record:
        summary["trajectories"] = ends["trajectories"]
    summary["eval_wall_s"] = time.perf_counter() - start
    return summary


__all__ = ["Policy", "evaluate_scenario"]
