"""goToPoint workers: (robot state, sub-goal) -> velocity command, batched; chosen by a spec string.

A worker is ``__call__(state (N, R), subgoal (N, R, 5)) -> (N, R, 3)`` robot-frame commands in m/s and
rad/s, plus ``reset(fields)`` (the ``Worker`` protocol below). ``make_worker`` takes the spec a config's
``env.worker`` or the command line's ``--worker`` gives: ``paper``, ``bangbang``, the run directory of a
trained worker, or an import spec ``package.module:Name`` of a class or factory
(``hier_ssl.worker.external``), each optionally followed by ``+key=value`` perturbations
(``paper+latency=2+noise=0.2``; the keys are listed in ``hier_ssl.worker.perturbed``).
``resolve_worker`` takes a spec or a Python object. The learned worker (and torch) is imported only
when one is named.
"""

from __future__ import annotations

import inspect
import os
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from hier_ssl.worker.external import (
    CheckedWorker,
    WorkerError,
    build_imported,
    build_worker,
    checked,
    import_target,
    is_import_spec,
    worker_name,
)
from hier_ssl.worker.perturbed import Perturbation, PerturbedWorker, parse_worker_spec
from hier_ssl.worker.scripted import BangBangGoToPoint, PaperGoToPoint
from hier_ssl.world.physics import RobotSpec, RobotState

WORKERS = ("paper", "bangbang")
_KINDS = f"{'|'.join(WORKERS)}, a worker run directory or package.module:Name"


class Worker(Protocol):
    """What the environments call once per 25 ms control step, for every controlled robot of every field.

    Optional attributes that planners read when present: ``max_speed`` (m/s, the fastest the worker
    commands) and ``brake_accel`` (m/s^2, the deceleration it brakes with). A worker with randomness of
    its own may have ``seed(seed: int)``: the environments call it on every seeded reset, with the
    episode seed, so the same seed gives the same episodes through every view.
    """

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        """Commands (N, R, 3): (vx, vy, w) in each robot's own frame (x forward), m/s and rad/s.

        ``state`` holds the robots' pos (N, R, 2) m, angle (N, R) rad, vel (N, R, 2) m/s and ang_vel
        (N, R) rad/s, field frame; ``subgoal`` (N, R, 5) is (x, y, theta, vx, vy), field frame.
        """
        ...

    def reset(self, fields: np.ndarray) -> None:
        """Forget what the worker remembers of the fields ``fields`` (M,) int indices into N: their
        episodes start anew. Called before the first ``__call__`` of every episode."""
        ...


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
    if is_import_spec(name):
        return build_imported(name, robot, dt)
    if Path(name).is_dir():
        # here, not at the top: torch, for a learned worker alone
        from hier_ssl.worker.learned import load_learned_worker

        return load_learned_worker(name, robot, dt)
    raise WorkerError(f"unknown worker {name!r}; expected {_KINDS}")


def check_worker_spec(spec: str) -> str:
    """``spec`` if its name part is a scripted worker, an importable ``package.module:Name`` (a class or
    factory; imported, not built) or an existing directory; a ValueError naming it otherwise."""
    base, _ = parse_worker_spec(spec)
    if is_import_spec(base):
        import_target(base)
    elif base not in WORKERS and not Path(base).is_dir():
        raise WorkerError(f"unknown worker {base!r}; expected {_KINDS}")
    return spec


def make_worker(spec: str, robot: RobotSpec, dt: float) -> Worker:
    """The worker ``spec`` names (module docstring), tuned to the world's robot and control period.

    A ValueError names the spec, or the run directory when it holds no usable worker checkpoint.
    """
    name, perturbation = parse_worker_spec(spec)
    worker = _base_worker(name, robot, dt)
    return worker if perturbation.is_identity else PerturbedWorker(worker, perturbation, robot, dt)


def resolve_worker(worker: str | os.PathLike[str] | Any, robot: RobotSpec, dt: float) -> Worker:
    """A ready worker from a spec string or run directory (``make_worker``), a class or factory function
    (called as an import spec's target is, with the ``robot`` / ``dt`` keywords it accepts), or a worker
    object. Workers from outside hier_ssl come inside a ``CheckedWorker``; ``WorkerError`` names the
    worker when it cannot be built or lacks ``__call__`` / ``reset``.
    """
    if isinstance(worker, (str, os.PathLike)):
        return make_worker(os.fspath(worker), robot, dt)
    if inspect.isclass(worker) or inspect.isfunction(worker):
        return build_worker(worker, worker_name(worker), robot, dt)
    return checked(worker, worker_name(worker))


def __getattr__(name: str) -> Any:
    if name == "LearnedWorker":  # loaded on first use: it brings torch
        from hier_ssl.worker.learned import LearnedWorker

        return LearnedWorker
    raise AttributeError(f"module 'hier_ssl.worker' has no attribute {name!r}")


__all__ = [
    "WORKERS",
    "BangBangGoToPoint",
    "CheckedWorker",
    "LearnedWorker",
    "PaperGoToPoint",
    "Perturbation",
    "PerturbedWorker",
    "Worker",
    "WorkerError",
    "check_worker_spec",
    "make_worker",
    "parse_worker_spec",
    "resolve_worker",
    "worker_name",
]
