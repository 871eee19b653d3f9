"""Controllers from outside hier_ssl as workers: named by an import spec, or handed over as objects.

An import spec ``package.module:Name`` names a class or a factory function. It is called with the
keyword arguments among ``robot`` (``hier_ssl.world.physics.RobotSpec``: the robot's speed and
acceleration limits) and ``dt`` (the control period in s) that its signature accepts (all of them if it
takes ``**kwargs``), and must return a worker: ``__call__(state, subgoal) -> commands`` and
``reset(fields)`` (the protocol of ``hier_ssl.worker``). A worker object is used as it is.

Such workers run inside ``CheckedWorker``, which turns a wrong output shape or a NaN / infinite command
into one ``WorkerError`` naming the worker, at the step where it happens. Import and construction
failures are ``WorkerError``s naming the spec too. The built-in workers are trusted and not wrapped.
"""

from __future__ import annotations

import importlib
import inspect
import re
from typing import Any

import numpy as np

from hier_ssl.world.physics import RobotSpec, RobotState

_IMPORT_SPEC = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")
BUILD_ARGUMENTS = ("robot", "dt")


class WorkerError(ValueError):
    """A worker that cannot be imported or built, or that returned unusable commands; names the worker."""


def is_import_spec(name: str) -> bool:
    """Whether ``name`` has the form ``package.module:Name`` (dots allowed on both sides)."""
    return _IMPORT_SPEC.fullmatch(name) is not None


def worker_name(worker: Any) -> str:
    """How errors and tables name a worker: a spec string as given, else ``module:QualifiedClassName``."""
    if isinstance(worker, str):
        return worker
    cls = worker if inspect.isclass(worker) else type(worker)
    return f"{cls.__module__}:{cls.__qualname__}"


def import_target(spec: str) -> Any:
    """The class or factory that ``spec`` (``package.module:Name``) names, imported but not called."""
    module_name, _, qualname = spec.partition(":")
    try:
        target = importlib.import_module(module_name)
    except Exception as err:  # whatever the module raises while importing: one error naming the worker
        raise WorkerError(
            f"worker {spec!r}: cannot import {module_name!r} ({type(err).__name__}: {err})"
        ) from err
    for part in qualname.split("."):
        if not hasattr(target, part):
            raise WorkerError(f"worker {spec!r}: {module_name!r} has no attribute {qualname!r}")
        target = getattr(target, part)
    if not (inspect.isclass(target) or inspect.isroutine(target)):
        raise WorkerError(
            f"worker {spec!r}: names a {type(target).__name__} object; expected a class or a factory function"
        )
    return target


def _accepted(target: Any, arguments: dict[str, Any]) -> dict[str, Any]:
    """The entries of ``arguments`` that ``target``'s signature takes as keywords."""
    try:
        parameters = inspect.signature(target).parameters.values()
    except (TypeError, ValueError):  # no introspectable signature (some built-in callables)
        return {}
    if any(p.kind is p.VAR_KEYWORD for p in parameters):
        return dict(arguments)
    names = {p.name for p in parameters if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    return {key: value for key, value in arguments.items() if key in names}


def build_worker(target: Any, name: str, robot: RobotSpec, dt: float) -> CheckedWorker:
    """``target`` (a class or factory) called with the ``BUILD_ARGUMENTS`` it accepts, checked."""
    kwargs = _accepted(target, {"robot": robot, "dt": dt})
    try:
        worker = target(**kwargs)
    except Exception as err:  # the user's constructor failed: name the worker and what it was given
        call = f"{getattr(target, '__name__', 'target')}({', '.join(f'{k}=...' for k in kwargs)})"
        raise WorkerError(f"worker {name!r}: {call} failed ({type(err).__name__}: {err})") from err
    return checked(worker, name)


def build_imported(spec: str, robot: RobotSpec, dt: float) -> CheckedWorker:
    """The worker an import spec names, built for ``robot`` and control period ``dt``."""
    return build_worker(import_target(spec), spec, robot, dt)


def checked(worker: Any, name: str) -> CheckedWorker:
    """``worker`` inside a ``CheckedWorker`` named ``name``; a WorkerError if it lacks the protocol."""
    if isinstance(worker, CheckedWorker):
        return worker
    if inspect.isclass(worker):
        problem = f"got the class {worker.__qualname__}, not an instance of it"
    else:
        missing = [m for m in ("__call__", "reset") if not callable(getattr(worker, m, None))]
        if not missing:
            return CheckedWorker(worker, name)
        problem = f"got a {type(worker).__name__} without {' or '.join(missing)}"
    raise WorkerError(
        f"worker {name!r}: {problem}; a worker is an object called as worker(state, subgoal) -> commands, "
        "with reset(fields)"
    )


class CheckedWorker:
    """``worker`` with every output checked: shape (N, R, 3) for sub-goals (N, R, 5), all values finite.

    The check is two comparisons and one ``np.isfinite(...).all()`` a call; locating the bad command
    runs only when there is one. Attributes the worker has (``max_speed``, ``brake_accel``, ...) read
    through, for planners that use them.
    """

    def __init__(self, worker: Any, name: str) -> None:
        self.worker, self.name = worker, name

    def __repr__(self) -> str:
        return f"CheckedWorker({self.name!r})"

    def __getattr__(self, attr: str) -> Any:
        if attr == "worker":  # not set yet (unpickling): no recursion
            raise AttributeError(attr)
        return getattr(self.worker, attr)

    def reset(self, fields: np.ndarray) -> None:
        """Reset the wrapped worker's fields ``fields`` (M,), int indices into N."""
        self.worker.reset(fields)

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        """The wrapped worker's commands (N, R, 3) float64, for robots ``state`` (N, R) and ``subgoal``
        (N, R, 5); a WorkerError naming the worker when they are not of that shape or not finite."""
        output = self.worker(state, subgoal)
        try:
            command = np.asarray(output, dtype=np.float64)
        except (TypeError, ValueError):
            raise WorkerError(
                f"worker {self.name!r} returned a {type(output).__name__}, not an array of numbers"
            ) from None
        expected = (*subgoal.shape[:-1], 3)
        if command.shape != expected:
            raise WorkerError(
                f"worker {self.name!r} returned commands of shape {command.shape}; expected {expected} "
                "(fields, robots, (vx, vy, w))"
            )
        if not np.isfinite(command).all():
            field, robot = np.argwhere(~np.isfinite(command).all(axis=-1))[0]
            raise WorkerError(
                f"worker {self.name!r} returned a non-finite command {command[field, robot].tolist()} "
                f"(field {field}, robot {robot})"
            )
        return command


__all__ = [
    "BUILD_ARGUMENTS",
    "CheckedWorker",
    "WorkerError",
    "build_imported",
    "build_worker",
    "checked",
    "import_target",
    "is_import_spec",
    "worker_name",
]
