"""Measurement, not CI: the scripted planners' decision time per robot at batch 1, on states they meet.

Plays ``sampling`` on a task's or scenario's seeded episodes at frame skip 1 and keeps every live robot's
manager observation; then times each planner on single rows drawn from them (after 20 warm-up calls):
one robot, one decision, one call, as a robot that replans every control step would. ``trajectory`` is
called without rows (no memory), which changes no work: its last winner is one candidate more.
Prints the median and 90th percentile per call.

Run: python benchmarks/planner_latency.py [--task obstacle | --scenario crowd] [--episodes 20] [--calls 300]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from hier_ssl.envs import env_config, scenario_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.planners import make_planner
from hier_ssl.envs.play import play
from hier_ssl.manager.planners import PLANNERS


def met_states(config, episodes: int, seed: int) -> np.ndarray:
    """Manager observations (S, O) of every live robot at every control step of ``sampling``'s episodes."""
    planner, seen = make_planner("sampling", config), []

    def recording(obs: np.ndarray) -> np.ndarray:
        seen.append(obs.copy())
        return planner(obs)

    play(HierarchicalCore(config, episodes, autoreset=False), recording, seed)
    return np.concatenate(seen)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--task", default=None)
    where.add_argument("--scenario", default=None)
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--calls", type=int, default=300)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    if args.scenario:
        config = scenario_config(args.scenario, frame_skip=1)
    else:
        config = env_config(task=args.task or "obstacle", frame_skip=1)
    states = met_states(config, args.episodes, args.seed)
    picks = np.random.default_rng(0).integers(0, len(states), args.calls + 20)
    print(f"{config.scenario_name}: {len(states)} states met, {args.calls} timed at batch 1, frame skip 1")
    for name in PLANNERS:
        planner = make_planner(name, config)
        times = []
        for i, row in enumerate(picks):
            start = time.perf_counter()
            planner(states[row : row + 1])
            if i >= 20:
                times.append(time.perf_counter() - start)
        median, p90 = np.median(times) * 1e3, np.percentile(times, 90) * 1e3
        print(f"  {name:10s} median {median:6.2f} ms, p90 {p90:6.2f} ms per decision")


if __name__ == "__main__":
    main()
