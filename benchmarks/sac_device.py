"""Benchmark: the SAC learner on the CPU against a GPU, the world staying on the CPU.

For each learner device (cpu, and cuda when torch sees one; a device that is not there is skipped):
- updates/s of ``SAC.update`` alone (batch 256, 2 x 256 networks, obs 13, act 4, replay of 50,000 rows);
- vector steps/s of ``SACRunner`` on the batched world (Proposed task, frame skip 16, ``--num-envs``
  fields): "collect" is the warm-up (random actions, one copy each way per vector step, no update),
  "train" acts with the policy and runs one update per vector step.
Times are the runner's own ``train_time_s`` (collection and updates, no logging or checkpoints).

Run: python benchmarks/sac_device.py [--devices cpu cuda] [--num-envs 16] [--updates 300] [--steps 200]
                                     [--threads 1] [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import tempfile
import time

import torch
from sac_update import filled_sac, sac_settings  # benchmarks/ is on the path of a script run from it

import hier_ssl
from hier_ssl.policies import SACConfig, SACRunner


def updates_per_s(config: SACConfig, device: torch.device, updates: int) -> float:
    """Updates/s of one SAC on ``device`` over a replay of random transitions (after a warm-up)."""
    sac = filled_sac(config, device)
    for _ in range(max(1, updates // 4)):  # allocator, optimiser state, kernel caches
        sac.update()
    start = time.perf_counter()
    for _ in range(updates):
        sac.update()  # returns host floats: every update ends synchronised
    return updates / (time.perf_counter() - start)


def steps_per_s(config: SACConfig, device: torch.device, num_envs: int, steps: int, train: bool) -> float:
    """Vector steps/s of ``SACRunner.learn`` on the Proposed task; ``train`` acts and updates."""
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=num_envs)
    warm_up = max(1, steps // 4)
    # Training: the warm-up fills the replay with random actions, then every step acts and updates.
    # Collecting: the warm-up never ends.
    learning_starts = warm_up * num_envs if train else 10**12
    config = config.model_copy(update={"learning_starts": learning_starts})
    with tempfile.TemporaryDirectory() as run_dir:
        runner = SACRunner(
            env, config, run_dir, device=device, log_interval=10**9, save_interval=10**9, progress=False
        )
        runner.learn(warm_up)
        before = runner.train_time_s
        runner.learn(warm_up + steps)
        runner.close()
    return steps / (runner.train_time_s - before)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", nargs="+", default=["cpu", "cuda"])
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--updates", type=int, default=300, help="timed updates per device")
    parser.add_argument("--steps", type=int, default=200, help="timed vector steps per device and mode")
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a SACConfig key (YAML value)"
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config = sac_settings(parser, args.set, caps=True)

    print(f"SAC {config.model_dump(include={'caps', 'caps_actions', 'actor_schedule', 'batch_size'})}")
    print(f"{args.num_envs} envs, {torch.get_num_threads()} CPU threads, torch {torch.__version__}")
    print("| learner | updates/s | ms/update | collect vector steps/s | train vector steps/s |")
    print("|---|---|---|---|---|")
    for name in args.devices:
        device = torch.device(name)
        if device.type == "cuda" and not torch.cuda.is_available():
            print(f"| {name} | skipped: torch sees no CUDA device | | | |")
            continue
        label = torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu"
        ups = updates_per_s(config, device, args.updates)
        collect = steps_per_s(config, device, args.num_envs, args.steps, train=False)
        train = steps_per_s(config, device, args.num_envs, args.steps, train=True)
        print(f"| {label} | {ups:.0f} | {1e3 / ups:.2f} | {collect:.0f} | {train:.1f} |")


if __name__ == "__main__":
    main()
