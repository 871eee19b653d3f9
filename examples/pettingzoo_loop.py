"""The Obstacle task through PettingZoo's ParallelEnv API, with the `sampling` planner as the manager.

    python examples/pettingzoo_loop.py --episodes 5

Checks the environment with PettingZoo's own API test, then plays seeded episodes and prints each one's
outcome from ``infos["manager_0"]["task"]``.
"""

from __future__ import annotations

import argparse

from pettingzoo.test import parallel_api_test

import hier_ssl
from hier_ssl.envs import env_config
from hier_ssl.envs.planners import make_planner


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=5)
    args = parser.parse_args()

    config = env_config(task="obstacle", frame_skip=16)  # one decision every 16 control steps (0.4 s)
    parallel_api_test(hier_ssl.parallel_env(config), num_cycles=20)

    env = hier_ssl.parallel_env(config)
    planner = make_planner("sampling", config)  # numpy: observations (N, O) -> actions (N, A)
    for episode in range(args.episodes):
        obs, infos = env.reset(seed=episode)
        while env.agents:
            actions = {agent: planner(obs[agent][None])[0] for agent in env.agents}
            obs, rewards, terminations, truncations, infos = env.step(actions)
        task = infos["manager_0"]["task"]
        print(
            f"episode {episode}: success {task['success']:.0f} collision {task['collision']:.0f} "
            f"length {task['length']} control steps, {task['decisions']} decisions"
        )


if __name__ == "__main__":
    main()
