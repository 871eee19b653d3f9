"""goToPoint workers: (robot state, sub-goal) -> velocity command, batched; chosen by a spec string.

A worker is ``__call__(state (N, R), subgoal (N, R, 5)) -> (N, R, 3)`` robot-frame commands in m/s and
rad/s, plus ``reset(fields)``. ``make_worker`` takes the spec a config's ``env.worker`` or the command
line's ``--worker`` gives: ``paper``, ``bangbang``, or the run directory of a trained worker, each
optionally followed by ``+key=value`` perturbations (``paper+latency=2+noise=0.2``; the keys are listed
in ``hier_ssl.worker.perturbed``). The learned worker (and torch) is imported only when one is named.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np

from hier_ssl.worker.perturbed import Perturbation, PerturbedWorker, parse_worker_spec
from hier_ssl.worker.scripted import BangBangGoToPoint, PaperGoToPoint
from hier_ssl.world.physics import RobotSpec, RobotState

WORKERS = ("paper", "bangbang")


class Worker(Protocol):
    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray: ...

    def reset(self, fields: np.ndarray) -> None: ...


def _base_worker(name: str, robot: RobotSpec, dt: float) -> Worker:
    if name == "paper":
        return PaperGoToPoint(dt=dt)
    if name == "bangbang":
        return BangBangGoToPoint(
            dt=dt,
            max_speed=robot.max_speed,
            max_accel=robot.max_accel,
            max_ang_speed=robot.max_ang_speed,
            max_ang_accel=robot.max_ang_accel,
        )
    if Path(name).is_dir():
        from hier_ssl.worker.learned import load_learned_worker

        return load_learned_worker(name, robot, dt)
    raise ValueError(f"unknown worker {name!r}; expected one of {list(WORKERS)} or a worker run directory")


def check_worker_spec(spec: str) -> str:
    """``spec`` if its name part is a scripted worker or an existing directory; a ValueError naming it."""
    base, _ = parse_worker_spec(spec)
    if base not in WORKERS and not Path(base).is_dir():
        raise ValueError(f"unknown worker {base!r}; expected {'|'.join(WORKERS)} or a worker run directory")
    return spec


def make_worker(spec: str, robot: RobotSpec, dt: float) -> Worker:
    """The worker ``spec`` names (module docstring), tuned to the world's robot and control period.

    A ValueError names the spec, or the run directory when it holds no usable worker checkpoint.
    """
    name, perturbation = parse_worker_spec(spec)
    worker = _base_worker(name, robot, dt)
    return worker if perturbation.is_identity else PerturbedWorker(worker, perturbation, robot, dt)


def __getattr__(name: str) -> Any:
    if name == "LearnedWorker":  # loaded on first use: it brings torch
        from hier_ssl.worker.learned import LearnedWorker

        return LearnedWorker
    raise AttributeError(f"module 'hier_ssl.worker' has no attribute {name!r}")


__all__ = [
    "WORKERS",
    "BangBangGoToPoint",
    "LearnedWorker",
    "PaperGoToPoint",
    "Perturbation",
    "PerturbedWorker",
    "Worker",
    "check_worker_spec",
    "make_worker",
    "parse_worker_spec",
]
