"""Throughput benchmarks behind ``hier-ssl bench``, each on one core, best of several short runs.

A field-step is one 25 ms control step of one field: workers, obstacles, physics and state read-back
included, and in the env views also rewards, success and collision checks, observations and resets.

- ``world``: N fields of the paper's field, each with one controlled robot and one random-walk obstacle
  (paper text: a new direction and a speed in [0, 1] m/s every step), the scripted paper worker driving the
  robot to random sub-goals.
- ``env``: the PettingZoo ParallelEnv of one field, random manager actions, at frame skip 1 and 16; also
  the seconds that importing ``hier_ssl`` and building the env take in a fresh interpreter.
- ``vector``: the batched view (auto-reset) at frame skip 16 with random actions, for the Proposed task at
  N = 1024 and ``formation`` (6 controlled robots + 6 moving obstacles per field) at N = 256, or (``sweep``)
  each task of a list at each N of a list; the policy's cost is not included. Also the resident memory
  per field. ``scaling``: the same view on 1, 2, ... cores (``hier_ssl.envs.shards``), the counts
  alternated round by round in one process, on the wall clock.
"""

from __future__ import annotations

import gc
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import hier_ssl
from hier_ssl.envs import task_config
from hier_ssl.worker.scripted import PaperGoToPoint
from hier_ssl.world.obstacles import make_obstacle
from hier_ssl.world.physics import World

# The timer of the runs: wall-clock time by default; this thread's CPU time (``time.thread_time``) counts
# only the time the benchmark itself ran, steadier on a machine other processes share.
Clock = Callable[[], float]
WORLD_SIZES = (1, 64, 1024)
ENV_FRAME_SKIPS = (1, 16)
# (task or scenario, fields) of ``bench vector``.
VECTOR_RUNS = (("proposed", 1024), ("formation", 256))
# One new random sub-goal per field every 2 s, so robots keep accelerating, braking and turning.
_SUBGOAL_PERIOD = 80
# Robot-steps of a round of ``scaling``: about 0.1-0.3 s on one core, short enough that a shared machine's
# drift lands in every count's rounds alike.
SCALING_ROUND_ROBOT_STEPS = 100_000


@dataclass(frozen=True)
class BenchResult:
    """One measurement: ``steps_per_s`` field-steps per second of wall-clock time; ``extra`` what a
    bench adds (task, frame skip, decisions per second, build seconds)."""

    bench: str
    n_fields: int
    robots_per_field: int
    steps_per_s: float
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "bench": self.bench,
            "n_fields": self.n_fields,
            "robots_per_field": self.robots_per_field,
            "steps_per_s": round(self.steps_per_s, 1),
            **self.extra,
        }

    def describe(self) -> str:
        """One line of text for the terminal."""
        extra = "".join(
            f", {k} {v:,}" if isinstance(v, float) else f", {k} {v}" for k, v in self.extra.items()
        )
        return (
            f"  {self.bench}: N = {self.n_fields:5d} fields x {self.robots_per_field} robots: "
            f"{self.steps_per_s:12,.0f} field-steps/s{extra}"
        )


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


def bench_world(
    n_fields: int, steps: int | None = None, repeats: int = 5, seed: int = 0, clock: Clock = time.perf_counter
) -> BenchResult:
    """Field-steps per second of ``n_fields`` fields (1 robot + 1 random-walk obstacle, paper worker).

    ``steps`` control steps per timed run (``default_steps`` if None), timed by ``clock``; the best of
    ``repeats`` runs is reported, the usual guard against other processes taking the core for part of a
    run. Short runs make
    that guard work on a shared machine; on a loaded one every figure is still a lower bound.
    """
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
        start = clock()
        run(steps)
        best = min(best, clock() - start)
    return BenchResult("world", n_fields, 2, n_fields * steps / best)


def bench_worlds(
    sizes: Sequence[int] = WORLD_SIZES, steps: int | None = None, clock: Clock = time.perf_counter
) -> Iterator[BenchResult]:
    """``bench_world`` for each N in ``sizes``, yielded as each finishes."""
    for n in sizes:
        yield bench_world(n, steps, clock=clock)


def _best(run: Callable[[], tuple[float, ...]], repeats: int) -> tuple[float, ...]:
    """The fastest of ``repeats`` runs, each returning (seconds, count, ...), by seconds per count."""
    return min((run() for _ in range(repeats)), key=lambda r: r[0] / max(r[1], 1))


def build_seconds(task: str, frame_skip: int, repeats: int = 3) -> float:
    """Seconds that ``import hier_ssl`` and ``parallel_env(task=..., frame_skip=...)`` take in a fresh
    interpreter (its own start-up not included), best of ``repeats``; the child inherits this process's
    CPU affinity."""
    code = (
        "import time; start = time.perf_counter(); import hier_ssl; "
        f"hier_ssl.parallel_env(task={task!r}, frame_skip={frame_skip}); print(time.perf_counter() - start)"
    )
    runs = (
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
        for _ in range(repeats)
    )
    return min(float(run.stdout) for run in runs)


def bench_env(
    frame_skip: int,
    task: str = "proposed",
    decisions: int | None = None,
    repeats: int = 7,
    seed: int = 0,
    clock: Clock = time.perf_counter,
) -> BenchResult:
    """The PettingZoo ParallelEnv of ``task`` at ``frame_skip``, uniform random actions drawn beforehand,
    resetting when the episode ends (resets count in the time, not in the steps). ``decisions`` manager
    steps per timed run (about 4000 control steps if None). ``steps_per_s``: control steps per second;
    ``decisions_per_s``: ``step`` calls per second; ``build_s``: ``build_seconds``."""
    decisions = max(50, 4000 // frame_skip) if decisions is None else decisions
    env = hier_ssl.parallel_env(task=task, frame_skip=frame_skip)
    core = env.core
    for i, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(seed + i)
    pool = [{a: env.action_space(a).sample() for a in env.possible_agents} for _ in range(256)]
    env.reset(seed=seed)

    def run(count: int = decisions) -> tuple[float, int]:
        first, start = core.control_steps, clock()
        for i in range(count):
            if not env.agents:
                env.reset()
            actions = pool[i % len(pool)]
            env.step({a: actions[a] for a in env.agents})
        return clock() - start, core.control_steps - first

    run(min(decisions, 100))
    wall, steps = _best(run, repeats)
    extra = {
        "task": task,
        "frame_skip": frame_skip,
        "decisions_per_s": round(decisions / wall, 1),
        "build_s": round(build_seconds(task, frame_skip), 3),
    }
    return BenchResult("env", 1, core.num_agents + core.num_obstacles, steps / wall, extra)


def resident_bytes() -> int | None:
    """This process's resident memory in bytes (Linux's /proc), or None where that cannot be read."""
    try:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError):
        return None


@dataclass
class VectorRun:
    """The batched torch view of ``task`` over ``n_fields`` fields, built and reset, ready to be timed:
    ``run(count)`` makes ``count`` vector steps of uniform random actions (drawn beforehand, auto-reset)
    and returns (seconds, control steps of one field, seconds in ``World.step``) by ``clock``;
    ``memory_per_field`` is the resident memory building and one step added, bytes per field. The fields
    step on ``threads`` cores (``hier_ssl.envs.shards``); the time in ``World.step`` is counted where this
    process steps them all (one core), None otherwise."""

    task: str
    n_fields: int
    frame_skip: int
    clock: Clock
    seed: int = 0
    threads: int = 1

    def __post_init__(self) -> None:
        # here, not at the top: torch, for the vector bench alone
        import torch

        from hier_ssl.envs.vector import TorchVectorEnv

        config = task_config(self.task, frame_skip=self.frame_skip)
        # One field's first step loads the compiled per-robot loops (numba, with LLVM): memory taken once
        # a process, not per field.
        warm = TorchVectorEnv(config, 1)
        warm.reset(seed=self.seed)
        warm.step(torch.zeros(warm.num_envs, warm.num_actions))
        del warm
        gc.collect()  # what an earlier run left is freed before, not while, this one is measured
        before = resident_bytes()
        self.env = env = TorchVectorEnv(config, self.n_fields, threads=self.threads)
        self.core, self._in_world = env.core, [0.0]
        # The cores this process steps (every shard on one core; the first ones on more): their worlds.
        local = getattr(self.core, "local_cores", [self.core])
        self._all_local = getattr(self.core, "threads", 1) == 1
        for world in (core.world for core in local):
            world.step = self._timed(world.step)
        generator = torch.Generator().manual_seed(self.seed)
        self._pool = [
            torch.rand(env.num_envs, env.num_actions, generator=generator) * 2 - 1 for _ in range(8)
        ]
        env.reset(seed=self.seed)
        self.run(1)
        after = resident_bytes()
        self.memory_per_field = None if before is None else (after - before) / self.n_fields

    def _timed(self, world_step: Callable[[Any], Any]) -> Callable[[Any], Any]:
        def timed_step(command: Any) -> Any:  # World.step, timed
            start = self.clock()
            state = world_step(command)
            self._in_world[0] += self.clock() - start
            return state

        return timed_step

    def run(self, count: int) -> tuple[float, int, float | None]:
        self._in_world[0], first, start = 0.0, self.core.control_steps, self.clock()
        for i in range(count):
            self.env.step(self._pool[i % len(self._pool)])
        in_world = self._in_world[0] if self._all_local else None
        return self.clock() - start, self.core.control_steps - first, in_world

    @property
    def robots_per_field(self) -> int:
        return self.core.num_agents + self.core.num_obstacles


def bench_vector(
    task: str,
    n_fields: int,
    frame_skip: int = 16,
    decisions: int = 10,
    repeats: int = 5,
    seed: int = 0,
    clock: Clock = time.perf_counter,
) -> BenchResult:
    """The batched torch view of ``task`` (a paper task or a scenario) over ``n_fields`` fields at
    ``frame_skip``, uniform random actions drawn beforehand, auto-reset. ``decisions`` vector steps per
    timed run. ``steps_per_s``: control steps per second of all fields; ``decisions_per_s``: rows x vector
    steps per second; ``physics_share``: the part of the time spent in ``World.step``;
    ``memory_kb_per_field``: resident memory the env took, kB per field (``VectorRun``)."""
    bench = VectorRun(task, n_fields, frame_skip, clock, seed)
    bench.run(1)
    wall, steps, physics = _best(lambda: bench.run(decisions), repeats)
    memory = bench.memory_per_field
    extra = {
        "task": task,
        "frame_skip": frame_skip,
        "decisions_per_s": round(bench.env.num_envs * decisions / wall, 1),
        "physics_share": None if physics is None else round(physics / wall, 3),
        "memory_kb_per_field": None if memory is None else round(memory / 1024, 1),
    }
    return BenchResult("vector", n_fields, bench.robots_per_field, n_fields * steps / wall, extra)


def views(target: str, clock: Clock = time.perf_counter) -> Iterator[BenchResult]:
    """The runs of ``hier-ssl bench env`` or ``hier-ssl bench vector``, yielded as each finishes."""
    if target == "env":
        yield from (bench_env(frame_skip, clock=clock) for frame_skip in ENV_FRAME_SKIPS)
    else:
        yield from (bench_vector(task, n, clock=clock) for task, n in VECTOR_RUNS)


def sweep(
    tasks: Sequence[str], sizes: Sequence[int], frame_skip: int, clock: Clock = time.perf_counter
) -> Iterator[BenchResult]:
    """``bench_vector`` for each task at each N of ``sizes``, yielded by task and N. Each result adds
    ``per_field_vs_smallest``: its field-steps/s over those at the smallest N (1.0: the cost per field is
    flat). The largest N runs first: memory a smaller run freed would otherwise be counted as not taken."""
    for task in tasks:
        results = {
            n: bench_vector(task, n, frame_skip, decisions=max(2, 40 // frame_skip), repeats=3, clock=clock)
            for n in sorted(set(sizes), reverse=True)
        }
        smallest = results[min(results)].steps_per_s
        for n in sorted(results):
            results[n].extra["per_field_vs_smallest"] = round(results[n].steps_per_s / smallest, 3)
            yield results[n]


def scaling(
    tasks: Sequence[str],
    sizes: Sequence[int],
    threads: Sequence[int],
    frame_skip: int,
    rounds: int = 20,
    clock: Clock = time.perf_counter,
) -> Iterator[BenchResult]:
    """Each task at each N on each count of cores in ``threads`` (``VectorRun``): the counts' views built
    side by side and timed in turn, ``rounds`` rounds of about ``SCALING_ROUND_ROBOT_STEPS`` robot-steps
    each, the best round of each count. Each result adds ``threads`` and ``speedup``, its field-steps/s
    over those of the first count."""
    for task in tasks:
        for n in sizes:
            runs = {k: VectorRun(task, n, frame_skip, clock, threads=k) for k in threads}
            robots = runs[threads[0]].robots_per_field
            count = max(1, round(SCALING_ROUND_ROBOT_STEPS / (n * robots * frame_skip)))
            best = dict.fromkeys(runs, 0.0)
            for _ in range(rounds):
                for k, run in runs.items():
                    seconds, steps, _ = run.run(count)
                    best[k] = max(best[k], n * steps / seconds)
            for run in runs.values():
                run.env.close()
            for k in runs:
                extra = {
                    "task": task,
                    "frame_skip": frame_skip,
                    "threads": k,
                    "speedup": round(best[k] / best[threads[0]], 3),
                }
                yield BenchResult("vector", n, robots, best[k], extra)


def print_results(results: Iterator[BenchResult], as_json: bool) -> None:
    """Each result as it comes, as a JSON line or a line of text."""
    for result in results:
        print(json.dumps(result.as_dict()) if as_json else result.describe(), flush=True)
