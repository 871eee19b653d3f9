"""One training job and what its run directory says of it (``hier_ssl.runs.train``'s layout), for every
backend of ``hier_ssl.runs.launch``: local processes and Ray Tune trials (``hier_ssl.runs.ray_tune``).

The run directory is the job's whole state, so every backend can pick a job up where any other left it: a
directory with ``eval.json`` is finished and skipped, one with ``stopped.json`` was stopped early by a
scheduler and is skipped, one with ``config.yaml`` and a checkpoint resumes from it (replay buffer
included), anything else trains from the start.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hier_ssl.checkpoints.actor import CONFIG_FILE
from hier_ssl.checkpoints.files import write_text
from hier_ssl.config import TrainConfig
from hier_ssl.policies.sac_runner import MODEL_FILE
from hier_ssl.runs.train import EVAL_FILE, train

STOPPED_FILE = "stopped.json"
# Fault injection for the tests: "RUN_NAME@STEP" makes the process training RUN_NAME exit hard at its first
# selection evaluation at or after STEP, once (a marker file in the run directory remembers it did).
EXIT_ONCE_ENV = "HIER_SSL_EXIT_ONCE"
EXIT_MARKER = ".exited_once"

State = Literal["finished", "stopped", "resumable", "new"]


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


def mark_stopped(job: Job, step: int, reason: str) -> None:
    """Record that a scheduler stopped ``job`` at ``step``, so that reruns skip it."""
    text = json.dumps({"step": step, "reason": reason}) + "\n"
    write_text(text, job.run_dir / STOPPED_FILE)


__all__ = [
    "EXIT_MARKER",
    "EXIT_ONCE_ENV",
    "STOPPED_FILE",
    "Job",
    "State",
    "mark_stopped",
    "run_job",
    "run_state",
]
