"""Seeded, batched evaluation of a shared manager on a multi-robot scenario, and the scripted planners as
managers of it.

One episode per field, all fields stepped together; every controlled robot is one sample of the per-robot
figures. With the same seed every manager meets the same starts, targets and obstacle motion.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from hier_ssl.envs.multi import MultiRobotCore
from hier_ssl.envs.scenarios import ScenarioConfig
from hier_ssl.manager import MANAGER_OBS_BASE_DIM, summarize
from hier_ssl.manager.neighbours import as_obstacle_observation

Policy = Callable[[np.ndarray], np.ndarray]
"""Manager observations (B, obs_dim) -> actions (B, act_dim) in [-1, 1], one row per live robot."""


def planner_policy(name: str, config: ScenarioConfig, **options: object) -> Policy:
    """The scripted manager ``name`` of ``hier_ssl.manager.planners`` ("direct": the sub-goal is the
    target; "sampling") acting on neighbour observations: the planners read the paper's layout, so the
    neighbours are handed to them as obstacles (``as_obstacle_observation``)."""
    from hier_ssl.manager.planners import make_planner

    planner = make_planner(name, config, **options)
    if name == "direct":
        return lambda obs: planner(obs[:, :MANAGER_OBS_BASE_DIM])
    return lambda obs: planner(as_obstacle_observation(obs))


def evaluate_scenario(
    policy: Policy, config: ScenarioConfig, episodes: int, seed: int = 0
) -> dict[str, object]:
    """Run ``episodes`` episodes of the scenario and summarise them per robot.

    Returns success_rate and collision_rate (shares of robots), field_success_rate (share of episodes in
    which every robot succeeded), episode_length (control steps until each robot left; max_steps for a
    timeout) and cpad as {median, q1, q3, min, max}, per-robot arrays (E, M) under "per_robot", and
    eval_wall_s.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    start = time.perf_counter()
    core = MultiRobotCore(config, episodes, autoreset=False)
    obs = core.reset(seed)
    shape = (episodes, config.num_agents)
    length, cpad = np.zeros(shape, dtype=np.int64), np.zeros(shape)
    success, collision = np.zeros(shape, dtype=bool), np.zeros(shape, dtype=bool)
    action = np.zeros(shape + (core.act_dim,))
    while not core.done.all():
        live = core.active
        action[live] = policy(obs[live])
        result = core.step(action)
        episode = result.info["episode"]
        at = (episode["field"], episode["agent"])
        length[at], cpad[at] = episode["length"], episode["cpad"]
        success[at], collision[at] = episode["success"] > 0, episode["collision"] > 0
        obs = result.obs
    return {
        "episodes": episodes,
        "robots": int(success.size),
        "success_rate": float(success.mean()),
        "collision_rate": float(collision.mean()),
        "field_success_rate": float(success.all(axis=1).mean()),
        "episode_length": summarize(length.ravel()),
        "cpad": summarize(cpad.ravel()),
        "per_robot": {"length": length, "success": success, "collision": collision, "cpad": cpad},
        "eval_wall_s": time.perf_counter() - start,
    }


__all__ = ["Policy", "evaluate_scenario", "planner_policy"]
