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


# -- entry point ------------------------------------------------------------------------------------------

COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (_add_bench, _add_demo)


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
    except Exception as err:  # noqa: BLE001 - the contract is one line, not a traceback
        print(f"hier-ssl {args.command}: error: {err}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
