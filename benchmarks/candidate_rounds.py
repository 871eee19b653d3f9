"""Measurement, not CI: how long a candidate manager's DAgger rounds and PPO iterations take.

Trains ``--config`` (default the crowd scorer) for ``--rounds`` DAgger rounds of ``--episodes`` episodes
and ``--iterations`` PPO iterations into a temporary folder, with the run's selection scoring done by
nothing, and prints each round's and iteration's training time (rollouts and updates, ``train_time_s``).
It drives ``CandidateLearner`` through the learner protocol (``hier_ssl.policies.learner``): run it with
PYTHONPATH at each checkout to compare two versions that have it.

Run: PYTHONPATH=CHECKOUT python benchmarks/candidate_rounds.py [--rounds 2] [--episodes 100] [--iterations 3]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import torch

from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.policies.candidates import CandidateLearner
from hier_ssl.policies.learner import Checkpoint


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="scenarios/crowd_scorer")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    data = load_yaml(config_dir() / f"{args.config}.yaml")
    section = data["candidates"]
    section |= {"rounds": args.rounds, "episodes": args.episodes}
    section["ppo"] = {**section.get("ppo", {}), "iterations": args.iterations, "eval_interval": 1}
    config = parse_config(data)
    times: list[float] = []

    def timed(checkpoint: Checkpoint) -> None:
        times.append(checkpoint.train_time_s)

    with tempfile.TemporaryDirectory() as run_dir:
        CandidateLearner(config, Path(run_dir), progress=False).learn(args.rounds + args.iterations, timed)
    each = np.diff([0.0, *times])
    rounds, iterations = each[: args.rounds], each[args.rounds :]
    ppo = config.candidates.ppo
    print(f"{args.config}: {args.threads} thread(s); DAgger rounds of {args.episodes} episodes, "
          f"PPO iterations of {ppo.fields} fields x {ppo.horizon} decisions")  # fmt: skip
    print("  DAgger round s: " + ", ".join(f"{t:.1f}" for t in rounds))
    print("  PPO iteration s: " + ", ".join(f"{t:.1f}" for t in iterations))


if __name__ == "__main__":
    main()
