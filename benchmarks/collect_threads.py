"""Measurement, not CI: what torch's own threads do to a training's collection on sharded fields.

A PPO-like collection loop: a config's fields (default ``obstacle/ppo_frame_skip``: 512 fields, frame skip 16)
as a torch vector view stepped on K cores (``threads``: shards in this process and K - 1 workers), a
256 x 256 MLP's forward pass between the steps, torch at T intra-op threads. Every (K, T) pair in turns,
``--rounds`` times, each round ``--steps`` vector steps from a fresh reset; prints the best and the median
round, wall clock. Run it on a machine with nothing else running: a lock-step step of K processes waits for
whichever one the scheduler parked.

Run: python benchmarks/collect_threads.py [--config obstacle/ppo_frame_skip] [--fields N] [--cores K]
     [--rounds 5] [--steps 32]
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from hier_ssl.config import validate_config
from hier_ssl.config.files import find_config, load_yaml
from hier_ssl.envs.shards import resolve_threads
from hier_ssl.envs.vector import TorchVectorEnv
from hier_ssl.policies.networks import mlp


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="obstacle/ppo_frame_skip")
    parser.add_argument("--fields", type=int, default=None, help="default: the config's num_envs")
    parser.add_argument("--cores", type=int, default=None, help="K and T up to this (default: every core)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=32)
    args = parser.parse_args()
    config = validate_config(load_yaml(find_config(args.config)))
    fields = args.fields or config.num_envs
    cores = range(1, (args.cores or resolve_threads("auto")) + 1)
    envs = {k: TorchVectorEnv(config.task_config, fields, threads=k) for k in cores}
    net = mlp(envs[1].num_obs, [256, 256], envs[1].num_actions)
    times: dict[tuple[int, int], list[float]] = {}
    try:
        for round_ in range(args.rounds):
            for k, env in envs.items():
                for t in cores:
                    torch.set_num_threads(t)
                    obs = env.reset(seed=round_)
                    began = time.perf_counter()
                    for _ in range(args.steps):
                        with torch.no_grad():
                            obs = env.step(net(obs).clamp(-1.0, 1.0))[0]
                    times.setdefault((k, t), []).append(time.perf_counter() - began)
    finally:
        for env in envs.values():
            env.close()
    print(f"{args.config}: {fields} fields, {args.steps} steps a round, {args.rounds} rounds")
    for (k, t), spent in sorted(times.items()):
        print(
            f"fields on {k} core(s), torch at {t} thread(s): best {min(spent):.3f} s, "
            f"median {statistics.median(spent):.3f} s"
        )


if __name__ == "__main__":
    main()
