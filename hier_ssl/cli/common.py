"""What every subcommand module shares: the one-line-error parser and the argument types."""

from __future__ import annotations

import argparse

from hier_ssl.worker import check_worker_spec


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line instead of usage + message
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


WORKER_HELP = "paper|bangbang|RUN_DIR|package.module:Name, optionally perturbed: paper+latency=2+noise=0.2"


def worker_spec(text: str) -> str:
    """A ``make_worker`` spec whose name part is a known worker, an importable class or factory, or an
    existing directory."""

    try:
        return check_worker_spec(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
