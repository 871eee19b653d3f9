"""Train a manager against a frozen worker, keep the best policy, evaluate it on held-out episodes.

A run directory holds: ``config.yaml`` (the full resolved config), TensorBoard events, ``model.pt`` and
``replay.pt`` (SAC, for ``--resume``) or ``model_*.pt`` (PPO), ``best_actor.pt`` (the actor that scored
best on the selection episodes), ``curve.csv`` (success rate against training wall time) and
``eval.json`` (the final evaluation, on episodes the selection never saw).
"""

from __future__ import annotations

import csv
import io
import json
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from hier_ssl.checkpoints.actor import BEST_ACTOR_FILE, CONFIG_FILE
from hier_ssl.checkpoints.files import write_text
from hier_ssl.checkpoints.tensors import save_checkpoint
from hier_ssl.config import ConfigError, TrainConfig, dump_config
from hier_ssl.config.files import load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.envs.gotopoint import GoToPointEnv, print_worker_summary, worker_summary
from hier_ssl.envs.shards import resolve_threads
from hier_ssl.envs.vector import TorchVectorEnv
from hier_ssl.evaluation.evaluate import Policy, evaluate
from hier_ssl.policies.actor import load_policy
from hier_ssl.policies.candidates import CandidateLearner
from hier_ssl.policies.learner import Checkpoint, Learner
from hier_ssl.policies.ppo import PPOLearner
from hier_ssl.policies.sac_runner import MODEL_FILE, SACRunner

CURVE_FILE, EVAL_FILE = "curve.csv", "eval.json"
# Model selection and the final evaluation draw their episodes from different seeds, so the reported
# figures are not biased by having picked the checkpoint on them.
SELECTION_SEED, EVALUATION_SEED = 10_000, 20_000


def resume_config(run_dir: Path) -> TrainConfig:
    """The config a run was started with; errors name the missing file."""
    if not (run_dir / CONFIG_FILE).is_file():
        raise ConfigError(f"cannot resume {run_dir}: missing checkpoint file {run_dir / CONFIG_FILE}")
    config = parse_config(load_yaml(run_dir / CONFIG_FILE))
    if config.algo in ("sac", "candidates") and not (run_dir / MODEL_FILE).is_file():
        raise ConfigError(f"cannot resume {run_dir}: missing checkpoint file {run_dir / MODEL_FILE}")
    return config


def selection_score(rows: list[dict[str, Any]], window: int) -> tuple[float, float]:
    """The score of the checkpoint that ends ``rows`` (curve rows, oldest first): the mean success rate of
    the last ``window`` of them, then their lower mean CPAD."""
    last = rows[-window:]
    return (
        sum(float(r["success_rate"]) for r in last) / len(last),
        -sum(float(r["cpad_median"]) for r in last) / len(last),
    )


class Selection:
    """Model selection at each checkpoint of a learner: score its policy on the selection episodes, add the
    row to the learning curve and keep the best policy's state in ``best_actor.pt`` (``selection_score``
    over the last ``selection_window`` rows). A resumed run's selection goes on from its curve."""

    def __init__(
        self, config: TrainConfig, run_dir: Path, on_selection: Callable[[dict], None] | None = None
    ) -> None:
        self.config, self.run_dir, self.on_selection = config, run_dir, on_selection
        self.best: tuple[float, float] | None = None
        curve = run_dir / CURVE_FILE
        self.rows = list(csv.DictReader(curve.open())) if curve.is_file() else []
        if self.rows:
            window = config.selection_window
            self.best = max(selection_score(self.rows[: i + 1], window) for i in range(len(self.rows)))

    def __call__(self, checkpoint: Checkpoint) -> dict[str, float]:
        """Score the checkpoint's policy; returns the curve row's figures (TensorBoard's ``eval/``)."""
        cfg = self.config
        result = evaluate_run(checkpoint.policy, cfg, SELECTION_SEED + cfg.seed)
        row = {
            "step": checkpoint.step,
            "transitions": checkpoint.transitions,
            "train_time_s": round(checkpoint.train_time_s, 2),
            "success_rate": result["success_rate"],
            "collision_rate": result["collision_rate"],
            "episode_length_median": result["episode_length"]["median"],
            "cpad_median": result["cpad"]["median"],
        }
        self.rows.append(row)
        curve = io.StringIO(newline="")
        writer = csv.DictWriter(curve, fieldnames=list(row))
        writer.writeheader()
        writer.writerows(self.rows)
        write_text(curve.getvalue(), self.run_dir / CURVE_FILE)
        score = selection_score(self.rows, self.config.selection_window)
        if self.best is None or score > self.best:
            self.best = score
            save_checkpoint(checkpoint.state(), self.run_dir / BEST_ACTOR_FILE)
        if self.on_selection is not None:
            self.on_selection(row)
        return {k: float(v) for k, v in row.items() if k not in ("step", "transitions")}


def evaluate_run(
    policy: Policy, config: TrainConfig, seed: int, progress: str | None = None
) -> dict[str, Any]:
    """``config.eval_episodes`` seeded episodes of the run's environment or scenario (per robot), with a
    progress bar labelled ``progress`` where given."""
    return evaluate(policy, config.task_config, config.eval_episodes, seed, progress=progress)


def train(
    config: TrainConfig,
    run_dir: Path,
    resume: bool = False,
    progress: bool = True,
    on_selection: Callable[[dict], None] | None = None,
) -> dict[str, Any]:
    """Train as ``config`` says into ``run_dir`` (or continue it), then evaluate the best and the final
    policy on held-out episodes; returns eval.json's dict (the best policy's figures, "final" the final's).

    ``on_selection`` receives each row of the learning curve (curve.csv's columns) once it is written.
    """
    threads = resolve_threads(config.threads)
    torch.set_num_threads(threads)
    run_dir.mkdir(parents=True, exist_ok=True)
    if not resume:
        write_text(dump_config(config), run_dir / CONFIG_FILE)
    if config.kind == "worker":
        return _train_worker(config, run_dir, resume)
    # The learners' fields (candidates plays its own); SAC keeps the world on the CPU, its runner puts the
    # learner on config.device.
    env = None
    if config.algo != "candidates":
        env_device = "cpu" if config.algo == "sac" else config.device
        env = TorchVectorEnv(config.task_config, config.num_envs, env_device, threads=threads)
    try:
        learner = _learner(config, run_dir, progress, env)
        if resume:
            learner.load(run_dir)
        learner.learn(_budget(config), Selection(config, run_dir, on_selection))
    finally:
        if env is not None:
            env.close()
    policy, train_wall_s = learner.policy(), learner.train_time_s
    # Both policies on the held-out episodes: the paper reports its final models, we keep the best.
    seed, held_out = EVALUATION_SEED + config.seed, f"held-out episodes ({config.eval_episodes})"
    final = evaluate_run(policy, config, seed, f"{held_out}, final policy" if progress else None)
    best = final
    if (run_dir / BEST_ACTOR_FILE).is_file():
        label = f"{held_out}, best policy" if progress else None
        best = evaluate_run(load_policy(run_dir, which="best"), config, seed, label)
    summary = {
        "policy": "best" if best is not final else "final",
        **_figures(best),
        "final": _figures(final),
        "episodes": best["episodes"],
        "train_wall_s": round(train_wall_s, 1),
        "task": config.task_config.scenario_name,
        "worker": config.task_config.worker,
        # Figures are per robot; "episodes" counts fields.
        "robots": best["robots"],
    }
    write_text(json.dumps(summary, indent=2) + "\n", run_dir / EVAL_FILE)
    return summary


def _figures(result: dict[str, Any]) -> dict[str, Any]:
    """What eval.json keeps of an evaluation (``hier_ssl.evaluation.evaluate.evaluate``'s dict)."""
    keys = ("success_rate", "collision_rate", "field_success_rate", "optimal_ratio_median")
    return {
        **{key: result[key] for key in keys},
        "episode_length_median": result["episode_length"]["median"],
        "cpad_median": result["cpad"]["median"],
        "cpad_public_median": result["cpad_public"]["median"],
        "episode_length": result["episode_length"],
        "cpad": result["cpad"],
    }


def _learner(config: TrainConfig, run_dir: Path, progress: bool, env: TorchVectorEnv | None) -> Learner:
    """The learner ``config.algo`` names, over ``env`` (fresh; None for candidates)."""
    if env is None:  # candidates plays its own fields: a fixed number per phase
        return CandidateLearner(config, run_dir, progress)
    if config.algo == "ppo":
        return PPOLearner(
            env,
            config.ppo,
            run_dir,
            config.device,
            seed=config.seed,
            checkpoint_interval=config.eval_interval,
        )
    _warn_if_only_warm_up(config)
    return SACRunner(
        env,
        config.sac,
        run_dir,
        seed=config.seed,
        device=config.device,
        eval_interval=config.eval_interval,
        progress=progress,
        save_interval=config.save_interval,
    )


def _budget(config: TrainConfig) -> int:
    """Where the learner stops, in its own steps (``hier_ssl.policies.learner.Checkpoint``)."""
    if config.algo == "candidates":
        return config.candidates.rounds + config.candidates.ppo.iterations
    return config.total_steps


def _warn_if_only_warm_up(config: TrainConfig) -> None:
    # One row, one transition a step, per robot of each field (a paper task's config has no num_agents).
    rows = config.num_envs * getattr(config.task_config, "num_agents", 1)
    transitions = config.total_steps * rows
    if transitions < config.sac.learning_starts:
        warnings.warn(
            f"this run collects total_steps {config.total_steps} x {rows} rows (num_envs {config.num_envs} "
            f"fields) = {transitions} transitions, fewer than sac.learning_starts = "
            f"{config.sac.learning_starts}: it only takes warm-up actions and never updates the policy; "
            "raise total_steps or lower sac.learning_starts",
            stacklevel=4,
        )


def _train_worker(config: TrainConfig, run_dir: Path, resume: bool) -> dict[str, Any]:
    """``kind: worker``: PPO on the goToPoint task, then the worker beside the scripted ones."""
    env = GoToPointEnv(config.env, config.gotopoint, config.num_envs, config.device, seed=config.seed)
    # No model selection: rsl-rl's checkpoints follow save_interval, and the final policy is the worker.
    learner = PPOLearner(
        env, config.ppo, run_dir, config.device, seed=config.seed, checkpoint_interval=config.save_interval
    )
    if resume:
        learner.load(run_dir)
    learner.learn(config.total_steps)
    summary = worker_summary(learner.policy(), config, EVALUATION_SEED + config.seed)
    summary["train_wall_s"] = round(learner.train_time_s, 1)
    write_text(json.dumps(summary, indent=2) + "\n", run_dir / EVAL_FILE)
    return summary


def print_summary(summary: dict[str, Any]) -> None:
    if summary.get("task") == "gotopoint":
        return print_worker_summary(summary)
    length, cpad = summary["episode_length"], summary["cpad"]
    several = summary.get("robots", summary["episodes"]) > summary["episodes"]
    robots = f" ({summary['robots']} robots)" if several else ""
    where = f"{summary['episodes']} episodes{robots}, task {summary['task']}, worker {summary['worker']}"
    print(f"| metric ({where}) | value |")
    print("|---|---|")
    print(f"| success rate | {100 * summary['success_rate']:.1f} % |")
    if several:
        print(f"| episodes every robot succeeded | {100 * summary['field_success_rate']:.1f} % |")
    print(f"| collision rate | {100 * summary['collision_rate']:.1f} % |")
    quartiles = f"{length['median']:.0f} ({length['q1']:.0f} - {length['q3']:.0f})"
    print(f"| episode length, median (Q1 - Q3) | {quartiles} |")
    print(f"| CPAD m, median (Q1 - Q3) | {cpad['median']:.3f} ({cpad['q1']:.3f} - {cpad['q3']:.3f}) |")
    print(f"| training wall time | {summary['train_wall_s']:.0f} s |")
    final = summary.get("final")
    if final is not None and summary.get("policy") == "best":
        print(
            f"(the {summary['policy']} policy of the selection curve; the final policy: "
            f"{100 * final['success_rate']:.1f} % success, {100 * final['collision_rate']:.1f} % collisions, "
            f"median length {final['episode_length_median']:.0f}, median CPAD {final['cpad_median']:.3f} m)"
        )
