"""Micro benchmark: milliseconds per SAC update (batch 256, obs 13, act 4, CAPS on, 2 x 256 networks).

Prints the best and the median of several timed blocks: on a shared machine the best block is the
closest to the cost of the update itself.

Run: python benchmarks/sac_update.py [--updates N] [--repeats R] [--threads T] [--no-caps]
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from hier_ssl.policies import SAC, SACConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=200, help="updates per timed block")
    parser.add_argument("--repeats", type=int, default=5, help="timed blocks")
    parser.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    parser.add_argument("--no-caps", action="store_true", help="plain SAC with learned alpha")
    args = parser.parse_args()
    if args.threads is not None:
        torch.set_num_threads(args.threads)

    num_obs, num_actions, filled = 13, 4, 50_000
    sac = SAC(num_obs, num_actions, SACConfig(caps=not args.no_caps, buffer_size=filled), seed=0)
    gen = torch.Generator().manual_seed(0)
    sac.process_env_step(
        torch.rand(filled, num_obs, generator=gen) * 2 - 1,
        torch.rand(filled, num_actions, generator=gen) * 2 - 1,
        -torch.rand(filled, generator=gen),
        torch.rand(filled, num_obs, generator=gen) * 2 - 1,
        torch.rand(filled, generator=gen) < 0.01,
    )

    for _ in range(args.updates // 2):  # warm-up: allocator, optimiser state
        sac.update()
    block_ms = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        for _ in range(args.updates):
            sac.update()
        block_ms.append(1e3 * (time.perf_counter() - start) / args.updates)
    print(
        f"{min(block_ms):.2f} ms per update best, {statistics.median(block_ms):.2f} median "
        f"(batch {sac.config.batch_size}, obs {num_obs}, act {num_actions}, caps={sac.config.caps}, "
        f"policy_frequency {sac.config.policy_frequency}, {torch.get_num_threads()} threads, "
        f"torch {torch.__version__})"
    )


if __name__ == "__main__":
    main()
