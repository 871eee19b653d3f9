"""N fields on K cores: the fields in shards of ``SHARD_BLOCKS`` pymunk blocks each, every shard a
``HierarchicalCore`` of its own, stepped by this process and K - 1 worker processes over shared memory.

Not threads: Chipmunk's step releases Python's lock, but the per-robot loops, the observation, the rules
and the book-keeping hold it (two threads on halves of `obstacle`, N = 1024: 1.2x one, benchmarks.md).

**Same seed, same results, for every K.** The shards are ``block_groups(N, SHARD_BLOCKS)``, whatever K
is; a reset's seed gives each shard its own (``shard_seeds``), and each shard's core, draws and physics
are those of a core of its fields alone, wherever it runs. So N above one shard does not replay one core
over all N fields; N within one shard is one core (``batched_core`` returns it).

**The processes.** Workers fork from a ``forkserver`` (started once, this module preloaded): none inherits
the threads torch or OpenMP started in the caller. Every per-field array of a step lives in one shared
buffer; a pipe per worker carries the command and the statistics of robots that left. ``close()`` (also
on garbage collection and at exit) stops the workers; a worker whose parent dies exits. A command that
fails part-way leaves the shards out of step: the core then refuses all but ``close()``.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import traceback
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any, Literal

import numpy as np

from hier_ssl.config import TaskConfig
from hier_ssl.envs.core import HierarchicalCore, StepResult
from hier_ssl.envs.registry import make_scenario
from hier_ssl.envs.scenario import Scenario
from hier_ssl.world.blocks import block_groups
from hier_ssl.world.robot import RobotState

Threads = int | Literal["auto"]
# The per-robot info of a core's step that the shards hand back as arrays (N, M): what the views read.
_INFO = ("control_steps", "success", "collision", "action_clipped", "live")
_ROBOTS = ("pos", "angle", "vel", "ang_vel")
_ALIGN = 64  # bytes: every array of the shared buffer starts on a cache line


def resolve_threads(threads: Threads) -> int:
    """``threads`` as a count: "auto" is the cores this process may run on; a ValueError names a bad
    value."""
    if threads == "auto":
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    if isinstance(threads, bool) or not isinstance(threads, int | np.integer) or threads < 1:
        raise ValueError(f"threads must be an integer >= 1 or 'auto', got {threads!r}")
    return int(threads)


SHARD_BLOCKS = 4  # a core's per-step overhead paid once for 4 blocks: 1-block shards cost one core 25 %


def shard_seeds(seed: int | None, count: int) -> list[int | None]:
    """The seeds of ``count`` shards' resets from one ``seed``: the seed itself for a single shard (one
    core, as ever), else one drawn for each shard by ``SeedSequence(seed).spawn``; None stays None."""
    if seed is None or count == 1:
        return [seed] * count
    return [int(child.generate_state(1, np.uint64)[0]) for child in np.random.SeedSequence(seed).spawn(count)]


def _layout(n: int, m: int, robots: int, obs_dim: int, act_dim: int) -> dict[str, tuple[tuple, type]]:
    """Name -> (shape, dtype) of every shared array of N fields."""
    flags = ("terminated", "truncated", "success", "collision", "live", "active")
    return {
        "action": ((n, m, act_dim), np.float64),
        "obs": ((n, m, obs_dim), np.float32),
        "final_obs": ((n, m, obs_dim), np.float32),
        "reward": ((n, m), np.float32),
        **dict.fromkeys(flags, ((n, m), np.bool_)),
        **dict.fromkeys(("control_steps", "action_clipped", "decisions"), ((n, m), np.int64)),
        "steps": ((n,), np.int64),
        **dict.fromkeys(("target", "subgoal"), ((n, m, 5), np.float64)),
        **{key: ((n, robots, 2) if key in ("pos", "vel") else (n, robots), np.float64) for key in _ROBOTS},
    }


def _places(layout: dict[str, tuple[tuple, type]]) -> tuple[dict[str, int], int]:
    """Each array's byte offset in the shared buffer (each on a cache line), and the buffer's size."""
    places, at = {}, 0
    for name, (shape, dtype) in layout.items():
        places[name] = at
        at += -(-int(np.prod(shape)) * np.dtype(dtype).itemsize // _ALIGN) * _ALIGN
    return places, at


def _arrays(buffer: Any, layout: dict[str, tuple[tuple, type]]) -> dict[str, np.ndarray]:
    """The arrays of ``layout`` on ``buffer`` (bytes-like), at their ``_places``."""
    places, _ = _places(layout)
    return {
        name: np.frombuffer(buffer, dtype, int(np.prod(shape)), places[name]).reshape(shape)
        for name, (shape, dtype) in layout.items()
    }


# What a step writes of each shard, besides its observations: the result's arrays and the core's counters.
_RESULT = ("reward", "terminated", "truncated")
_COUNTERS = ("active", "steps", "decisions", "subgoal")


@dataclass
class _Lane:
    """The shards one process steps: ``cores`` over fields ``bounds``, writing into ``arrays``; ``views``
    holds each shard's rows of every array, made once."""

    cores: list[HierarchicalCore]
    bounds: list[tuple[int, int]]
    arrays: dict[str, np.ndarray]
    views: list[dict[str, np.ndarray]]
    # The statistics of a step where no robot left (zero-length arrays of the core's dtypes), from the
    # first step: a shard with every episode ended (no auto-reset) has stepped before.
    nobody: dict[str, np.ndarray] | None = None

    @classmethod
    def build(
        cls,
        scenario: type[Scenario],
        config: TaskConfig,
        bounds: list[tuple[int, int]],
        autoreset: bool,
        worker: Any,
        arrays: dict[str, np.ndarray],
    ) -> _Lane:
        cores = [HierarchicalCore(scenario(config), b - a, autoreset, worker) for a, b in bounds]
        views = [{key: array[a:b] for key, array in arrays.items()} for a, b in bounds]
        return cls(cores, bounds, arrays, views)

    def run(self, command: str, seeds: Sequence[int | None]) -> list[dict[str, np.ndarray]]:
        """``reset`` (with ``seeds``, one a shard), ``step`` (with the shared actions) or ``state`` (the
        targets and robots, written on demand: a step does not need them) every shard, its results into
        the shared arrays; after a step, each shard's episode statistics (``info["task"]``, fields
        numbered among the N)."""
        out = []
        for k, (core, view) in enumerate(zip(self.cores, self.views, strict=True)):
            if command == "state":
                np.copyto(view["target"], core.target)
                for key in _ROBOTS:
                    np.copyto(view[key], getattr(core.state, key))
                continue
            if command == "reset":
                np.copyto(view["obs"], core.reset(seeds[k]))
            elif core.active.any():
                out.append(self._step(core, view, self.bounds[k][0]))
            else:  # a shard whose episodes have all ended (no auto-reset) waits for the others: no step
                out.append(self._idle(view))
            for key in _COUNTERS:
                np.copyto(view[key], getattr(core, key))
        return out

    def _step(self, core: HierarchicalCore, view: dict[str, np.ndarray], first: int) -> dict[str, np.ndarray]:
        result = core.step(view["action"])
        info = result.info
        np.copyto(view["obs"], result.obs)
        np.copyto(view["final_obs"], info["final_obs"])
        for key in _RESULT:
            np.copyto(view[key], getattr(result, key))
        for key in _INFO:
            np.copyto(view[key], info[key])
        stats = info["task"]
        if self.nobody is None:
            self.nobody = {key: value[:0] for key, value in stats.items()}
        return {**stats, "field": stats["field"] + first}

    def _idle(self, view: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        np.copyto(view["final_obs"], view["obs"])
        for key in (*_RESULT, *_INFO):
            view[key].fill(0)
        assert self.nobody is not None
        return self.nobody

    @property
    def control_steps(self) -> int:
        return max(core.control_steps for core in self.cores)


def _serve(conn: Connection, buffer: Any, layout: dict, lane: tuple) -> None:
    """A worker process: build its lane, then run each command from ``conn`` until "close" or until the
    parent's end of the pipe closes."""
    try:
        worker_lane = _Lane.build(*lane, _arrays(buffer, layout))
        conn.send(("ok", worker_lane.control_steps))
    except Exception:
        conn.send(("error", traceback.format_exc()))
        return
    while True:
        try:
            command, seeds = conn.recv()
        except EOFError:  # the parent is gone
            return
        if command == "close":
            return
        try:
            # Empty statistics (most steps) travel as None: no arrays to pickle.
            stats = [entry if len(entry["field"]) else None for entry in worker_lane.run(command, seeds)]
            conn.send(("ok", (stats, worker_lane.control_steps)))
        except Exception:
            conn.send(("error", traceback.format_exc()))


def _stop(processes: list[Any], conns: list[Connection]) -> None:
    """Ask every worker to stop, then make sure it has (``ShardedCore.close``, also at exit)."""
    for conn in conns:
        try:
            conn.send(("close", ()))
        except (BrokenPipeError, OSError):
            pass
    for process in processes:
        process.join(timeout=5)
        if process.is_alive():
            process.terminate()
            process.join()
    for conn in conns:
        conn.close()


class ShardedCore:
    """N fields of one task or scenario in shards (``block_groups(N, SHARD_BLOCKS)``), stepped on
    ``threads`` cores (an int, or "auto": the cores this process may use): this process steps the first
    shards, K - 1 worker processes the others, K at most the number of shards.

    The interface is the part of ``HierarchicalCore`` the views and ``play`` use: ``reset(seed)``,
    ``step(action (N, M, A))`` with the same ``StepResult`` (``info`` without what a view does not read:
    the core's ``step`` info keys, ``task`` concatenated in field order), ``observe()``, and copies of
    ``active``, ``steps``, ``decisions``, ``target``, ``subgoal`` and ``state``; ``close()`` ends the workers.
    """

    def __init__(
        self,
        task: TaskConfig | Scenario,
        num_fields: int,
        autoreset: bool = True,
        worker: Any = None,
        threads: Threads = 1,
    ) -> None:
        scenario = task if isinstance(task, Scenario) else make_scenario(task)
        kind, config = type(scenario), scenario.config
        bounds = block_groups(num_fields, SHARD_BLOCKS)
        lanes = [
            list(part)
            for part in np.array_split(np.arange(len(bounds)), min(resolve_threads(threads), len(bounds)))
        ]
        self.num_fields, self.autoreset, self.threads = num_fields, autoreset, len(lanes)
        self._bounds, self._lanes = bounds, lanes
        first = [bounds[k] for k in lanes[0]]
        probe = HierarchicalCore(kind(config), 1, autoreset, worker)
        self.config, self.scenario = probe.config, probe.scenario
        self.num_agents, self.num_obstacles = probe.num_agents, probe.num_obstacles
        self.obs_dim, self.act_dim = probe.obs_dim, probe.act_dim
        robots = probe.num_agents + probe.num_obstacles
        layout = _layout(num_fields, self.num_agents, robots, self.obs_dim, self.act_dim)
        self._processes: list[Any] = []
        self._conns: list[Connection] = []
        if len(lanes) == 1:
            buffer: Any = bytearray(_places(layout)[1])
        else:
            context = multiprocessing.get_context("forkserver")
            context.set_forkserver_preload([__name__])
            buffer = context.RawArray(ctypes.c_ubyte, _places(layout)[1])
        self._arrays = _arrays(buffer, layout)
        self._lane = _Lane.build(kind, config, first, autoreset, worker, self._arrays)
        self._finalizer = weakref.finalize(self, _stop, self._processes, self._conns)
        for shards in lanes[1:]:
            mine, theirs = context.Pipe()
            lane = (kind, config, [bounds[k] for k in shards], autoreset, worker)
            process = context.Process(target=_serve, args=(theirs, buffer, layout, lane), daemon=True)
            process.start()
            theirs.close()
            self._processes.append(process)
            self._conns.append(mine)
        self.control_steps, self._broken = 0, None  # _broken: why commands are refused
        self._await()

    # -- the commands ------------------------------------------------------------------------------------

    def _send(self, command: str, seeds: list[int | None]) -> list[dict[str, np.ndarray] | None]:
        """Run ``command`` on every lane, this process's while the workers run theirs; the shards' episode
        statistics in shard order."""
        if self._broken is not None:
            raise RuntimeError(f"{self._broken}; close() this core and build a new one")
        shard_seeds_of = [[seeds[k] for k in shards] for shards in self._lanes]
        self._broken = f"ShardedCore: a {command!r} failed part-way"
        for conn, lane_seeds in zip(self._conns, shard_seeds_of[1:], strict=True):
            conn.send((command, lane_seeds))
        try:
            stats = self._lane.run(command, shard_seeds_of[0])
        finally:
            replies = self._await()
        self._broken = None
        self.control_steps = max([self._lane.control_steps, *(steps for _, steps in replies)])
        return stats + [entry for lane_stats, _ in replies for entry in lane_stats]

    def _await(self) -> list[Any]:
        """Every worker's reply to the last command; a RuntimeError carries a worker's traceback."""
        replies, failed = [], None
        for k, conn in enumerate(self._conns, start=1):
            try:
                status, reply = conn.recv()
            except EOFError:  # a script without ``if __name__ == "__main__":`` (workers import it), ...
                status, reply = "error", f"the worker process exited (code {self._processes[k - 1].exitcode})"
            if status == "error" and failed is None:
                a, b = self._bounds[self._lanes[k][0]][0], self._bounds[self._lanes[k][-1]][1]
                failed = f"shard worker {k} (fields {a} to {b - 1}) failed:\n{reply}"
            replies.append(reply)
        if failed is not None:
            raise RuntimeError(failed)
        return replies

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start a new episode in every field, each shard from its seed of ``seed`` (``shard_seeds``).
        Returns the observations (N, M, obs_dim)."""
        self._send("reset", shard_seeds(seed, len(self._bounds)))
        return self._arrays["obs"].copy()

    def step(self, action: np.ndarray) -> StepResult:
        """One manager decision in every field (``HierarchicalCore.step``): ``action`` (N, M, A) float64."""
        if not self._arrays["active"].any():
            raise RuntimeError("step() with every episode finished: call reset() first")
        np.copyto(self._arrays["action"], action)
        # This process's shards always give their statistics, empty or not: the concatenation's dtypes.
        ended = [entry for entry in self._send("step", [None] * len(self._bounds)) if entry is not None]
        a = self._arrays
        task = {key: np.concatenate([entry[key] for entry in ended]) for key in ended[0]}
        obs = a["obs"].copy()
        info = {key: a[key].copy() for key in _INFO}
        # Where no robot left, no field was reset: the last observations are the new ones, one array for
        # both as a core gives them (the largest copy of the step, spared on most steps).
        info |= {
            "subgoal": a["subgoal"].copy(),
            "final_obs": a["final_obs"].copy() if len(task["field"]) else obs,
            "task": task,
        }
        return StepResult(obs, *(a[key].copy() for key in _RESULT), info)

    def observe(self, fields: np.ndarray | None = None) -> np.ndarray:
        """Manager observations (F, M, obs_dim) float32 of ``fields`` (default all)."""
        obs = self._arrays["obs"]
        return obs.copy() if fields is None else obs[fields]

    def close(self) -> None:
        """Stop the worker processes (again: nothing)."""
        self._finalizer()

    @property
    def local_cores(self) -> list[HierarchicalCore]:
        """The shards' cores this process steps (all of them on one core), in field order."""
        return self._lane.cores

    # -- the state, as copies ------------------------------------------------------------------------------

    @property
    def done(self) -> np.ndarray:
        """(N,) bool: no robot is left in the field's episode."""
        return ~self._arrays["active"].any(axis=1)

    def __getattr__(self, name: str) -> np.ndarray:
        # ``active``, ``steps``, ``decisions``, ``subgoal``: copies of the shards' counters after the last
        # command (a core replaces its arrays; a caller may keep these).
        if name in _COUNTERS and "_arrays" in self.__dict__:
            return self._arrays[name].copy()
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def target(self) -> np.ndarray:
        self._send("state", [None] * len(self._bounds))
        return self._arrays["target"].copy()

    @property
    def state(self) -> RobotState:
        self._send("state", [None] * len(self._bounds))
        return RobotState(*(self._arrays[key].copy() for key in _ROBOTS))


def close_core(core: HierarchicalCore | ShardedCore) -> None:
    """Stop a sharded core's worker processes; a core of this process has none."""
    if isinstance(core, ShardedCore):
        core.close()


def batched_core(
    task: TaskConfig | Scenario,
    num_fields: int,
    autoreset: bool = True,
    worker: Any = None,
    threads: Threads = 1,
) -> HierarchicalCore | ShardedCore:
    """N fields on ``threads`` cores: one ``HierarchicalCore`` where they are one shard (nothing to share
    out), else a ``ShardedCore``."""
    resolve_threads(threads)
    if len(block_groups(num_fields, SHARD_BLOCKS)) == 1:
        return HierarchicalCore(task, num_fields, autoreset, worker)
    return ShardedCore(task, num_fields, autoreset, worker, threads)


__all__ = ["ShardedCore", "Threads", "batched_core", "close_core", "resolve_threads", "shard_seeds"]
