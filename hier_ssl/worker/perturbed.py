"""Any worker with the gaps between this simulator and a real robot: command latency, actuator noise,
and a different acceleration limit, each optional.

Chosen by a spec string, wherever a worker is named (``env.worker`` in a config, ``--worker`` on the
command line): the worker's name or run directory, then ``+key=value`` perturbations::

    paper+latency=2+noise=0.2          the paper's controller, 2 steps late, 20 % multiplicative noise
    bangbang+accel=1.5                 bang-bang commands ramped at 1.5 m/s^2 at most
    runs/worker-s0+latency=1+seed=3    a learned worker, 1 step late

==========  ===========================================================================  =================
key         effect on the command (vx, vy, w) in the robot's frame                       value
==========  ===========================================================================  =================
latency     applied this many 25 ms control steps after the worker computed it; zero     int >= 0 steps
            (stop) for the first steps after a reset
accel       velocity changes by at most accel * dt per step (norm, field frame), from    m/s^2 > 0
            the robot's velocity at reset; the world still caps it at 3 m/s^2 itself
ang_accel   angular velocity changes by at most ang_accel * dt per step                  rad/s^2 > 0
noise       each component times (1 + noise * N(0, 1)): multiplicative                   fraction >= 0
noise_add   plus noise_add * (v_max, v_max, w_max) * N(0, 1): additive                   fraction >= 0
seed        seed of the noise, mixed with the episode seed of every seeded reset         int
            (default 0; the same episode seed, the same noise)
==========  ===========================================================================  =================

Per step the order is that of a real robot: the late command arrives, the firmware ramps towards it at
its acceleration limit, the wheels add noise. Buffers are per field and robot, and ``reset(fields)``
clears the given fields' buffers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from hier_ssl.world.frames import to_field_frame, to_robot_frame
from hier_ssl.world.physics import RobotSpec, RobotState


@dataclass(frozen=True)
class Perturbation:
    """The perturbations of the module docstring; defaults perturb nothing."""

    latency: int = 0
    accel: float | None = None
    ang_accel: float | None = None
    noise: float = 0.0
    noise_add: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        if not (isinstance(self.latency, int) and self.latency >= 0):
            raise ValueError(f"latency: expected an integer >= 0 control steps, got {self.latency!r}")
        for name in ("accel", "ang_accel"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name}: expected a limit > 0, got {value!r}")
        for name in ("noise", "noise_add"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: expected a fraction >= 0, got {value!r}")

    @property
    def is_identity(self) -> bool:
        return self == Perturbation(seed=self.seed)


_KEYS = {f.name: f.type for f in fields(Perturbation)}
_INT_KEYS = ("latency", "seed")


def parse_worker_spec(spec: str) -> tuple[str, Perturbation]:
    """Split ``"paper+latency=2+noise=0.2"`` into the base worker and its ``Perturbation``.

    Only trailing ``+key=value`` parts with a known key are perturbations, so a run directory whose
    name holds a ``+`` stays whole. A ValueError names the bad part.
    """
    base, options = spec, {}
    while True:
        head, sep, tail = base.rpartition("+")
        key, eq, value = tail.partition("=")
        if not sep or not eq:
            break
        if key not in _KEYS:
            if key.isidentifier():
                raise ValueError(f"worker {spec!r}: unknown perturbation {key!r}; known: {sorted(_KEYS)}")
            break
        if key in options:
            raise ValueError(f"worker {spec!r}: {key} given twice")
        try:
            options[key] = int(value) if key in _INT_KEYS else float(value)
        except ValueError:
            kind = "an integer" if key in _INT_KEYS else "a number"
            raise ValueError(f"worker {spec!r}: {key} must be {kind}, got {value!r}") from None
        base = head
    if not base:
        raise ValueError(f"worker {spec!r}: no worker name before the perturbations")
    try:
        return base, Perturbation(**options)
    except ValueError as err:
        raise ValueError(f"worker {spec!r}: {err}") from None


class PerturbedWorker:
    """``worker``'s commands, late, rate-limited and noisy as ``perturbation`` says.

    Same interface as the workers it wraps: ``__call__(state (N, R), subgoal (N, R, 5)) -> (N, R, 3)``
    and ``reset(fields)``. Buffers are sized on the first call.
    """

    def __init__(self, worker: Any, perturbation: Perturbation, robot: RobotSpec, dt: float) -> None:
        self.worker, self.perturbation, self.robot, self.dt = worker, perturbation, robot, dt
        self.rng = np.random.default_rng(perturbation.seed)
        self._scale = np.array([robot.max_speed, robot.max_speed, robot.max_ang_speed])
        self._queue: np.ndarray | None = None  # (latency, N, R, 3) commands not yet applied, oldest first
        self._vel: np.ndarray | None = None  # (N, R, 2) last applied velocity, field frame, before noise
        self._spin: np.ndarray | None = None  # (N, R) last applied angular velocity, before noise
        self._fresh: np.ndarray | None = None  # (N, R) no command applied since reset

    def __repr__(self) -> str:
        return f"PerturbedWorker({self.worker!r}, {self.perturbation})"

    def __getattr__(self, name: str) -> Any:
        # The wrapped worker's settings (max_speed, brake_accel, ...) for planners that read them.
        if name == "worker":
            raise AttributeError(name)
        return getattr(self.worker, name)

    def seed(self, seed: int) -> None:
        """Restart the noise from ``seed`` (an environment's episode seed) mixed with the spec's ``seed``,
        and seed the wrapped worker where it takes a seed: a seeded reset replays the same noise."""
        self.rng = np.random.default_rng((seed, self.perturbation.seed))
        inner = getattr(self.worker, "seed", None)
        if inner is not None:
            inner(seed)

    def reset(self, fields: np.ndarray) -> None:
        """Forget the given fields' queued commands and ramp state, then reset the wrapped worker."""
        if self._queue is not None:
            self._queue[:, fields] = 0.0
            self._fresh[fields] = True
        self.worker.reset(fields)

    def _allocate(self, shape: tuple[int, int]) -> None:
        self._queue = np.zeros((self.perturbation.latency, *shape, 3))
        self._vel, self._spin = np.zeros((*shape, 2)), np.zeros(shape)
        self._fresh = np.ones(shape, dtype=bool)

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        """Commands (N, R, 3) for robots ``state`` (N, R) to reach ``subgoal`` (N, R, 5)."""
        p = self.perturbation
        command = np.asarray(self.worker(state, subgoal), dtype=np.float64)
        if self._queue is None or self._fresh.shape != command.shape[:2]:
            self._allocate(command.shape[:2])
        # Latency: push the new command, apply the oldest.
        if p.latency:
            self._queue = np.concatenate([self._queue, command[None]])
            command, self._queue = self._queue[0].copy(), self._queue[1:]
        # Acceleration limit: ramp from the last applied velocity (the robot's own after a reset).
        if p.accel is not None or p.ang_accel is not None:
            command = self._ramp(state, command)
        # Actuator noise.
        if p.noise:
            command = command * (1.0 + p.noise * self.rng.standard_normal(command.shape))
        if p.noise_add:
            command = command + p.noise_add * self._scale * self.rng.standard_normal(command.shape)
        return command

    def _ramp(self, state: RobotState, command: np.ndarray) -> np.ndarray:
        p, fresh = self.perturbation, self._fresh
        self._vel[fresh], self._spin[fresh] = state.vel[fresh], state.ang_vel[fresh]
        fresh[:] = False
        command = command.copy()
        if p.accel is not None:
            wanted = to_field_frame(command[..., 0:2], state.angle)
            change = wanted - self._vel
            size = np.linalg.norm(change, axis=-1, keepdims=True)
            step = p.accel * self.dt
            self._vel = self._vel + change * np.minimum(1.0, step / np.maximum(size, 1e-12))
            command[..., 0:2] = to_robot_frame(self._vel, state.angle)
        if p.ang_accel is not None:
            step = p.ang_accel * self.dt
            self._spin = self._spin + np.clip(command[..., 2] - self._spin, -step, step)
            command[..., 2] = self._spin
        return command


__all__ = ["Perturbation", "PerturbedWorker", "parse_worker_spec"]
