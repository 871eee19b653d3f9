"""The Ray Tune backend of ``hier_ssl.runs.launch``: every job is one Tune trial.

A trial trains into its run directory exactly as a local run does (``hier_ssl.runs.jobs.run_job``), so the
run directories must lie on storage every node sees (a shared filesystem). Tune retries a trial whose
process died; the retry finds the run's ``config.yaml`` and last checkpoint and resumes from them, replay
buffer included. Each selection evaluation is reported to Tune (``step`` in vector steps, success and
collision rates, median episode length and CPAD, training time), which is what ASHA ranks trials on.

This is the only module that imports ray, and only when a command asks for ``--ray``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from hier_ssl.config.launch_options import LaunchOptions
from hier_ssl.runs.jobs import Job, mark_stopped, run_job, run_state

# Without them a Ray started here would look up this machine's network address (Ray's address discovery
# reaches out to a public address) and announce it; both keep every address on 127.0.0.1.
LOOPBACK_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
LOOPBACK = "127.0.0.1"
RAY_MISSING = '--ray needs Ray, which is not installed: pip install -e ".[ray]" (or pip install "ray[tune]")'
MAX_RETRIES = 3  # per trial, on top of its first attempt
ASHA_METRIC = "success_rate"


def import_ray(address: str) -> ModuleType:
    """``ray`` itself; a Ray started by us ("local") listens on loopback only. One-line error without it."""
    if address == "local":
        os.environ[LOOPBACK_ENV] = "0"
    # here, not at the top: ray, for --ray alone
    try:
        import ray
        import ray.tune  # noqa: F401  (the extra installs Tune; a bare ray lacks its dependencies)
    except ImportError:
        raise ValueError(RAY_MISSING) from None
    return ray


def connect(ray: ModuleType, address: str) -> bool:
    """Start ("local") or join ("auto", an address) Ray unless this process already did; returns whether
    it connected now (and should disconnect when done)."""
    if ray.is_initialized():
        return False
    if address == "local":
        ray.init(address="local", include_dashboard=False, _node_ip_address=LOOPBACK)
    else:
        ray.init(address=address)
    return True


def _trial(params: dict[str, Any], jobs: dict[str, Job], cwd: str) -> None:
    """One Tune trial: train (or resume) the job its params name, reporting each selection evaluation."""
    # here, not at the top: ray, for --ray alone
    from ray import tune

    if os.path.isdir(cwd):  # Tune starts trials in their own folder; configs may name relative paths
        os.chdir(cwd)
    run_job(jobs[params["run"]], report=tune.report)


def asha(jobs: Sequence[Job]) -> Any:
    """ASHA over vector steps: at a quarter and at half of the longest run's budget, a trial stops if its
    selection success rate is below the median of the trials that reached that rung before it.

    Both rungs lie before every run's end, and reaching ``max_t`` stops nothing (``stop_last_trials``):
    a trial stopped at its last selection evaluation would never write its final one, eval.json. The
    scheduler's ``stopped`` maps the runs it stopped to the step, so that an interrupted trial is not
    mistaken for one that ASHA stopped.
    """
    # here, not at the top: ray, for --ray alone
    from ray.tune.schedulers import ASHAScheduler, TrialScheduler

    class RecordingASHA(ASHAScheduler):
        def __init__(self, **kwargs: Any) -> None:
            super().__init__(**kwargs)
            self.stopped: dict[str, int] = {}

        def on_trial_result(self, controller: Any, trial: Any, result: dict) -> str:
            action = super().on_trial_result(controller, trial, result)
            if action == TrialScheduler.STOP:
                self.stopped[trial.config["run"]] = int(result["step"])
            return action

    if any(job.config.algo == "candidates" for job in jobs):
        raise ValueError(
            "--asha: algo 'candidates' counts rounds and iterations, not the vector steps ASHA's rungs use"
        )
    grace = max(
        max(job.config.eval_interval for job in jobs), max(job.config.total_steps for job in jobs) // 4
    )
    shortest = min(job.config.total_steps for job in jobs)
    if 2 * grace >= shortest:
        raise ValueError(
            f"--asha: runs of {shortest} vector steps are too short for rungs at {grace} and {2 * grace} "
            "(a quarter and half of the longest run, and at least one eval_interval)"
        )
    return RecordingASHA(
        time_attr="step",
        metric=ASHA_METRIC,
        mode="max",
        max_t=2 * grace,
        grace_period=grace,
        reduction_factor=2,
        stop_last_trials=False,
    )


def run_trials(jobs: Sequence[Job], options: LaunchOptions, storage: Path) -> dict[str, str]:
    """Run ``jobs`` as Tune trials, Tune's own records under ``storage``; returns {run name: error} of the
    trials that failed after their retries. Trials that ASHA stopped are marked so that reruns skip them."""
    assert options.ray is not None
    ray = import_ray(options.ray)
    # here, not at the top: ray, for --ray alone
    from ray import tune

    by_name = {job.name: job for job in jobs}
    trainable = tune.with_parameters(_trial, jobs=by_name, cwd=os.getcwd())
    resources = {"cpu": options.cpus_per_run, "gpu": options.gpus_per_run}
    scheduler = asha(jobs) if options.asha else None
    started = connect(ray, options.ray)
    try:
        tuner = tune.Tuner(
            tune.with_resources(trainable, resources),
            param_space={"run": tune.grid_search(list(by_name))},
            tune_config=tune.TuneConfig(
                max_concurrent_trials=options.jobs,
                scheduler=scheduler,
                trial_name_creator=lambda trial: trial.config["run"],
                trial_dirname_creator=lambda trial: trial.config["run"],
            ),
            run_config=tune.RunConfig(
                name=time.strftime("hier-ssl-%Y%m%d-%H%M%S"),
                storage_path=str(storage.resolve()),
                failure_config=tune.FailureConfig(max_failures=MAX_RETRIES),
                verbose=1,
            ),
        )
        results = tuner.fit()
    finally:
        if started:
            ray.shutdown()
    failures = {}
    stopped = scheduler.stopped if scheduler is not None else {}
    for result in results:
        job = by_name[result.config["run"]]
        if result.error is not None:
            failures[job.name] = _last_line(result.error)
        elif job.name in stopped:
            mark_stopped(job, stopped[job.name], f"ASHA on {ASHA_METRIC}")
            print(f"{job.name}: stopped early by ASHA at step {stopped[job.name]}", flush=True)
        elif run_state(job.run_dir) != "finished":
            failures[job.name] = "the trial ended without eval.json (interrupted? rerun to resume it)"
    return failures


def _last_line(error: BaseException) -> str:
    lines = [line for line in str(error).splitlines() if line.strip()]
    return f"{type(error).__name__}: {lines[-1] if lines else ''}"


__all__ = ["RAY_MISSING", "connect", "import_ray", "run_trials"]
