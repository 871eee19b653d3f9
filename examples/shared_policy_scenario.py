"""A multi-robot scenario in PettingZoo, every robot acting through one shared policy in one batch.

    python examples/shared_policy_scenario.py --manager sampling --robots 4 --episodes 3
    python examples/shared_policy_scenario.py --manager runs/<a crossing run>

``crossing``: robots on a circle swap to the opposite points, all through the centre. The manager is a
planner's name or the directory of a run trained on the scenario (``hier-ssl train scenarios/crossing``);
``load_manager`` gives it as one numpy policy, observations (B, O) -> actions (B, A), which acts for every
live robot at once. ``env.state()`` is the whole field, as a centralised critic would see it.
"""

from __future__ import annotations

import argparse

import numpy as np

import hier_ssl
from hier_ssl.envs import scenario_config
from hier_ssl.evaluation.compare import load_manager


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--manager", default="sampling", help="direct, sampling, or a run directory")
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--episodes", type=int, default=3)
    args = parser.parse_args()

    config = scenario_config("crossing", num_agents=args.robots)
    env = hier_ssl.parallel_env(config)
    policy = load_manager(args.manager, config)
    for episode in range(args.episodes):
        obs, infos = env.reset(seed=episode)
        outcome, team_return = {}, 0.0
        while env.agents:
            agents = list(env.agents)
            batch = np.stack([obs[agent] for agent in agents])  # (live robots, O)
            actions = dict(zip(agents, policy(batch), strict=True))  # one call for the whole team
            critic_input = env.state()  # (D,): every robot, target and held sub-goal
            obs, rewards, terminations, truncations, infos = env.step(actions)
            team_return += sum(rewards.values())
            for agent in agents:
                if "task" in infos[agent]:
                    task = infos[agent]["task"]
                    outcome[agent] = (
                        "success" if task["success"] else "collision" if task["collision"] else "timeout"
                    )
        print(
            f"episode {episode}: state {critic_input.shape}, team return {team_return:.0f}, "
            + ", ".join(f"{agent} {outcome[agent]}" for agent in sorted(outcome))
        )


if __name__ == "__main__":
    main()
