"""The ``hier-ssl`` command: one small function per subcommand, registered in ``COMMANDS``.

Heavy imports happen inside the subcommands, so ``hier-ssl --help`` stays fast. Errors end the command
with one line on stderr and a non-zero exit status, not a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line instead of usage + message
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


# -- bench ------------------------------------------------------------------------------------------------


def _add_bench(subparsers: argparse._SubParsersAction) -> None:
    bench = subparsers.add_parser("bench", help="throughput benchmarks, pinned to one core")
    targets = bench.add_subparsers(dest="target", required=True, metavar="TARGET")
    world = targets.add_parser(
        "world",
        help="field-steps/s of the world with the paper worker, 1 robot + 1 random-walk obstacle per field",
    )
    world.add_argument("--json", action="store_true", help="one JSON object per line")
    world.add_argument(
        "--steps",
        type=_positive_int,
        default=None,
        help="control steps per timed run (default: 4000 / sqrt(N), at least 20)",
    )
    world.set_defaults(func=_bench_world)


def _bench_world(args: argparse.Namespace) -> int:
    from hier_ssl.bench import WORLD_SIZES, bench_world, default_steps, pin_to_one_core

    cpu = pin_to_one_core()
    if not args.json:
        where = f"CPU {cpu}" if cpu is not None else "one thread (affinity not settable here)"
        print(f"world bench on {where}: best of 5 runs per N, paper worker + random-walk obstacle")
    for n in WORLD_SIZES:
        result = bench_world(n, args.steps)
        if args.json:
            print(json.dumps(result.as_dict()), flush=True)
        else:
            steps = args.steps or default_steps(n)
            print(
                f"  N = {n:5d} fields x {result.robots_per_field} robots: "
                f"{result.steps_per_s:12,.0f} field-steps/s  ({steps} steps per run)",
                flush=True,
            )
    return 0


# -- demo -------------------------------------------------------------------------------------------------


def _add_demo(subparsers: argparse._SubParsersAction) -> None:
    from hier_ssl.worker import WORKERS

    demo = subparsers.add_parser("demo", help="drive a robot to random targets past an obstacle, write a PNG")
    demo.add_argument("--out", default="runs/demo.png", help="PNG to write (default: %(default)s)")
    demo.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    demo.add_argument(
        "--worker", choices=WORKERS, default="paper", help="scripted worker (default: %(default)s)"
    )
    demo.add_argument(
        "--targets", type=_positive_int, default=4, help="targets to visit (default: %(default)s)"
    )
    demo.set_defaults(func=_demo)


def _demo(args: argparse.Namespace) -> int:
    from hier_ssl.demo import run_demo

    result = run_demo(args.out, seed=args.seed, worker=args.worker, targets=args.targets)
    print(
        f"wrote {result.path} ({args.worker} worker: {result.reached}/{result.targets} targets reached in "
        f"{result.steps} steps, {result.contact_steps} steps in contact with the obstacle)"
    )
    return 0


# -- train ------------------------------------------------------------------------------------------------

DEFAULT_CONFIG = "configs/proposed/fscaps.yaml"


def _add_train(subparsers: argparse._SubParsersAction) -> None:
    train = subparsers.add_parser("train", help="train a manager, then evaluate it and write eval.json")
    train.add_argument("config", nargs="?", default=DEFAULT_CONFIG, help="YAML config (default: %(default)s)")
    train.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a config key"
    )
    train.add_argument("--seed", type=int, default=None, help="random seed (overrides the config's)")
    train.add_argument("--out", default=None, help="run directory (default: runs/NAME-sSEED-TIME)")
    train.add_argument("--resume", default=None, metavar="RUN_DIR", help="continue a killed run")
    train.add_argument("--no-progress", action="store_true", help="no progress bar")
    train.set_defaults(func=_train)


def _train(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from hier_ssl.config import apply_overrides, load_yaml, parse_config
    from hier_ssl.train import print_summary, resume_config, train

    # Everything is validated before the run directory is created, so a bad config writes nothing.
    if args.resume:
        run_dir = Path(args.resume)
        config = resume_config(run_dir)
    else:
        data = apply_overrides(load_yaml(args.config), args.set)
        if args.seed is not None:
            data["seed"] = args.seed
        config = parse_config(data)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        run_dir = Path(args.out) if args.out else Path("runs") / f"{config.name}-s{config.seed}-{stamp}"
    print(f"run directory: {run_dir}", flush=True)
    summary = train(config, run_dir, resume=bool(args.resume), progress=not args.no_progress)
    print_summary(summary)
    print(f"wrote {run_dir / 'eval.json'}")
    return 0


# -- entry point ------------------------------------------------------------------------------------------

COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (_add_bench, _add_demo, _add_train)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="hier-ssl", description="Hierarchical RL path planning for RoboCup SSL.")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``hier-ssl`` with ``argv`` (default: the process arguments); returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("hier-ssl: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError) as err:  # bad input: one line naming it; bugs keep their traceback
        print(f"hier-ssl {args.command}: error: {err}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
