"""``hier-ssl reproduce``: train the paper's 12 configurations (or some), evaluate them beside the scripted
planners on the same episodes, and write one ``report.md`` with the paper's numbers beside ours.

Layout under ``out``: ``runs/<name>-s<seed>/`` (one training run each, ``hier_ssl.train``), and per task
``<task>/table.{md,csv,tex}``, ``<task>/fig3.png``, ``<task>/eval.json``; ``report.md`` links them.
Resumable: the runs train through ``hier_ssl.launch`` (in turn, as local processes or as Ray Tune trials),
which skips finished runs, resumes killed ones and trains the rest.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hier_ssl.config import apply_overrides, load_yaml
from hier_ssl.config import config_dir as shipped_configs
from hier_ssl.envs import parse_config
from hier_ssl.launch import Job, launch
from hier_ssl.launch_options import LaunchOptions
from hier_ssl.report import SETUP_TITLES, SETUPS, TASKS
from hier_ssl.train import EVAL_FILE

PLANNER_ROWS = ("direct", "sampling")


def paper_configs(
    config_dir: str | Path | None = None, only: Sequence[str] = ()
) -> list[tuple[str, str, Path]]:
    """(task, setup, config path) of the paper's configurations, in the paper's order, or of those named
    in ``only`` ("proposed/fscaps" or "proposed-fscaps"; a bare task such as "obstacle" names its four).
    ``config_dir`` defaults to the shipped configs."""
    config_dir = Path(config_dir) if config_dir is not None else shipped_configs()
    every = [(task, setup, config_dir / task / f"{setup}.yaml") for task in TASKS for setup in SETUPS]
    if only:
        wanted = set()
        for name in only:
            key = name.replace("-", "/", 1) if "/" not in name else name
            match = [c for c in every if key in (c[0], f"{c[0]}/{c[1]}")]
            if not match:
                known = ", ".join(f"{t}/{s}" for t, s, _ in every)
                raise ValueError(f"--only {name!r}: not a paper configuration; known: {known}")
            wanted.update((t, s) for t, s, _ in match)
        every = [c for c in every if (c[0], c[1]) in wanted]
    for _, _, path in every:
        if not path.is_file():
            raise ValueError(f"config file not found: {path}")
    return every


def reproduce(
    only: Sequence[str] = (),
    seeds: int = 1,
    out: str | Path = "runs/reproduce",
    episodes: int = 1000,
    config_dir: str | Path | None = None,
    overrides: Sequence[str] = (),
    eval_seed: int = 0,
    progress: bool = True,
    launch_options: LaunchOptions | None = None,
) -> Path:
    """Train what is missing, evaluate everything, write ``out``/report.md; returns its path.

    ``seeds`` runs per configuration (training seeds config.seed, config.seed + 1, ...); ``overrides``
    are ``key=value`` settings applied to every config (e.g. ``total_steps=2000`` for a quick pass);
    ``launch_options`` say where the runs train (``hier_ssl.launch``: in turn, as processes, on Ray).
    """
    from hier_ssl.compare import compare
    from hier_ssl.report import write_evaluation

    if seeds < 1:
        raise ValueError(f"seeds must be >= 1, got {seeds}")
    out = Path(out)
    # Every config is validated before anything is trained.
    plans: list[tuple[str, str, Path]] = []
    jobs = []
    for task, setup, path in paper_configs(config_dir, only):
        data = apply_overrides(load_yaml(path), list(overrides))
        base_seed = int(data.get("seed", 0))
        for k in range(seeds):
            config = parse_config({**data, "seed": base_seed + k})
            jobs.append(Job(config, out / "runs" / f"{config.name}-s{config.seed}"))
            plans.append((task, setup, jobs[-1].run_dir))
    launch(jobs, launch_options or LaunchOptions(), progress=progress, tune_dir=out / "tune")

    sections = []
    for task in TASKS:
        runs = [(setup, run_dir) for t, setup, run_dir in plans if t == task]
        if not runs:
            continue
        print(f"evaluating the {task} managers on {episodes} episodes (seed {eval_seed})", flush=True)
        specs = [run_dir for _, run_dir in runs] + list(PLANNER_ROWS)
        evaluations = compare(
            specs,
            task=task,
            episodes=episodes,
            seed=eval_seed,
            record=range(min(16, episodes)),
            progress=True,
        )
        write_evaluation(evaluations, out / task, json_path=out / task / "eval.json", title=task)
        setups = [setup for setup, _ in runs] + list(PLANNER_ROWS)
        rows = [(task, s, e.record) for s, e in zip(setups, evaluations, strict=True)]
        sections.append(_section(task, rows, evaluations, [run_dir for _, run_dir in runs]))

    report = out / "report.md"
    report.parent.mkdir(parents=True, exist_ok=True)
    report.write_text(_header(episodes, eval_seed, seeds) + "\n".join(sections))
    return report


def _header(episodes: int, eval_seed: int, seeds: int) -> str:
    return (
        '# Reproduction of "Planning the path with Reinforcement Learning" (RoboCup SSL)\n\n'
        f"Every manager is evaluated on the same {episodes} seeded episodes per task (seed {eval_seed}): "
        "same starts, targets and obstacle commands. Learned managers act in their own training environment "
        "(frame skip, worker); the scripted planners `direct` (sub-goal = target) and `sampling` (sampled "
        "sub-goals, obstacles predicted at constant velocity, fastest collision-free bang-bang "
        "trajectory) decide every 16 control steps. "
        f"{seeds} training seed(s) per configuration.\n\n"
        "Cells are median (Q1 - Q3) over episodes; lengths in control steps of 25 ms (1200 = timeout). "
        "*Time / optimum*: episode time over the analytic minimum time to the target under the robot's "
        "speed and acceleration limits, median over successful episodes.\n\n"
        "**CPAD differs from the paper's column.** We compute CPAD as the paper defines it: the sum of "
        "the distances between consecutive (x, y) sub-goals, one per control step. The paper's public "
        "code, which produced its tables, takes sqrt(sum of squared distances) instead (never larger; "
        '`hier_ssl.manager.metrics.cpad(..., variant="public_code")`). Compare CPAD trends, not values.\n\n'
    )


def _section(
    task: str, rows: list[tuple[str, str, dict[str, Any]]], evaluations: list, runs: list[Path]
) -> str:
    from hier_ssl.report import markdown_table, paper_comparison

    lines = [
        f"## {task.capitalize()} task\n",
        paper_comparison(rows),
        "Full table:\n",
        markdown_table([e.record for e in evaluations]),
    ]
    trained = []
    for run_dir in runs:
        summary = json.loads((run_dir / EVAL_FILE).read_text()) if (run_dir / EVAL_FILE).is_file() else {}
        if "train_wall_s" in summary:
            trained.append(f"{run_dir.name} {summary['train_wall_s']:.0f} s")
    if trained:
        lines.append("Training wall time: " + ", ".join(trained) + ".\n")
    names = ", ".join(SETUP_TITLES.get(s, s) for _, s, _ in rows)
    lines.append(f"![{task}: {names}, one episode]({task}/fig3.png)\n")
    return "\n".join(lines) + "\n"


__all__ = ["paper_configs", "reproduce"]
