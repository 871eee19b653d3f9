"""Micro benchmark: milliseconds per SAC update (batch 256, obs 13, act 4, CAPS on, 2 x 256 networks).

Prints the best and the median of several timed blocks: on a shared machine the best block is the
closest to the cost of the update itself. ``--set`` changes any ``SACConfig`` key, e.g. the public
code's CAPS and actor schedule: ``--set caps_actions=sampled --set actor_schedule=delayed``.

Run: python benchmarks/sac_update.py [--updates N] [--repeats R] [--threads T] [--no-caps] [--set K=V ...]
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch
import yaml

from hier_ssl.policies import SAC, SACConfig

NUM_OBS, NUM_ACTIONS, FILLED = 13, 4, 50_000  # the Proposed task's manager; a replay of 50,000 rows


def sac_settings(parser: argparse.ArgumentParser, items: list[str], **defaults: object) -> SACConfig:
    """``defaults`` updated by ``--set KEY=VALUE`` items (values parsed as YAML), as a SACConfig."""
    settings = dict(defaults)
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            parser.error(f"--set {item!r}: expected KEY=VALUE")
        settings[key] = yaml.safe_load(value)
    return SACConfig(**settings)


def filled_sac(config: SACConfig, device: torch.device | str = "cpu") -> SAC:
    """A SAC on ``device`` whose replay holds FILLED random transitions."""
    sac = SAC(NUM_OBS, NUM_ACTIONS, config.model_copy(update={"buffer_size": FILLED}), device=device)
    gen = torch.Generator().manual_seed(0)
    rows = (
        torch.rand(FILLED, NUM_OBS, generator=gen) * 2 - 1,
        torch.rand(FILLED, NUM_ACTIONS, generator=gen) * 2 - 1,
        -torch.rand(FILLED, generator=gen),
        torch.rand(FILLED, NUM_OBS, generator=gen) * 2 - 1,
        torch.rand(FILLED, generator=gen) < 0.01,
    )
    sac.process_env_step(*(x.to(device) for x in rows))
    return sac


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=200, help="updates per timed block")
    parser.add_argument("--repeats", type=int, default=5, help="timed blocks")
    parser.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    parser.add_argument("--no-caps", action="store_true", help="plain SAC with learned alpha")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a SACConfig key (YAML value)"
    )
    args = parser.parse_args()
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    sac = filled_sac(sac_settings(parser, args.set, caps=not args.no_caps))

    for _ in range(args.updates // 2):  # warm-up: allocator, optimiser state
        sac.update()
    block_ms = []
    actor_adam = sac.actor_optimizer.state[next(sac.actor.parameters())]
    actor_steps_before = int(actor_adam["step"])
    for _ in range(args.repeats):
        start = time.perf_counter()
        for _ in range(args.updates):
            sac.update()
        block_ms.append(1e3 * (time.perf_counter() - start) / args.updates)
    actor_steps = int(actor_adam["step"]) - actor_steps_before
    cfg = sac.config
    print(
        f"{min(block_ms):.2f} ms per update best, {statistics.median(block_ms):.2f} median "
        f"(batch {cfg.batch_size}, obs {NUM_OBS}, act {NUM_ACTIONS}, caps={cfg.caps} on {cfg.caps_actions} "
        f"actions, actor_schedule {cfg.actor_schedule}, policy_frequency {cfg.policy_frequency}: "
        f"{actor_steps / (args.repeats * args.updates):.2f} actor steps per update, "
        f"{torch.get_num_threads()} threads, torch {torch.__version__})"
    )


if __name__ == "__main__":
    main()
