"""Run many trainings: one after another, as local processes, or as Ray Tune trials (``hier_ssl.ray_tune``).

A job is a config and the run directory it trains into (``hier_ssl.train``'s layout). The run directory is
the job's whole state, so every backend can pick a job up where any other left it: a directory with
``eval.json`` is finished and skipped, one with ``stopped.json`` was stopped early by a scheduler and is
skipped, one with ``config.yaml`` and a checkpoint resumes from it (replay buffer included), anything else
trains from the start. Rerunning a command after its driver was killed therefore finishes what is left.
"""

from __future__ import annotations

import json
import multiprocessing
import multiprocessing.connection
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hier_ssl.config import ConfigError, TrainConfig
from hier_ssl.envs import load_config
from hier_ssl.launch_options import LaunchOptions
from hier_ssl.policies.actor import CONFIG_FILE
from hier_ssl.policies.sac_runner import MODEL_FILE
from hier_ssl.train import EVAL_FILE, atomic_write_text, train

STOPPED_FILE = "stopped.json"
# Fault injection for the tests: "RUN_NAME@STEP" makes the process training RUN_NAME exit hard at its first
# selection evaluation at or after STEP, once (a marker file in the run directory remembers it did).
EXIT_ONCE_ENV = "HIER_SSL_EXIT_ONCE"
EXIT_MARKER = ".exited_once"

State = Literal["finished", "stopped", "resumable", "new"]


class RunFailed(ChildProcessError):
    """Some runs (each in a process or trial of its own) raised or died; the message names each."""


@dataclass(frozen=True)
class Job:
    """One training run: ``config`` trained into ``run_dir``."""

    config: TrainConfig
    run_dir: Path

    @property
    def name(self) -> str:
        return self.run_dir.name


def run_state(run_dir: Path) -> State:
    """What a run directory holds: a finished run, one stopped early, a killed one to resume, or nothing."""
    if (run_dir / EVAL_FILE).is_file():
        return "finished"
    if (run_dir / STOPPED_FILE).is_file():
        return "stopped"
    has_checkpoint = (run_dir / MODEL_FILE).is_file() or any(run_dir.glob("model_*.pt"))  # SAC or PPO
    if (run_dir / CONFIG_FILE).is_file() and has_checkpoint:
        return "resumable"
    return "new"


def run_job(job: Job, progress: bool = False, report: Callable[[dict], None] | None = None) -> dict[str, Any]:
    """Train ``job`` (or resume it, or read it if finished); returns its eval.json dict.

    ``report`` receives each selection evaluation's row (curve.csv's columns) as the run writes it. A
    resumed run continues with ``job.config``, which ``launch`` checked against the run's config.yaml.
    """
    state = run_state(job.run_dir)
    if state == "finished":
        return json.loads((job.run_dir / EVAL_FILE).read_text())
    hook = _with_exit_once(job, report)
    return train(job.config, job.run_dir, resume=state == "resumable", progress=progress, on_selection=hook)


def _with_exit_once(job: Job, report: Callable[[dict], None] | None) -> Callable[[dict], None] | None:
    """``report``, preceded by the fault injection of ``EXIT_ONCE_ENV`` when it names this run."""
    name, _, step = os.environ.get(EXIT_ONCE_ENV, "").partition("@")
    if name != job.name or (job.run_dir / EXIT_MARKER).exists():
        return report

    def hook(row: dict) -> None:
        if row["step"] >= int(step) and not (job.run_dir / EXIT_MARKER).exists():
            (job.run_dir / EXIT_MARKER).touch()
            os._exit(17)  # no cleanup, no exception: as a killed worker
        if report is not None:
            report(row)

    return hook


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
        from hier_ssl.ray_tune import run_trials

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
    ignored = {"threads", "device"}  # where it runs, not what it learns
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


def mark_stopped(job: Job, step: int, reason: str) -> None:
    """Record that a scheduler stopped ``job`` at ``step``, so that reruns skip it."""
    text = json.dumps({"step": step, "reason": reason}) + "\n"
    atomic_write_text(text, job.run_dir / STOPPED_FILE)


__all__ = ["Job", "RunFailed", "launch", "mark_stopped", "run_job", "run_state"]
