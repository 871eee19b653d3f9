"""The ``hier-ssl`` command: one small function per subcommand, registered in ``COMMANDS``; the
subcommands live in ``look`` (bench, demo, render, configs), ``runs`` (train, reproduce, sweep),
``evaluation`` (eval, export) and ``deploy`` (deploy, field).

Heavy imports happen inside the subcommands, so ``hier-ssl --help`` stays fast. Errors end the command
with one line on stderr and a non-zero exit status, not a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence

from hier_ssl import __version__
from hier_ssl.cli import deploy, evaluation, look, runs
from hier_ssl.cli.common import Parser

COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    look.add_bench,
    look.add_configs,
    look.add_demo,
    look.add_render,
    runs.add_train,
    evaluation.add_export,
    evaluation.add_eval,
    runs.add_reproduce,
    runs.add_sweep,
    deploy.add_deploy,
    deploy.add_field,
)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="hier-ssl", description="Hierarchical RL path planning for RoboCup SSL.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``hier-ssl`` with ``argv`` (default: the process arguments); returns the exit status."""
    # A worker named package.module:Name may live in the current directory, which a console script does
    # not search (``python -m`` does). Appended, so a local file never shadows an installed module.
    if os.getcwd() not in sys.path:
        sys.path.append(os.getcwd())
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("hier-ssl: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError) as err:  # bad input: one line naming it; bugs keep their traceback
        print(f"hier-ssl {args.command}: error: {err}", file=sys.stderr)
        return 1


__all__ = ["COMMANDS", "build_parser", "main"]
