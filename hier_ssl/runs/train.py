"""Train a manager against a frozen worker, keep the best policy, evaluate it on held-out episodes.

A run directory holds: ``config.yaml`` (the full resolved config), TensorBoard events, ``model.pt`` and
``replay.pt`` (SAC, for ``--resume``) or ``model_*.pt`` (PPO), ``best_actor.pt`` (the actor that scored
best on the selection episodes), ``curve.csv`` (success rate against training wall time) and
``eval.json`` (the final evaluation, on episodes the selection never saw).
"""

from __future__ import annotations

import csv
import json
import os
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from hier_ssl.checkpoints.actor import BEST_ACTOR_FILE, CONFIG_FILE
from hier_ssl.checkpoints.tensors import load_checkpoint
from hier_ssl.config import ConfigError, TrainConfig, dump_config
from hier_ssl.config.files import load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.envs.gotopoint import GoToPointEnv, print_worker_summary, worker_summary
from hier_ssl.envs.vector import TorchVectorEnv, TorchView
from hier_ssl.evaluation.evaluate import Policy, evaluate
from hier_ssl.policies.actor import load_policy
from hier_ssl.policies.candidates import CandidateLearner, candidate_policy, missing_keys
from hier_ssl.policies.networks import sac_policy
from hier_ssl.policies.ppo import load_ppo, make_ppo_runner, ppo_policy
from hier_ssl.policies.sac_runner import MODEL_FILE, SACRunner, atomic_save

CURVE_FILE, EVAL_FILE = "curve.csv", "eval.json"
# Model selection and the final evaluation draw their episodes from different seeds, so the reported
# figures are not biased by having picked the checkpoint on them.
SELECTION_SEED, EVALUATION_SEED = 10_000, 20_000


def atomic_write_text(text: str, path: Path) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def resume_config(run_dir: Path) -> TrainConfig:
    """The config a run was started with; errors name the missing file."""
    for name in (CONFIG_FILE,):
        if not (run_dir / name).is_file():
            raise ConfigError(f"cannot resume {run_dir}: missing checkpoint file {run_dir / name}")
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


class _Selection:
    """Model selection: score the policy on the selection episodes, append the row to the learning curve
    and keep the best policy's state in ``best_actor.pt`` (``selection_score`` over the last
    ``selection_window`` rows)."""

    def __init__(
        self, config: TrainConfig, run_dir: Path, on_selection: Callable[[dict], None] | None = None
    ) -> None:
        self.config, self.run_dir, self.on_selection = config, run_dir, on_selection
        self.best: tuple[float, float] | None = None
        self.last_step = -1
        curve = run_dir / CURVE_FILE
        self.rows = list(csv.DictReader(curve.open())) if curve.is_file() else []
        if self.rows:
            window = config.selection_window
            self.best = max(selection_score(self.rows[: i + 1], window) for i in range(len(self.rows)))
            self.last_step = int(self.rows[-1]["step"])

    def record(
        self,
        policy: Policy,
        step: int,
        transitions: int,
        train_time_s: float,
        state: Callable[[], dict[str, Any]],
    ) -> dict[str, float]:
        """Score ``policy`` after ``step`` vector steps; ``state()`` is what ``best_actor.pt`` keeps."""
        cfg = self.config
        result = evaluate_run(policy, cfg, SELECTION_SEED + cfg.seed)
        row = {
            "step": step,
            "transitions": transitions,
            "train_time_s": round(train_time_s, 2),
            "success_rate": result["success_rate"],
            "collision_rate": result["collision_rate"],
            "episode_length_median": result["episode_length"]["median"],
            "cpad_median": result["cpad"]["median"],
        }
        curve = self.run_dir / CURVE_FILE
        new = not curve.is_file()
        with curve.open("a", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(row))
            if new:
                writer.writeheader()
            writer.writerow(row)
        self.last_step = step
        self.rows.append(row)
        score = selection_score(self.rows, self.config.selection_window)
        if self.best is None or score > self.best:
            self.best = score
            atomic_save(state(), self.run_dir / BEST_ACTOR_FILE)
        if self.on_selection is not None:
            self.on_selection(row)
        return {k: float(v) for k, v in row.items() if k not in ("step", "transitions")}

    def __call__(self, runner: SACRunner) -> dict[str, float]:
        """SACRunner's evaluation callback."""
        actor = runner.sac.actor
        return self.record(
            sac_policy(actor),
            runner.step,
            runner.num_transitions,
            runner.train_time_s,
            lambda: {"actor": actor.state_dict(), "step": runner.step},
        )


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
    torch.set_num_threads(config.threads)
    run_dir.mkdir(parents=True, exist_ok=True)
    if not resume:
        atomic_write_text(dump_config(config), run_dir / CONFIG_FILE)
    if config.kind == "worker":
        return _train_worker(config, run_dir, resume)
    if config.algo == "candidates":
        policy, train_wall_s = _train_candidates(config, run_dir, resume, progress, on_selection)
    else:
        # SAC keeps the world on the CPU; its runner puts the learner on config.device.
        env_device = "cpu" if config.algo == "sac" else config.device
        env = TorchVectorEnv(config.task_config, config.num_envs, env_device)
        if config.algo == "sac":
            policy, train_wall_s = _train_sac(config, env, run_dir, resume, progress, on_selection)
        else:
            policy, train_wall_s = _train_ppo(config, env, run_dir, resume, on_selection=on_selection)
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
    atomic_write_text(json.dumps(summary, indent=2) + "\n", run_dir / EVAL_FILE)
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


def _train_sac(
    config: TrainConfig, env: TorchView, run_dir: Path, resume: bool, progress: bool, on_selection=None
):
    transitions = config.total_steps * config.num_envs
    if transitions < config.sac.learning_starts:
        warnings.warn(
            f"this run collects total_steps {config.total_steps} x num_envs {config.num_envs} = "
            f"{transitions} transitions, fewer than sac.learning_starts = {config.sac.learning_starts}: it "
            "only takes warm-up actions and never updates the policy; raise total_steps or lower "
            "sac.learning_starts",
            stacklevel=3,
        )
    selection = _Selection(config, run_dir, on_selection)
    runner = SACRunner(
        env,
        config.sac,
        run_dir,
        seed=config.seed,
        device=config.device,
        eval_interval=config.eval_interval,
        eval_callback=selection,
        progress=progress,
        save_interval=config.save_interval,
    )
    if resume:
        runner.load(run_dir)
    runner.learn(config.total_steps)
    runner.close()
    return sac_policy(runner.sac.actor), runner.train_time_s


def _train_candidates(config: TrainConfig, run_dir: Path, resume: bool, progress: bool, on_selection=None):
    """The classifier or scorer over the planner's candidates (``hier_ssl.policies.candidates``): DAgger,
    then PPO."""
    learner = CandidateLearner(config, run_dir, _Selection(config, run_dir, on_selection).record, progress)
    saved = load_checkpoint(run_dir / MODEL_FILE) if resume else None
    if saved is not None and (missing := missing_keys(saved)):
        raise ConfigError(f"cannot resume {run_dir}: {run_dir / MODEL_FILE} lacks {missing}")
    learner.learn(saved)
    return candidate_policy(learner.manager), learner.train_time


def _train_ppo(
    config: TrainConfig, env: TorchView, run_dir: Path, resume: bool, select: bool = True, on_selection=None
):
    """PPO through rsl-rl. With ``select`` (managers) the policy is scored on the selection episodes at
    every rsl-rl checkpoint (after the first iteration, then every ``eval_interval`` vector steps, and at
    the end) and the best one is returned, as for SAC; without it checkpoints follow ``save_interval``."""
    steps_per_iteration = config.ppo.num_steps_per_env
    every = (config.eval_interval if select else config.save_interval) // steps_per_iteration
    torch.manual_seed(config.seed)  # the networks' initial weights and the policy's exploration noise
    runner = make_ppo_runner(
        env, config.ppo, str(run_dir), config.device, seed=config.seed, save_interval=max(1, every)
    )
    if resume:
        saved = sorted(run_dir.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))
        if not saved:
            raise ConfigError(f"cannot resume {run_dir}: no PPO checkpoint model_*.pt in it")
        load_ppo(runner, saved[-1])
        runner.current_learning_iteration += 1  # rsl-rl saves the index of the last finished iteration
    policy, selection = ppo_policy(runner), _Selection(config, run_dir, on_selection)
    start, evaluating = time.perf_counter(), 0.0

    def state() -> dict[str, Any]:  # what runner.save writes, for load_ppo and load_actor
        return {**runner.alg.save(), "iter": runner.current_learning_iteration}

    def score(runner: Any) -> None:
        nonlocal evaluating
        step = (runner.current_learning_iteration + 1) * steps_per_iteration
        if step == selection.last_step:  # the final save repeats the last periodic one
            return
        began = time.perf_counter()
        selection.record(policy, step, step * env.num_envs, began - start - evaluating, state)
        evaluating += time.perf_counter() - began

    runner.on_save = score if select else None
    remaining = max(1, config.total_steps // steps_per_iteration) - runner.current_learning_iteration
    if remaining > 0:  # a resumed run that had finished has nothing left to learn
        runner.learn(remaining)
    runner.on_save = None
    return policy, time.perf_counter() - start - evaluating


def _train_worker(config: TrainConfig, run_dir: Path, resume: bool) -> dict[str, Any]:
    """``kind: worker``: PPO on the goToPoint task, then the worker beside the scripted ones."""
    env = GoToPointEnv(config.env, config.gotopoint, config.num_envs, config.device, seed=config.seed)
    policy, train_wall_s = _train_ppo(config, env, run_dir, resume, select=False)
    summary = worker_summary(policy, config, EVALUATION_SEED + config.seed)
    summary["train_wall_s"] = round(train_wall_s, 1)
    atomic_write_text(json.dumps(summary, indent=2) + "\n", run_dir / EVAL_FILE)
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
