"""Run many trainings: one after another, as local processes, or as Ray Tune trials
(``hier_ssl.runs.ray_tune``).

A job is a config and the run directory it trains into (``hier_ssl.runs.jobs``). Every backend picks a job
up where any other left it: finished and stopped runs are skipped, killed ones resume from their last
checkpoint. Rerunning a command after its driver was killed therefore finishes what is left.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hier_ssl.checkpoints.actor import CONFIG_FILE
from hier_ssl.config import ConfigError
from hier_ssl.config.launch_options import LaunchOptions
from hier_ssl.envs import load_config
from hier_ssl.runs.jobs import Job, run_job, run_state
from hier_ssl.runs.ray_tune import run_trials


class RunFailed(ChildProcessError):
    """Some runs (each in a process or trial of its own) raised or died; the message names each."""


def launch(
    jobs: Sequence[Job],
    options: LaunchOptions | None = None,
    progress: bool = True,
    tune_dir: Path | None = None,
) -> None:
    """Bring every job to an end: train what is new, resume what was killed, skip what is done.

    ``tune_dir``: where Ray Tune keeps its own records (default: ``tune`` beside the run directories'
    folder). Raises ``RunFailed`` after all others have ended if some runs failed.
    """
    names = [job.name for job in jobs]
    if len(set(names)) != len(names):  # trials, processes and log lines are known by these names
        raise ValueError(f"run directory names repeat: {sorted({n for n in names if names.count(n) > 1})}")
    options = options or LaunchOptions()
    jobs = [Job(options.apply(job.config), job.run_dir.resolve()) for job in jobs]
    for job in jobs:
        _check_same_config(job)
    todo = []
    for i, job in enumerate(jobs, 1):
        state = run_state(job.run_dir)
        if state in ("finished", "stopped"):
            print(f"[{i}/{len(jobs)}] {job.name}: {state}, skipped", flush=True)
        else:
            todo.append(job)
    if not todo:
        return
    if options.ray is not None:
        failures = run_trials(todo, options, tune_dir or todo[0].run_dir.parent.parent / "tune")
    elif (options.jobs or 1) == 1:
        failures = _run_sequentially(todo, progress)
    else:
        failures = _run_processes(todo, options.jobs)
    if failures:
        lines = "; ".join(f"{name}: {error}" for name, error in failures.items())
        raise RunFailed(f"{len(failures)} of {len(todo)} runs failed: {lines}")


def _check_same_config(job: Job) -> None:
    """A run directory started from another config would report one experiment under another's name."""
    if not (job.run_dir / CONFIG_FILE).is_file():
        return
    # Where it runs and what it says of itself, not what it learns: a run started before a config's
    # description changed resumes.
    ignored = {"threads", "device", "description"}
    saved = load_config(job.run_dir / CONFIG_FILE).model_dump(exclude=ignored)
    difference = _first_difference(saved, job.config.model_dump(exclude=ignored))
    if difference is not None:
        key, then, now = difference
        raise ConfigError(
            f"{job.run_dir} was started with {key}={then!r}, this command asks for {now!r}: "
            "use another --out, or remove that run directory"
        )


def _first_difference(a: Any, b: Any, key: str = "") -> tuple[str, Any, Any] | None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(a.keys() | b.keys()):
            found = _first_difference(a.get(k), b.get(k), f"{key}.{k}" if key else k)
            if found is not None:
                return found
        return None
    return None if a == b else (key, a, b)


def _start_line(job: Job) -> str:
    verb = "resuming" if run_state(job.run_dir) == "resumable" else "training"
    return f"{job.name}: {verb} in {job.run_dir}"


def _end_line(job: Job, seconds: float) -> str:
    return f"{job.name}: trained and evaluated in {seconds:.0f} s"


def _run_sequentially(jobs: Sequence[Job], progress: bool) -> dict[str, str]:
    """One run after another in this process; an error stops here, with its traceback."""
    for i, job in enumerate(jobs, 1):
        print(f"[{i}/{len(jobs)}] {_start_line(job)}", flush=True)
        start = time.perf_counter()
        run_job(job, progress=progress)
        print(f"[{i}/{len(jobs)}] {_end_line(job, time.perf_counter() - start)}", flush=True)
    return {}


def _run_processes(jobs: Sequence[Job], processes: int) -> dict[str, str]:
    """``processes`` runs at once, each in a fresh process; returns {run name: error} of the failed ones.

    A run that raises prints its traceback to stderr; one whose process dies leaves its last checkpoint.
    """
    # "spawn": a forked child would inherit torch's thread pools and locks from this process.
    context = multiprocessing.get_context("spawn")
    waiting, running = list(jobs), {}
    failures: dict[str, str] = {}
    while waiting or running:
        while waiting and len(running) < processes:
            job = waiting.pop(0)
            print(_start_line(job), flush=True)
            process = context.Process(target=run_job, args=(job,), name=job.name)
            process.start()
            running[process.sentinel] = (job, process, time.perf_counter())
        for sentinel in multiprocessing.connection.wait(list(running)):
            job, process, start = running.pop(sentinel)
            process.join()
            if process.exitcode == 0:
                print(_end_line(job, time.perf_counter() - start), flush=True)
            else:
                failures[job.name] = f"its process exited with status {process.exitcode}"
                print(f"{job.name}: failed ({failures[job.name]})", file=sys.stderr, flush=True)
    return failures


__all__ = ["RunFailed", "launch"]
