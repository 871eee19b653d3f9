"""Throughput benchmarks behind ``hier-ssl bench``.

``world``: N fields of the paper's field, each with one controlled robot and one random-walk obstacle
(paper text: a new direction and a speed in [0, 1] m/s every step), the scripted paper worker driving the
robot to random sub-goals, on one core. A field-step is one 25 ms control step of one field: worker,
obstacle, physics and state read-back all included.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

WORLD_SIZES = (1, 64, 1024)
# One new random sub-goal per field every 2 s, so robots keep accelerating, braking and turning.
_SUBGOAL_PERIOD = 80


@dataclass(frozen=True)
class BenchResult:
    """One measurement: ``steps_per_s`` field-steps per second of wall-clock time."""

    bench: str
    n_fields: int
    robots_per_field: int
    steps_per_s: float

    def as_dict(self) -> dict[str, str | int | float]:
        return {
            "bench": self.bench,
            "n_fields": self.n_fields,
            "robots_per_field": self.robots_per_field,
            "steps_per_s": round(self.steps_per_s, 1),
        }


def pin_to_one_core() -> int | None:
    """Run this process on its first allowed CPU, with one thread for numpy's and torch's math libraries.

    Thread-count variables only bind libraries loaded afterwards, so call this before importing numpy's
    BLAS users or torch where possible; torch, if already imported, is told directly. Returns the CPU, or
    None where affinity cannot be set (not Linux).
    """
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)
    if not hasattr(os, "sched_setaffinity"):
        return None
    cpu = min(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {cpu})
    return cpu


def default_steps(n_fields: int) -> int:
    """Control steps per timed run: runs of a few tenths of a second for every N (4000 steps at N = 1)."""
    return max(20, round(4000 / n_fields**0.5))


def bench_world(n_fields: int, steps: int | None = None, repeats: int = 5, seed: int = 0) -> BenchResult:
    """Field-steps per second of ``n_fields`` fields (1 robot + 1 random-walk obstacle, paper worker).

    ``steps`` control steps per timed run (``default_steps`` if None); the best of ``repeats`` runs is
    reported, the usual guard against other processes taking the core for part of a run. Short runs make
    that guard work on a shared machine; on a loaded one every figure is still a lower bound.
    """
    from hier_ssl.worker.scripted import PaperGoToPoint
    from hier_ssl.world.obstacles import make_obstacle
    from hier_ssl.world.physics import World

    if not (isinstance(n_fields, int) and n_fields >= 1):
        raise ValueError(f"n_fields must be an integer >= 1, got {n_fields!r}")
    steps = default_steps(n_fields) if steps is None else steps
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    if not (isinstance(repeats, int) and repeats >= 1):
        raise ValueError(f"repeats must be an integer >= 1, got {repeats!r}")

    rng = np.random.default_rng(seed)
    world = World(n_fields, 2)
    fields = np.arange(n_fields)
    hx, hy = world.field.half_length - 0.1, world.field.half_width - 0.1
    world.set_state(
        fields, rng.uniform((-hx, -hy), (hx, hy), (n_fields, 2, 2)), rng.uniform(-np.pi, np.pi, (n_fields, 2))
    )
    worker = PaperGoToPoint(dt=world.dt)
    obstacle = make_obstacle("random_walk", n_fields)
    subgoal = np.zeros((n_fields, 1, 5))
    command = np.zeros((n_fields, 2, 3))

    def run(count: int) -> None:
        for t in range(count):
            if t % _SUBGOAL_PERIOD == 0:
                subgoal[:, 0, 0:2] = rng.uniform((-hx, -hy), (hx, hy), (n_fields, 2))
                subgoal[:, 0, 2] = rng.uniform(-np.pi, np.pi, n_fields)
            state = world.state
            command[:, 0:1] = worker(state.robots(slice(0, 1)), subgoal)
            command[:, 1] = obstacle(state.pos[:, 1], state.angle[:, 1], rng)
            world.step(command)

    run(min(steps, 50))
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        run(steps)
        best = min(best, time.perf_counter() - start)
    return BenchResult("world", n_fields, 2, n_fields * steps / best)


def bench_worlds(sizes: Sequence[int] = WORLD_SIZES, steps: int | None = None) -> Iterator[BenchResult]:
    """``bench_world`` for each N in ``sizes``, yielded as each finishes."""
    for n in sizes:
        yield bench_world(n, steps)
