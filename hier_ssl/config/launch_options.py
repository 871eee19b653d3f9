"""Where and how ``hier_ssl.runs.launch`` runs its jobs, and the command-line flags that say so.

Kept apart from ``hier_ssl.runs.launch`` so that building the command-line parser imports no torch.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Any

from hier_ssl.config.schema import TrainConfig


@dataclass(frozen=True)
class LaunchOptions:
    """Where and how runs execute.

    ``ray``: None runs locally; "local" starts a Ray instance on this machine; "auto" or an address joins a
    running cluster. ``jobs``: runs at once (local processes, or Ray's concurrent trials; None: 1 locally,
    as many as Ray's resources allow on Ray). ``cpus_per_run``: torch threads of each run and the CPUs a
    trial reserves. ``gpus_per_run`` > 0 trains on ``cuda``. ``asha``: stop weak Ray trials early (success
    rate of the selection evaluations).
    """

    ray: str | None = None
    jobs: int | None = None
    cpus_per_run: int = 1
    gpus_per_run: float = 0
    asha: bool = False

    def __post_init__(self) -> None:
        if self.jobs is not None and self.jobs < 1:
            raise ValueError(f"--jobs must be >= 1, got {self.jobs}")
        if self.cpus_per_run < 1:
            raise ValueError(f"--cpus-per-run must be >= 1, got {self.cpus_per_run}")
        if self.gpus_per_run < 0:
            raise ValueError(f"--gpus-per-run must be >= 0, got {self.gpus_per_run}")
        if self.asha and self.ray is None:
            raise ValueError("--asha stops Ray Tune trials early; it needs --ray")

    def apply(self, config: TrainConfig) -> TrainConfig:
        """``config`` with the threads and device these resources give a run."""
        update: dict[str, Any] = {"threads": self.cpus_per_run}
        if self.gpus_per_run > 0:
            update["device"] = "cuda"
        return config.model_copy(update=update)

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> LaunchOptions:
        """The options of the flags ``add_launch_flags`` registered (``asha`` where the command has it)."""
        return cls(args.ray, args.jobs, args.cpus_per_run, args.gpus_per_run, getattr(args, "asha", False))


def add_launch_flags(parser: argparse.ArgumentParser) -> None:
    """``--ray [ADDRESS]``, ``--jobs``, ``--cpus-per-run``, ``--gpus-per-run`` on ``parser``."""
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help="train as Ray Tune trials: alone, on a Ray started here; 'auto' or an address: on a cluster",
    )
    parser.add_argument("--jobs", type=int, default=None, help="runs at once (default: 1; Ray: all that fit)")
    parser.add_argument("--cpus-per-run", type=int, default=1, help="torch threads, Ray CPUs (default: 1)")
    parser.add_argument(
        "--gpus-per-run", type=float, default=0, help="Ray GPUs per run; > 0 trains on cuda (default: 0)"
    )
