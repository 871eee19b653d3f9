"""``hier-ssl sweep``: one config trained over a grid of key values and seeds, then tabulated.

Every grid point x seed is one run directory ``out/runs/<name>-<key>=<value>...-s<seed>``, trained
through ``hier_ssl.runs.launch`` (in turn, as local processes, or as Ray Tune trials with optional ASHA), so
rerunning the same command skips finished runs and resumes killed ones. ``out/sweep.md`` and
``out/sweep.csv`` hold one row per run with its ``eval.json`` figures (held-out episodes).
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import re
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hier_ssl.config import ConfigError
from hier_ssl.config.files import apply_overrides, load_yaml
from hier_ssl.config.launch_options import LaunchOptions
from hier_ssl.envs import parse_config
from hier_ssl.runs.jobs import STOPPED_FILE, Job, run_state
from hier_ssl.runs.launch import launch
from hier_ssl.runs.train import CURVE_FILE, EVAL_FILE

TABLE_MD, TABLE_CSV = "sweep.md", "sweep.csv"
# (column, eval.json key, scale): rates in %, lengths in control steps, CPAD in m, wall time in s.
FIGURES = (
    ("success %", "success_rate", 100.0),
    ("collisions %", "collision_rate", 100.0),
    ("length median", "episode_length_median", 1.0),
    ("CPAD median m", "cpad_median", 1.0),
    ("train s", "train_wall_s", 1.0),
)


def parse_grid(items: Sequence[str]) -> dict[str, list[str]]:
    """``KEY=V1,V2,...`` strings as {key: [raw values]}. Commas inside brackets or braces do not split
    (``sac.hidden=[64,64],[256,256]`` is two values); values are parsed as YAML later, as ``--set``'s."""
    grid: dict[str, list[str]] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key or not raw:
            raise ConfigError(f"--grid {item!r}: expected KEY=V1,V2,...")
        if key in grid:
            raise ConfigError(f"--grid {key}: given twice")
        values, depth, current = [], 0, ""
        for char in raw:
            depth += (char in "[{") - (char in "]}")
            if char == "," and depth == 0:
                values.append(current)
                current = ""
            else:
                current += char
        values.append(current)
        if any(not v.strip() for v in values):
            raise ConfigError(f"--grid {item!r}: an empty value")
        grid[key] = [v.strip() for v in values]
    return grid


def _label(key: str, raw: str) -> str:
    """``key=value`` as a file-name part."""
    return f"{key}={re.sub(r'[^A-Za-z0-9.+-]+', '_', raw).strip('_')}"


def sweep_jobs(
    config: str | Path, grid: dict[str, list[str]], seeds: int, overrides: Sequence[str], out: Path
) -> list[tuple[dict[str, str], Job]]:
    """(grid point, job) for every point of ``grid`` x ``seeds``, each config validated."""
    if seeds < 1:
        raise ValueError(f"--seeds must be >= 1, got {seeds}")
    base = apply_overrides(load_yaml(config), list(overrides))
    base_seed = int(base.get("seed", 0))
    planned = []
    for values in itertools.product(*grid.values()):
        point = dict(zip(grid, values, strict=True))
        data = apply_overrides(base, [f"{k}={v}" for k, v in point.items()])
        for k in range(seeds):
            run = parse_config({**data, "seed": base_seed + k})
            name = "-".join([run.name, *(_label(k, v) for k, v in point.items()), f"s{run.seed}"])
            planned.append((point, Job(run, out / "runs" / name)))
    return planned


def sweep(
    config: str | Path,
    grid: dict[str, list[str]],
    seeds: int = 1,
    overrides: Sequence[str] = (),
    out: str | Path | None = None,
    launch_options: LaunchOptions | None = None,
    progress: bool = True,
) -> list[Path]:
    """Train every run of the sweep that is not done, then write its tables; returns their paths. An empty
    ``grid`` sweeps the seeds of the config alone.

    ``out`` defaults to ``runs/sweep/<config name>``: rerunning the same command resumes the same sweep.
    """
    if out is None:
        out = Path("runs") / "sweep" / parse_config(load_yaml(config)).name
    out = Path(out)
    planned = sweep_jobs(config, grid, seeds, overrides, out)
    launch([job for _, job in planned], launch_options or LaunchOptions(), progress, tune_dir=out / "tune")
    rows = [_row(point, job) for point, job in planned]
    out.mkdir(parents=True, exist_ok=True)
    (out / TABLE_CSV).write_text(_csv(rows))
    (out / TABLE_MD).write_text(_markdown(rows, list(grid), seeds))
    return [out / TABLE_MD, out / TABLE_CSV]


def _row(point: dict[str, str], job: Job) -> dict[str, Any]:
    """A run's table row: its grid values, seed, status and eval.json figures (blank if it has none)."""
    row: dict[str, Any] = {"run": job.name, **point, "seed": job.config.seed}
    state = run_state(job.run_dir)
    figures = {}
    if state == "finished":
        figures = json.loads((job.run_dir / EVAL_FILE).read_text())
        row["status"] = "finished"
    elif state == "stopped":
        step = json.loads((job.run_dir / STOPPED_FILE).read_text())["step"]
        curve = list(csv.DictReader((job.run_dir / CURVE_FILE).open()))
        success = float(curve[-1]["success_rate"]) if curve else float("nan")
        row["status"] = f"stopped at step {step} (selection success {100 * success:.1f} %)"
    else:
        row["status"] = "not finished"
    for column, key, scale in FIGURES:
        row[column] = round(scale * figures[key], 4) if key in figures else ""
    return row


def _csv(rows: list[dict[str, Any]]) -> str:
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return text.getvalue()


def _markdown(rows: list[dict[str, Any]], keys: list[str], seeds: int) -> str:
    """One row per run; with several seeds, also the median over each grid point's finished seeds."""
    lines = [
        "# Sweep\n",
        "Figures from each run's `eval.json` (held-out episodes; the policy that scored best on the "
        "selection episodes). Rates in %, episode length in 25 ms control steps, CPAD in m, training "
        "wall time in s.\n",
        _md_table(list(rows[0]), [list(r.values()) for r in rows]),
    ]
    if seeds > 1:
        points: dict[tuple, list[dict[str, Any]]] = {}
        for row in rows:
            points.setdefault(tuple(row[k] for k in keys), []).append(row)
        header = [*keys, "finished seeds", *(column for column, _, _ in FIGURES)]
        table = []
        for point, group in points.items():
            done = [r for r in group if r["status"] == "finished"]
            medians = [_median([r[column] for r in done]) for column, _, _ in FIGURES]
            table.append([*point, f"{len(done)}/{len(group)}", *medians])
        lines += ["\nMedian over seeds, per grid point:\n", _md_table(header, table)]
    return "\n".join(lines) + "\n"


def _median(values: list[float]) -> str:
    return f"{statistics.median(values):.4g}" if values else ""


def _md_table(header: list[str], rows: list[list[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


__all__ = ["parse_grid", "sweep", "sweep_jobs"]
