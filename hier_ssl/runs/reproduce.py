"""``hier-ssl reproduce``: train the paper's twelve configurations in both families, evaluate every run on the
same episodes beside the scripted planners, and write the paper's tables with ours beside them.

Families (``FAMILIES``): "paper", the public code's settings (``configs/paper/<task>/<setup>.yaml``), and
"defaults", ours (``configs/<task>/<setup>.yaml``). Runs live in ``out/runs/<name>-s<seed>/`` and train
through ``hier_ssl.runs.launch`` (in turn, as local processes or as Ray Tune trials), which skips finished
runs, resumes killed ones and trains the rest; with ``train=False`` only finished runs are evaluated, so the
tables can be written while long runs go on. Evaluations are cached in ``out/evals/``.

Every manager of a task plays the same ``episodes`` episodes (seed ``eval_seed``) drawn as the paper's public
code draws them (its family's config: start 0.2 m from the target, the obstacle on the midpoint); each run
acts with its own interface (observation, action form and frame, frame skip, worker). Writes
``results/paper-tables.md`` and ``.csv`` (``hier_ssl.evaluation.paper_tables``) and
``results/fig3-<task>.png``; rows of an earlier ``paper-tables.csv`` that this plan does not evaluate
are kept, so ``only`` reruns a few rows of the committed tables (``reproduce``).
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hier_ssl.config import TaskConfig, TrainConfig
from hier_ssl.config.files import apply_overrides, load_yaml
from hier_ssl.config.files import config_dir as shipped_configs
from hier_ssl.config.launch_options import LaunchOptions
from hier_ssl.envs import parse_config
from hier_ssl.evaluation.compare import load_manager
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.evaluation.figures import figure3, label_outcomes, pick_episode
from hier_ssl.evaluation.paper_tables import (
    SETUPS,
    TASKS,
    Row,
    csv_text,
    header,
    header_episodes,
    markdown,
    paper_record,
    read_csv,
    summarise,
)
from hier_ssl.evaluation.report import make_record
from hier_ssl.runs.eval_cache import cached_record
from hier_ssl.runs.jobs import Job
from hier_ssl.runs.launch import launch
from hier_ssl.runs.train import EVAL_FILE
from hier_ssl.world.field import get_field

FAMILIES = {"paper": "paper/{task}/{setup}.yaml", "defaults": "{task}/{setup}.yaml"}
FAMILY_TITLES = {"paper": "paper family", "defaults": "defaults"}
# How each family's runs are evaluated, as (checkpoint, sampled actions): the paper's protocol first.
VARIANTS = {
    "paper": (("final", True), ("final", False), ("best", False)),
    "defaults": (("best", False), ("final", False)),
}
PLANNER_ROWS = ("direct", "sampling", "trajectory")
# A setup's rows in table order, as (source, policy, actions): the paper's own, then each family's variants.
ROW_ORDER = (("paper", "final", "sampled"),) + tuple(
    (FAMILY_TITLES[family], which, "sampled" if sample else "mean")
    for family in FAMILIES
    for which, sample in VARIANTS[family]
)
# What fixes the episodes a manager plays (not how it acts): taken from the paper family's config.
EPISODE_KEYS = (
    "field",
    "obstacles",
    "min_start_distance",
    "allow_start_contact",
    "max_steps",
    "spawn_margin",
    "d_th",
    "theta_th_deg",
    "speed_th",
    "collision_distance",
    "dt",
    "substeps",
)


def default_seeds(family: str, setup: str) -> int:
    """Training seeds of a configuration: 3 for our defaults and for the paper family's FSCAPS rows, 1 for
    the paper family's other rows (a paper-budget run is about 25 minutes of one core)."""
    return 3 if family == "defaults" or setup == "fscaps" else 1


@dataclass(frozen=True)
class Planned:
    """One training run of the tables."""

    family: str
    task: str
    setup: str
    config: TrainConfig
    run_dir: Path


def select(only: Sequence[str] = ()) -> list[tuple[str, str]]:
    """(task, setup) of the paper's rows in its order, or of those ``only`` names ("proposed/fscaps",
    "proposed-fscaps", or a bare task for its four)."""
    every = [(task, setup) for task in TASKS for setup in SETUPS]
    if not only:
        return every
    wanted = set()
    for name in only:
        key = name.replace("-", "/", 1) if "/" not in name else name
        match = [c for c in every if key in (c[0], f"{c[0]}/{c[1]}")]
        if not match:
            known = ", ".join(f"{t}/{s}" for t, s in every)
            raise ValueError(f"--only {name!r}: not a paper configuration; known: {known}")
        wanted.update(match)
    return [c for c in every if c in wanted]


def plan(
    families: Sequence[str],
    only: Sequence[str] = (),
    seeds: int | None = None,
    out: Path = Path("runs/reproduce"),
    config_dir: str | Path | None = None,
    overrides: Sequence[str] = (),
) -> list[Planned]:
    """Every run the tables need, each config validated before anything trains. ``seeds`` overrides
    ``default_seeds``; seeds count up from each config's own."""
    root = Path(config_dir) if config_dir is not None else shipped_configs()
    runs = []
    for family in families:
        if family not in FAMILIES:
            raise ValueError(f"family {family!r}: expected one of {sorted(FAMILIES)}")
        for task, setup in select(only):
            path = root / FAMILIES[family].format(task=task, setup=setup)
            data = apply_overrides(load_yaml(path), list(overrides))
            base = int(data.get("seed", 0))
            for k in range(seeds or default_seeds(family, setup)):
                config = parse_config({**data, "seed": base + k})
                runs.append(
                    Planned(family, task, setup, config, out / "runs" / f"{config.name}-s{config.seed}")
                )
    return runs


def episodes_of(task: str, config_dir: str | Path | None = None) -> TaskConfig:
    """The paper family's environment of ``task``: whose episodes every manager of the table plays."""
    root = Path(config_dir) if config_dir is not None else shipped_configs()
    path = root / FAMILIES["paper"].format(task=task, setup="fscaps")
    return parse_config(load_yaml(path)).task_config


def acting_config(own: TaskConfig, episodes: TaskConfig) -> TaskConfig:
    """``own`` (how a manager acts) playing ``episodes``'s episodes."""
    return own.model_copy(update={key: getattr(episodes, key) for key in EPISODE_KEYS})


def evaluate_run(
    run: Planned, which: str, sample: bool, episodes: TaskConfig, count: int, seed: int, cache: Path
) -> dict[str, Any]:
    """The record of one run evaluated one way, from ``cache`` when it was evaluated so before (a cached
    record older than the run's eval.json is stale)."""
    actions = "sampled" if sample else "mean"
    path = cache / f"{run.run_dir.name}-{which}-{actions}-e{count}-s{seed}.json"

    def compute() -> dict[str, Any]:
        acting = acting_config(run.config.task_config, episodes)
        result = evaluate(load_manager(run.run_dir, acting, which, sample, seed), acting, count, seed)
        trained = json.loads((run.run_dir / EVAL_FILE).read_text())
        context = {"policy": which, "actions": actions, "seed": seed}
        context |= {
            "start_contact_rate": result["start_contact_rate"],
            "train_wall_s": trained.get("train_wall_s"),
        }
        return make_record(run.run_dir.name, result, **context)

    return cached_record(path, compute, newer_than=(run.run_dir / EVAL_FILE).stat().st_mtime)


def learned_rows(
    runs: Sequence[Planned], count: int, seed: int, cache: Path, config_dir: str | Path | None, progress: bool
) -> list[Row]:
    """The rows of the finished runs of ``runs`` (others are left out), every variant of each family."""
    rows = []
    for task in dict.fromkeys(run.task for run in runs):
        episodes = episodes_of(task, config_dir)
        for setup in dict.fromkeys(run.setup for run in runs if run.task == task):
            for family in FAMILIES:
                done = [r for r in runs if (r.task, r.setup, r.family) == (task, setup, family)]
                done = [r for r in done if (r.run_dir / EVAL_FILE).is_file()]
                for which, sample in VARIANTS[family] if done else ():
                    records = [evaluate_run(r, which, sample, episodes, count, seed, cache) for r in done]
                    actions = "sampled" if sample else "mean"
                    rows.append(summarise(task, setup, FAMILY_TITLES[family], which, actions, records))
                    if progress:
                        print(
                            f"  {task}/{setup} {family} {which} {actions}: {len(records)} run(s)", flush=True
                        )
    return rows


def planner_rows(
    tasks: Sequence[str], count: int, seed: int, config_dir: str | Path | None
) -> tuple[list[Row], dict[str, float]]:
    """The planners' rows of ``tasks`` (deciding every 16 control steps) and per task the share of its
    episodes that begin in contact."""
    rows, contact = [], {}
    for task in tasks:
        planner_env = episodes_of(task, config_dir).model_copy(update={"frame_skip": 16})
        for name in PLANNER_ROWS:
            result = evaluate(load_manager(name, planner_env), planner_env, count, seed)
            rows.append(summarise(task, "-", "planner", name, "-", [make_record(name, result)]))
            contact[task] = result["start_contact_rate"]
    return rows, contact


def _order(row: Row) -> tuple[int, int, int]:
    if row.source == "planner":
        return TASKS.index(row.task), len(SETUPS), PLANNER_ROWS.index(row.policy)
    return TASKS.index(row.task), SETUPS.index(row.setup), ROW_ORDER.index(row.key[2:])


def merge(configs: Sequence[tuple[str, str]], evaluated: Sequence[Row], old: Sequence[Row]) -> list[Row]:
    """The tables' rows but the planners', in table order: the learned rows ``evaluated``, those of ``old``
    (an earlier table's) whose key ``evaluated`` lacks, and the paper's own row of every (task, setup) of
    ``configs`` (the plan's) or of the learned rows."""
    fresh = {row.key for row in evaluated}
    kept = [r for r in old if r.source in FAMILY_TITLES.values() and r.key not in fresh]
    for row in kept:
        if row.task not in TASKS or row.setup not in SETUPS or row.key[2:] not in ROW_ORDER:
            raise ValueError(f"earlier paper-tables.csv: row {row.key} is not one reproduce writes")
    learned = [*evaluated, *kept]
    present = dict.fromkeys([*configs, *((r.task, r.setup) for r in learned)])
    paper = [summarise(t, s, "paper", "final", "sampled", [paper_record(t, s)]) for t, s in present]
    return sorted([*paper, *learned], key=_order)


def write_figures(
    runs: Sequence[Planned], results: Path, config_dir: str | Path | None, seed: int
) -> list[Path]:
    """Fig. 3 per task with a finished FSCAPS run in ``runs``: one episode (of the recorded ones most
    managers solve, the one where their paths differ most) played by each family's first finished FSCAPS
    run (paper family: final policy, sampled; defaults: best) and by the planners."""
    paths = []
    for task in dict.fromkeys(run.task for run in runs):
        episodes = episodes_of(task, config_dir)
        panels = []
        for family, (which, sample) in (("paper", ("final", True)), ("defaults", ("best", False))):
            done = [r for r in runs if (r.task, r.setup, r.family) == (task, "fscaps", family)]
            done = [r for r in done if (r.run_dir / EVAL_FILE).is_file()]
            if done:
                acting = acting_config(done[0].config.task_config, episodes)
                policy = load_manager(done[0].run_dir, acting, which, sample, seed)
                panels.append((f"{FAMILY_TITLES[family]} FSCAPS", acting, policy))
        if not panels:  # the planners alone would replace a figure an earlier run drew
            continue
        planner_env = episodes.model_copy(update={"frame_skip": 16})
        panels += [(name, planner_env, load_manager(name, planner_env)) for name in PLANNER_ROWS]
        recorded = []
        for name, acting, policy in panels:
            result = evaluate(policy, acting, 16, seed, record=range(16))
            per = result["per_robot"]
            label_outcomes(result, per["success"], per["collision"], per["cpad"])
            recorded.append((name, result["trajectories"]))
        j = pick_episode([ts for _, ts in recorded])
        title = f"{task}: episode {j} of seed {seed}"
        path = results / f"fig3-{task}.png"
        paths.append(
            figure3([(n, ts[j]) for n, ts in recorded], get_field(episodes.field), path, title=title)
        )
    return paths


def plot_curves(series: Sequence[tuple[str, str, Path]], title: str, path: Path) -> Path:
    """Selection curves (success and collision rate against transitions, i.e. vector steps x envs) of
    run directories, one line each from its ``curve.csv``; ``series`` is (label, line style, run_dir)."""
    # here, not at the top: matplotlib, for the curves alone
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.2), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2)
    for label, style, run_dir in series:
        rows = list(csv.DictReader((run_dir / "curve.csv").open()))
        x = [int(row["transitions"]) / 1e6 for row in rows]
        for ax, key in zip(axes, ("success_rate", "collision_rate"), strict=True):
            ax.plot(x, [100 * float(row[key]) for row in rows], style, label=label)
    for ax, name in zip(axes, ("selection success %", "selection collisions %"), strict=True):
        ax.set_title(f"{title}: {name}", fontsize=9)
        ax.set_xlabel("transitions (millions, log scale)", fontsize=8)
        ax.set_xscale("log")
        ax.tick_params(labelsize=7)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    return path


def write_curves(runs: Sequence[Planned], results: Path) -> list[Path]:
    """Per task, the selection curves of every finished or running FSCAPS run of both families: where a
    run learned, stalled or collapsed, which its final and best policies alone do not show."""
    paths = []
    for task in dict.fromkeys(run.task for run in runs):
        series = [
            (f"{FAMILY_TITLES[r.family]} s{r.config.seed}", "-" if r.family == "paper" else "--", r.run_dir)
            for r in runs
            if (r.task, r.setup) == (task, "fscaps") and (r.run_dir / "curve.csv").is_file()
        ]
        if series:
            paths.append(plot_curves(series, f"{task} FSCAPS", results / f"curves-{task}.png"))
    return paths


def train_runs(runs: Sequence[Planned], out: Path, options: LaunchOptions | None, progress: bool) -> None:
    """Bring every planned run to its end (``hier_ssl.runs.launch``: finished ones skipped, killed ones
    resumed), Ray Tune's records in ``out``/tune."""
    jobs = [Job(run.config, run.run_dir) for run in runs]
    launch(jobs, options or LaunchOptions(), progress=progress, tune_dir=out / "tune")


def reproduce(
    families: Sequence[str] = tuple(FAMILIES),
    only: Sequence[str] = (),
    seeds: int | None = None,
    out: str | Path = "runs/reproduce",
    results: str | Path = "results",
    episodes: int = 1000,
    config_dir: str | Path | None = None,
    overrides: Sequence[str] = (),
    eval_seed: int = 0,
    progress: bool = True,
    launch_options: LaunchOptions | None = None,
    train: bool = True,
) -> Path:
    """Train what is missing (unless ``train`` is False), evaluate every finished run, write
    ``results``/paper-tables.md, .csv and the figures; returns the Markdown file's path.

    The tables hold more than the plan's runs when ``results``/paper-tables.csv exists (an earlier table,
    on the same episodes: its Markdown must name the same ``episodes`` and ``eval_seed``): a learned row
    the plan evaluated replaces the earlier one of the same (task, setup, source, policy, actions), even
    with fewer seeds finished; the earlier learned rows the plan did not evaluate are kept as they were.
    The paper's own rows, the planners' and the share of starts in contact are written for every task
    the merged tables hold (the planners evaluated again), rows in the paper's order. Figures are drawn
    for the plan's tasks with a finished FSCAPS run; the Markdown links every figure of the tables' tasks
    found in ``results``."""
    out, results = Path(out), Path(results)
    runs = plan(families, only, seeds, out, config_dir, overrides)
    old = _earlier_rows(results, episodes, eval_seed)
    if train:
        train_runs(runs, out, launch_options, progress)
    if progress:
        print(f"evaluating on {episodes} episodes per task (seed {eval_seed})", flush=True)
    evaluated = learned_rows(runs, episodes, eval_seed, out / "evals", config_dir, progress)
    rows = merge([(run.task, run.setup) for run in runs], evaluated, old)
    tasks = list(dict.fromkeys(row.task for row in rows))
    planners, contact = planner_rows(tasks, episodes, eval_seed, config_dir)
    rows = sorted([*rows, *planners], key=_order)
    results.mkdir(parents=True, exist_ok=True)
    (results / "paper-tables.csv").write_text(csv_text(rows))
    write_figures(runs, results, config_dir, eval_seed)
    write_curves(runs, results)
    figures = [results / f"{kind}-{task}.png" for kind in ("fig3", "curves") for task in tasks]
    text = header(episodes, eval_seed, contact) + markdown(rows)
    text += "\n" + "\n".join(f"![{p.stem}]({p.name})" for p in figures if p.is_file()) + "\n"
    path = results / "paper-tables.md"
    path.write_text(text)
    return path


def _earlier_rows(results: Path, episodes: int, seed: int) -> list[Row]:
    """The rows of ``results``/paper-tables.csv, if any, checked to be of the same episodes as these."""
    table, report = results / "paper-tables.csv", results / "paper-tables.md"
    if not table.is_file():
        return []
    played = header_episodes(report.read_text()) if report.is_file() else None
    if played not in (None, (episodes, seed)):
        raise ValueError(
            f"{report}: its rows played {played[0]} episodes (seed {played[1]}), not {episodes} (seed "
            f"{seed}); evaluate alike or write to another --results folder"
        )
    return read_csv(table.read_text())


__all__ = [
    "EPISODE_KEYS",
    "FAMILIES",
    "VARIANTS",
    "Planned",
    "default_seeds",
    "merge",
    "plan",
    "plot_curves",
    "reproduce",
    "select",
    "train_runs",
]
