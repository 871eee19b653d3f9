"""Managers by name: a scripted planner ("direct", "sampling") or a training run directory, as a numpy
policy ``obs (N, O) -> actions (N, A)`` for ``hier_ssl.evaluate``, and ``compare``: several managers on
the same seeded episodes.

A run directory (``hier_ssl.train``) holds ``config.yaml`` and ``best_actor.pt``, the policy that scored
best on the selection episodes (SAC always; PPO runs before model selection existed only have rsl-rl's
``model_<iteration>.pt`` files, and the latest is used). ``compare_scenario`` does the same on a multi-robot
scenario, per robot.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hier_ssl.config import EnvConfig, ScenarioConfig, TrainConfig
from hier_ssl.evaluate import Policy, evaluate
from hier_ssl.manager.planners import PLANNERS, make_planner


def is_planner(spec: str | Path) -> bool:
    return str(spec) in PLANNERS


def manager_name(spec: str | Path) -> str:
    """How a manager is labelled in tables and figures: the planner's name or the run folder's name."""
    return str(spec) if is_planner(spec) else Path(spec).resolve().name


def run_config(run_dir: str | Path) -> TrainConfig:
    """The TrainConfig a run was trained with; ValueError if ``run_dir`` is neither a planner nor a run."""
    from hier_ssl.policies.actor import run_config as saved_config

    if not Path(run_dir).is_dir():
        known = ", ".join(PLANNERS)
        raise ValueError(f"manager {str(run_dir)!r} is neither a planner ({known}) nor a run directory")
    return saved_config(run_dir)


def load_manager(spec: str | Path, env_config: EnvConfig | ScenarioConfig) -> Policy:
    """The manager ``spec`` (planner name or run directory) as a numpy policy acting in ``env_config`` (an
    environment or a scenario; in a scenario the policy acts for every live robot, one row each).

    Raises ValueError when a run's network does not fit the environment's observation or action size
    (e.g. a manager trained without obstacles evaluated on the Obstacle task) or has no checkpoint.
    """
    if is_planner(spec):
        return make_planner(str(spec), env_config)
    import torch

    from hier_ssl.policies.actor import load_actor

    run_dir = Path(spec)
    config = run_config(run_dir)
    own = config.scenario or config.env
    trained, wanted = (own.obs_dim, own.act_dim), (env_config.obs_dim, env_config.act_dim)
    if trained != wanted:
        raise ValueError(
            f"{run_dir} was trained with observations/actions of size {trained}, "
            f"the environment it is asked to act in has {wanted}"
        )
    actor, _ = load_actor(run_dir)

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return actor(torch.as_tensor(obs, dtype=torch.float32)).numpy()

    return policy


PLANNER_FRAME_SKIP = 16  # the paper's FSCAPS decision period, unless --frame-skip says otherwise


def manager_env(
    spec: str | Path, task: str | None = None, frame_skip: int | None = None, worker: str | None = None
) -> EnvConfig:
    """The environment to evaluate ``spec`` in: a run's own ``env`` section, or for a planner the task's
    default environment (``hier_ssl.envs.env_config``) deciding every ``PLANNER_FRAME_SKIP`` control
    steps. ``task``, ``frame_skip`` and ``worker`` override what the run or the default gives."""
    from hier_ssl.envs import env_config

    overrides: dict[str, Any] = {}
    if frame_skip is not None:
        overrides["frame_skip"] = frame_skip
    if worker is not None:
        overrides["worker"] = worker
    if is_planner(spec):
        overrides.setdefault("frame_skip", PLANNER_FRAME_SKIP)
        return env_config(task=task or "proposed", **overrides)
    base = run_config(spec).env
    if task is not None and task != base.task:
        overrides["task"] = task
    return env_config(base, **overrides) if overrides else base


@dataclass
class Evaluation:
    """One manager evaluated: its label, environment, the JSON ``record`` and ``evaluate``'s ``result``."""

    name: str
    env: EnvConfig | ScenarioConfig
    record: dict[str, Any]
    result: dict[str, Any]


def compare(
    specs: Sequence[str | Path],
    task: str | None = None,
    workers: Sequence[str | None] = (None,),
    episodes: int = 1000,
    seed: int = 0,
    frame_skip: int | None = None,
    record: Sequence[int] = (),
    progress: bool = False,
) -> list[Evaluation]:
    """Evaluate every manager under every worker on the same seeded episodes (same starts, targets and
    obstacle commands). Managers are all loaded before any is evaluated, so a bad name fails at once.
    Without ``task``, runs keep their own and planners take the first run's (else "proposed").

    Each evaluation's ``result`` carries ``trajectories`` of the ``record`` episodes, each with its
    ``outcome`` ("success", "collision", "timeout") and ``cpad`` added, for figures.
    """
    from hier_ssl.report import label_outcomes, make_record

    if task is None:  # planners follow the first run's task, so every row shares the episodes
        runs = [spec for spec in specs if not is_planner(spec)]
        task = run_config(runs[0]).env.task if runs else None
    jobs = []
    for spec in specs:
        for worker in workers:
            env = manager_env(spec, task, frame_skip, worker)
            jobs.append((manager_name(spec), env, load_manager(spec, env)))
    evaluations = []
    for name, env, policy in jobs:
        result = evaluate(policy, env, episodes, seed, record=record)
        per = result["per_episode"]
        label_outcomes(result, per["success"][:, None], per["collision"][:, None], per["cpad"][:, None])
        context = {"worker": env.worker, "task": env.task, "frame_skip": env.frame_skip, "seed": seed}
        evaluations.append(Evaluation(name, env, make_record(name, result, **context), result))
        if progress:
            print(f"  {name} ({env.worker} worker): {result['eval_wall_s']:.1f} s", flush=True)
    return evaluations


# The keys that fix a shared manager's interface: a run acts in any scenario with its own values of these.
INTERFACE_KEYS = ("action_form", "action_frame", "neighbours")


def compare_scenario(
    specs: Sequence[str | Path],
    scenario: ScenarioConfig | None = None,
    episodes: int = 200,
    seed: int = 0,
    record: Sequence[int] = (),
    progress: bool = False,
) -> list[Evaluation]:
    """Evaluate every manager on the same seeded episodes of a multi-robot scenario, per robot.

    ``scenario`` defaults to the first run's training scenario. A run trained on a scenario acts in it with
    its own ``INTERFACE_KEYS``; planners read and write whatever the scenario uses. Recorded episodes get
    per-robot ``outcome`` and ``cpad`` lists (``hier_ssl.report.label_outcomes``).
    """
    from hier_ssl.evaluate_multi import evaluate_scenario
    from hier_ssl.report import label_outcomes, make_record

    runs = [spec for spec in specs if not is_planner(spec)]
    for run in runs:
        if run_config(run).scenario is None:
            task = run_config(run).env.task
            raise ValueError(f"{run} was trained on a paper task ({task}), not on a scenario")
    if scenario is None:
        if not runs:
            raise ValueError("planners alone need a scenario to act in (--scenario NAME_OR_YAML)")
        scenario = run_config(runs[0]).scenario
    jobs = []
    for spec in specs:
        acting = scenario
        if not is_planner(spec):
            own = run_config(spec).scenario
            acting = scenario.model_copy(update={k: getattr(own, k) for k in INTERFACE_KEYS})
        jobs.append((manager_name(spec), acting, load_manager(spec, acting)))
    evaluations = []
    for name, acting, policy in jobs:
        result = evaluate_scenario(policy, acting, episodes, seed, record=record)
        per = result["per_robot"]
        label_outcomes(result, per["success"], per["collision"], per["cpad"])
        context = {
            "worker": acting.worker,
            "task": acting.scenario,
            "frame_skip": acting.frame_skip,
            "seed": seed,
            "robots": result["robots"],
            "field_success_rate": result["field_success_rate"],
        }
        evaluations.append(Evaluation(name, acting, make_record(name, result, **context), result))
        if progress:
            print(f"  {name}: {result['eval_wall_s']:.1f} s", flush=True)
    return evaluations


__all__ = [
    "compare_scenario",
    "PLANNERS",
    "Evaluation",
    "compare",
    "is_planner",
    "load_manager",
    "manager_env",
    "manager_name",
    "run_config",
]
