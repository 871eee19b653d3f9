"""Managers by name and their comparison on the same seeded episodes.

A manager is a scripted planner ("direct", "sampling", "trajectory", with settings of its own where given:
``sampling+trapped=brake``, ``hier_ssl.envs.planners.planner_spec``) or a training run directory, loaded
as a numpy policy ``obs (B, O) -> actions (B, A)`` for ``hier_ssl.evaluation.evaluate``. A run directory
(``hier_ssl.runs.train``) holds ``config.yaml`` and ``best_actor.pt``, the policy that scored best on the
selection episodes (SAC always; PPO runs before model selection existed only have rsl-rl's
``model_<iteration>.pt`` files, and the latest is used). ``compare`` evaluates several managers on one task's
or scenario's episodes.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hier_ssl.config import ScenarioConfig, TaskConfig, TrainConfig
from hier_ssl.envs import env_config, make_scenario, task_config
from hier_ssl.envs.planners import is_planner, make_planner
from hier_ssl.evaluation.evaluate import Policy, evaluate
from hier_ssl.evaluation.figures import label_outcomes
from hier_ssl.evaluation.report import make_record
from hier_ssl.manager.planners import PLANNERS
from hier_ssl.worker import worker_name


def manager_name(spec: str | Path) -> str:
    """How a manager is labelled in tables and figures: the planner's name or the run folder's name."""
    return str(spec) if is_planner(spec) else Path(spec).resolve().name


def run_config(run_dir: str | Path) -> TrainConfig:
    """The TrainConfig a run was trained with; ValueError if ``run_dir`` is neither a planner nor a run."""
    # here, not at the top: torch, for run directories alone
    from hier_ssl.checkpoints.actor import run_config as saved_config

    if not Path(run_dir).is_dir():
        known = ", ".join(PLANNERS)
        raise ValueError(f"manager {str(run_dir)!r} is neither a planner ({known}) nor a run directory")
    return saved_config(run_dir)


def load_manager(
    spec: str | Path,
    config: TaskConfig,
    which: str = "best",
    sample: bool = False,
    seed: int = 0,
    worker: Any = None,
) -> Policy:
    """The manager ``spec`` (planner name or run directory) as a numpy policy acting in the task or
    scenario ``config``, one row per live robot. A run acts with its ``which`` checkpoint ("best", the one
    model selection kept, or "final", the one training ended with) and its mean action, or with ``sample``
    actions drawn from its policy (seeded by ``seed``; the paper's test script samples). A planner is
    deterministic; it reads the limits of ``worker`` (an object of the worker protocol) where given, else
    of the worker ``config`` names.

    Raises ValueError when a run's network does not fit the task's observation or action size (e.g. a
    manager trained without obstacles evaluated on the Obstacle task) or has no such checkpoint.
    """
    if is_planner(spec):
        return make_planner(str(spec), config, worker)
    # here, not at the top: torch, for run directories alone
    from hier_ssl.policies.actor import load_policy

    run_dir = Path(spec)
    own, acting = make_scenario(run_config(run_dir).task_config), make_scenario(config)
    trained, wanted = (own.obs_dim, own.act_dim), (acting.obs_dim, acting.act_dim)
    if trained != wanted:
        raise ValueError(
            f"{run_dir} was trained with observations/actions of size {trained}, "
            f"the environment it is asked to act in has {wanted}"
        )
    return load_policy(run_dir, sample=sample, seed=seed, which=which)


PLANNER_FRAME_SKIP = 16  # the paper's FSCAPS decision period, unless --frame-skip says otherwise
# The keys that fix a manager's interface: a run acts in any task with its own values of these.
INTERFACE_KEYS = ("action_form", "action_frame", "observation", "neighbours")


def manager_env(
    spec: str | Path,
    task: str | None = None,
    frame_skip: int | None = None,
    worker: str | None = None,
    given: TaskConfig | None = None,
) -> TaskConfig:
    """The task or scenario to evaluate ``spec`` in. With ``given``, that one (a run acting with its own
    ``INTERFACE_KEYS``, a planner in the field frame); otherwise a run's own, or for a planner the paper
    ``task``'s default environment (``hier_ssl.envs.env_config``) deciding every ``PLANNER_FRAME_SKIP``
    control steps. ``task`` (paper tasks), ``frame_skip`` and ``worker`` override what these give."""
    overrides: dict[str, Any] = {}
    if frame_skip is not None:
        overrides["frame_skip"] = frame_skip
    if worker is not None:
        overrides["worker"] = worker
    if given is not None:
        if is_planner(spec):
            # A planner's sub-goals are field poses; the target frame (a run's choice) reaches half the
            # field's length from the target and clipped the far ones (crowd: `sampling` 97.4 % against 99.0).
            overrides["action_frame"] = "field"
        else:
            own = run_config(spec).task_config
            overrides |= {key: getattr(own, key) for key in INTERFACE_KEYS}
        return given.model_copy(update=overrides)
    if is_planner(spec):
        overrides.setdefault("frame_skip", PLANNER_FRAME_SKIP)
        return env_config(task=task or "proposed", **overrides)
    base = run_config(spec).task_config
    if task is not None and task != base.scenario_name:
        overrides["task"] = task
    return task_config(base, **overrides) if overrides else base


@dataclass
class Evaluation:
    """One manager evaluated: its label, task config, the JSON ``record``, ``evaluate``'s ``result`` and
    the worker's label (``env.worker``, or ``module:Class`` for a worker given as an object)."""

    name: str
    env: TaskConfig
    record: dict[str, Any]
    result: dict[str, Any]
    worker: str


def worker_apart(worker: Any) -> tuple[str | None, Any]:
    """(spec, object): a worker spec string or run directory, or None, stays a spec for the task config;
    an object, class or factory of the worker protocol is handed to the core as it is."""
    if worker is None or isinstance(worker, (str, os.PathLike)):
        return (None if worker is None else os.fspath(worker)), None
    return None, worker


def compare(
    specs: Sequence[str | Path],
    config: TaskConfig | None = None,
    *,
    task: str | None = None,
    workers: Sequence[Any] = (None,),
    episodes: int = 1000,
    seed: int = 0,
    frame_skip: int | None = None,
    record: Sequence[int] = (),
    progress: bool = False,
    which: str = "best",
    sample: bool = False,
) -> list[Evaluation]:
    """Evaluate every manager under every worker on the same seeded episodes (same starts, targets and
    obstacle commands). Managers are all loaded before any is evaluated, so a bad name fails at once.
    Runs act with their ``which`` checkpoint, sampling their actions with ``sample`` (``load_manager``);
    records say which ("policy": "best" | "final", "actions": "mean" | "sampled"; planners "-").

    Every manager acts in ``config`` when it is given (runs with their own ``INTERFACE_KEYS``), and in the
    first run's scenario when that run was trained on one. Otherwise runs keep their own environment and
    planners act in the first run's (its task, starts, obstacles and decision period, with ``task``,
    ``frame_skip`` and the worker applied as to the run), so they meet that run's episodes; without a run
    they take the paper ``task``'s default environment (default "proposed"). Figures are per robot.
    Each evaluation's ``result`` carries ``trajectories`` of the ``record`` episodes, each with its
    robots' ``outcome`` ("success", "collision", "foul", "timeout") and ``cpad`` added, for figures. With
    ``progress`` each evaluation shows a progress bar on stderr.

    ``workers`` are specs (``"paper"``, ``"my_pkg.control:Ctrl+latency=2"``, a run directory), None (each
    manager's own), or Python objects of the worker protocol (their classes or factories too), labelled
    ``module:Class`` in records and tables (``hier_ssl.worker.worker_name``).
    """
    runs = [spec for spec in specs if not is_planner(spec)]
    first = run_config(runs[0]).task_config if runs else None
    if config is None and isinstance(first, ScenarioConfig):
        config = first
    if task is None and config is None and first is not None:  # every row on the first run's task
        task = first.scenario_name
    # Planners act where the first run acts (not in the task's defaults): one episode set for every row.
    planners_in = config if config is not None or not runs else manager_env(runs[0], task, frame_skip)
    jobs = []
    for spec in specs:
        for worker in workers:
            worker_spec, obj = worker_apart(worker)
            given = planners_in if is_planner(spec) else config
            acting = manager_env(spec, task, frame_skip, worker_spec, given=given)
            label = acting.worker if obj is None else worker_name(obj)
            policy = load_manager(spec, acting, which, sample, seed, obj)
            labels = ("-", "-") if is_planner(spec) else (which, "sampled" if sample else "mean")
            jobs.append((manager_name(spec), acting, policy, obj, label, labels))
    evaluations = []
    for i, (name, acting, policy, obj, label, (checkpoint, actions)) in enumerate(jobs):
        bar = f"{name} ({i + 1}/{len(jobs)})" if progress else None
        result = evaluate(policy, acting, episodes, seed, record=record, worker=obj, progress=bar)
        per = result["per_robot"]
        label_outcomes(result, per["success"], per["collision"], per["cpad"], per.get("foul"))
        context = {
            "worker": label,
            "task": acting.scenario_name,
            "frame_skip": acting.frame_skip,
            "seed": seed,
            "robots": result["robots"],
            "field_success_rate": result["field_success_rate"],
            "policy": checkpoint,
            "actions": actions,
        }
        evaluations.append(Evaluation(name, acting, make_record(name, result, **context), result, label))
    return evaluations


__all__ = [
    "INTERFACE_KEYS",
    "PLANNERS",
    "Evaluation",
    "compare",
    "is_planner",
    "load_manager",
    "manager_env",
    "manager_name",
    "run_config",
    "worker_apart",
]
