"""Evaluation results in the paper's format: tables (Markdown, CSV, LaTeX), and the files of one
``hier-ssl eval`` (tables, Fig. 3 and a GIF of one episode from ``hier_ssl.evaluation.figures``).

A *record* is one manager's evaluation as ``hier-ssl eval --json`` writes it: manager, worker, task,
episodes, success_rate, collision_rate, episode_length and cpad (each {median, q1, q3, min, max}),
optimal_ratio_median, eval_wall_s (and frame_skip, seed). Tables never show wall times, so the same
evaluation repeated gives the same table, byte for byte.

CPAD here is the paper's definition (section 6): the sum of the distances between consecutive (x, y)
sub-goals, one sub-goal per control step. The paper's public code computes the Frobenius norm of the
matrix of differences instead, sqrt(sum of squared distances), which is never larger and can be much
smaller (``hier_ssl.manager.metrics.cpad(..., variant="public_code")``); the paper's CPAD column was
produced with the code, so its CPAD numbers and ours are not the same quantity.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hier_ssl.evaluation.figures import episode_video, figure3, pick_episode
from hier_ssl.world.field import get_field

RECORD_KEYS = (
    "manager",
    "worker",
    "task",
    "episodes",
    "success_rate",
    "collision_rate",
    "episode_length",
    "cpad",
    "cpad_public",
    "optimal_ratio_median",
    "eval_wall_s",
)

# A game scenario's keys of a record (``hier_ssl.evaluation.evaluate.evaluate``).
GAME_KEYS = ("foul_rate", "fouls", "robot_minutes", "fouls_per_robot_minute")


def fouls_and_collisions(record: dict[str, Any]) -> float:
    """The share of a game scenario's robots whose episode ended in a foul or a collision: a robot leaves
    one way only (``hier_ssl.envs.game.game_outcome``), so the two rates add up."""
    return record["foul_rate"] + record["collision_rate"]


def fouls_per_minute(record: dict[str, Any]) -> float:
    """Every foul of a game scenario's record per robot-minute played, all kinds together."""
    return sum(record["fouls_per_robot_minute"].values())


def make_record(manager: str, result: dict[str, Any], **context: Any) -> dict[str, Any]:
    """The JSON record of one evaluation: ``result`` is ``hier_ssl.evaluation.evaluate.evaluate``'s dict,
    ``context`` holds worker, task and anything else to keep (frame_skip, seed)."""
    record = {"manager": manager, **context}
    for key in (*RECORD_KEYS[3:], "time_to_target_s_median", *GAME_KEYS):
        if key in result or key in RECORD_KEYS:
            record[key] = result[key]
    return record


# -- tables ------------------------------------------------------------------------------------------------


def _number(value: float, digits: int) -> str:
    """``value`` with ``digits`` decimals; whole numbers of a 0-digit column without a decimal point."""
    if value != value:  # NaN
        return "-"
    if digits == 0:
        return f"{value:.0f}" if float(value).is_integer() else f"{value:.1f}"
    return f"{value:.{digits}f}"


def _iqr(d: dict[str, float], digits: int) -> str:
    return f"{_number(d['median'], digits)} ({_number(d['q1'], digits)} - {_number(d['q3'], digits)})"


HEADERS = (
    "Manager",
    "Worker",
    "Length median (Q1 - Q3)",
    "Length max",
    "Length min",
    "CPAD m median (Q1 - Q3)",
    "CPAD max",
    "CPAD min",
    "Collision",
    "Success",
    "Time / optimum",
)


def table_cells(record: dict[str, Any]) -> list[str]:
    """One table row of the paper's format for a record (strings, in the order of ``HEADERS``)."""
    length, cpad = record["episode_length"], record["cpad"]
    return [
        str(record["manager"]),
        str(record.get("worker", "")),
        _iqr(length, 0),
        _number(length["max"], 0),
        _number(length["min"], 0),
        _iqr(cpad, 2),
        _number(cpad["max"], 2),
        _number(cpad["min"], 2),
        f"{100 * record['collision_rate']:.2f} %",
        f"{100 * record['success_rate']:.1f} %",
        _number(record["optimal_ratio_median"], 2),
    ]


def markdown_table(records: Sequence[dict[str, Any]]) -> str:
    """The records as a Markdown table (lengths in control steps of 25 ms, CPAD in m); records of a game
    scenario add a "Foul" column (robots that left for a foul) and a line of their fouls by kind."""
    game = all("foul_rate" in r for r in records)
    headers = (*HEADERS, "Foul") if game else HEADERS
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    for r in records:
        cells = table_cells(r) + ([f"{100 * r['foul_rate']:.2f} %"] if game else [])
        lines.append("| " + " | ".join(cells) + " |")
    if game:
        lines.append("")
        for r in records:
            fouls = ", ".join(f"{kind} {count}" for kind, count in r["fouls"].items() if count) or "none"
            lines.append(f"fouls of {r['manager']}: {fouls}{_per_minute(r)}")
    return "\n".join(lines) + "\n"


def _per_minute(record: dict[str, Any]) -> str:
    """``record``'s fouls per robot-minute, all and by kind committed, as the end of its fouls' line."""
    rates = record.get("fouls_per_robot_minute")
    if rates is None:  # a record written before the rates were
        return ""
    kinds = "".join(f", {kind} {rate:.3f}" for kind, rate in rates.items() if record["fouls"][kind])
    total = fouls_per_minute(record)
    return f"; per robot-minute ({record['robot_minutes']:.1f} played): all {total:.3f}{kinds}"


CSV_COLUMNS = (
    "manager",
    "worker",
    "task",
    "frame_skip",
    "episodes",
    *(f"episode_length_{k}" for k in ("median", "q1", "q3", "max", "min")),
    *(f"cpad_{k}" for k in ("median", "q1", "q3", "max", "min")),
    "collision_rate",
    "success_rate",
    "optimal_ratio_median",
)


def csv_table(records: Sequence[dict[str, Any]]) -> str:
    """The records as CSV, one number per column (the table's IQR cell split into median, q1, q3); records
    of a game scenario add the median time to the target, the foul rate, the robot-minutes played and the
    fouls per robot-minute by kind."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    game = all("fouls_per_robot_minute" in r for r in records)
    kinds = list(records[0]["fouls_per_robot_minute"]) if game and records else []
    game_columns = ["foul_rate", "robot_minutes", *(f"fouls_per_robot_minute_{kind}" for kind in kinds)]
    writer.writerow([*CSV_COLUMNS, "time_to_target_s_median", *game_columns] if game else CSV_COLUMNS)
    for r in records:
        row = [r["manager"], r.get("worker", ""), r.get("task", ""), r.get("frame_skip", ""), r["episodes"]]
        row += [r["episode_length"][k] for k in ("median", "q1", "q3", "max", "min")]
        row += [r["cpad"][k] for k in ("median", "q1", "q3", "max", "min")]
        row += [r["collision_rate"], r["success_rate"], r["optimal_ratio_median"]]
        if game:
            row += [r["time_to_target_s_median"], r["foul_rate"], r["robot_minutes"]]
            row += [r["fouls_per_robot_minute"][kind] for kind in kinds]
        writer.writerow(row)
    return out.getvalue()


_TEX_ESCAPES = {c: "\\" + c for c in "&%_#${}"} | {"\\": r"\textbackslash{}", "~": r"\textasciitilde{}"}


def _tex(text: str) -> str:
    return "".join(_TEX_ESCAPES.get(c, c) for c in text)


def latex_table(records: Sequence[dict[str, Any]], caption: str | None = None) -> str:
    """The records as a LaTeX table laid out like the paper's Tables 1 and 2 (booktabs-free, plain
    ``tabular``), plus success rate and time over the optimum."""
    lines = [
        r"\begin{table}[ht]",
        r"\centering",
        *([rf"\caption{{{_tex(caption)}}}"] if caption else []),
        r"\begin{tabular}{|ll|ccc|ccc|c|c|c|}",
        r"\hline",
        r" & & \multicolumn{3}{c|}{Episode Length (steps)} & \multicolumn{3}{c|}{CPAD (m)} "
        r"& Collision & Success & $t / t^*$ \\",
        r"Manager & Worker & IQR & Max & Min & IQR & Max & Min & & & \\ \hline",
    ]
    for r in records:
        cells = [_tex(c) for c in table_cells(r)]
        lines.append(" & ".join(cells) + r" \\")
    lines += [r"\hline", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def write_tables(records: Sequence[dict[str, Any]], out_dir: str | Path, stem: str = "table") -> list[Path]:
    """``stem``.md, .csv and .tex in ``out_dir`` (created); returns the paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for suffix, text in (
        (".md", markdown_table(records)),
        (".csv", csv_table(records)),
        (".tex", latex_table(records)),
    ):
        path = out_dir / f"{stem}{suffix}"
        path.write_text(text)
        paths.append(path)
    return paths


# -- one evaluation's files ---------------------------------------------------------------------------------


def write_evaluation(
    evaluations: Sequence[Any],
    out_dir: str | Path,
    json_path: str | Path | None = None,
    video: bool = False,
    title: str | None = None,
    progress: bool = False,
) -> list[Path]:
    """What ``hier-ssl eval`` writes for ``hier_ssl.evaluation.compare.compare``'s evaluations: table.md, .csv
    and .tex, fig3.png (when episodes were recorded: of the recorded episodes in which most managers succeed,
    the one where their paths differ most), episode.gif with ``video`` (its frames counted on stderr with
    ``progress``), and the JSON records at ``json_path``. Returns the paths written."""
    out_dir = Path(out_dir)
    records = [e.record for e in evaluations]
    paths = write_tables(records, out_dir)
    several_workers = len({r["worker"] for r in records}) > 1
    labels = [f"{e.name} ({e.worker})" if several_workers else e.name for e in evaluations]
    recorded = [e.result.get("trajectories") for e in evaluations]
    if evaluations and all(recorded):
        j = pick_episode(recorded)
        panels = [(label, ts[j]) for label, ts in zip(labels, recorded, strict=True)]
        fld = get_field(evaluations[0].env.field)
        episode = f"episode {panels[0][1]['field']}" + (f" - {title}" if title else "")
        paths.append(figure3(panels, fld, out_dir / "fig3.png", title=episode))
        if video:
            paths.append(episode_video(panels, fld, out_dir / "episode.gif", progress=progress))
    if json_path is not None:
        json_path = Path(json_path)
        json_path.parent.mkdir(parents=True, exist_ok=True)
        # NaN (e.g. time over the optimum of a manager that never succeeds) as null: strict JSON.
        clean = [{k: None if v != v else v for k, v in r.items()} for r in records]
        json_path.write_text(json.dumps(clean, indent=2) + "\n")
        paths.append(json_path)
    return paths


__all__ = [
    "HEADERS",
    "RECORD_KEYS",
    "csv_table",
    "fouls_and_collisions",
    "fouls_per_minute",
    "latex_table",
    "make_record",
    "markdown_table",
    "table_cells",
    "write_evaluation",
    "write_tables",
]
