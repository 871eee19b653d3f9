"""The paper's Tables 1 and 2 beside ours: every configuration in both families, every seed, both the final
policy and the best checkpoint, the scripted planners as reference rows.

A *row* is one configuration evaluated one way: its runs' records (one per training seed, all on the same
episodes) under a family ("paper family": the public code's settings, ``configs/paper/``; "defaults": ours,
``configs/<task>/``), a checkpoint ("final" or "best") and an action rule ("sampled", as the paper's test
script, or "mean"). Each cell is the median over seeds of the runs' figures, with the seeds' min - max.
Per-run figures are episode medians (length, both CPADs), rates (success, collision), the median ratio of
episode time to the time-optimal bound over successful episodes, and the training wall time. A row keeps
only those cells (``summarise``), so the CSV holds all of it: ``read_csv`` gives back the rows it was
written from, which is how ``hier-ssl reproduce`` keeps the rows it does not evaluate again.

The paper's own row puts its published medians (1000 episodes of its final models, sampled actions) in the
same columns: its CPAD column was computed by its public code, so it stands under "CPAD, public code".
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

SETUPS = ("vanilla", "frame_skip", "caps", "fscaps")
SETUP_TITLES = {"vanilla": "Vanilla", "frame_skip": "Frame Skip", "caps": "CAPS", "fscaps": "FSCAPS"}
TASKS = ("baseline", "proposed", "obstacle")


def _dist(median: float, q1: float, q3: float, mx: float, mn: float) -> dict[str, float]:
    return {"median": median, "q1": q1, "q3": q3, "max": mx, "min": mn}


# The paper's Tables 1 and 2 (1000 test episodes each): episode length in control steps, CPAD in m,
# collision rate as a fraction (Obstacle task only).
PAPER_RESULTS: dict[tuple[str, str], dict[str, Any]] = {
    ("baseline", "vanilla"): {
        "episode_length": _dist(1200, 1200, 1200, 1200, 52),
        "cpad": _dist(20.84, 14.42, 26.75, 47.66, 1.39),
    },
    ("proposed", "vanilla"): {
        "episode_length": _dist(128, 102, 152, 1200, 35),
        "cpad": _dist(6.03, 3.93, 8.07, 16.43, 0.20),
    },
    ("baseline", "frame_skip"): {
        "episode_length": _dist(198, 150, 265, 1200, 49),
        "cpad": _dist(13.53, 11.03, 16.55, 38.40, 3.46),
    },
    ("proposed", "frame_skip"): {
        "episode_length": _dist(119, 95, 141, 223, 33),
        "cpad": _dist(1.31, 0.60, 2.12, 6.80, 0.01),
    },
    ("baseline", "caps"): {
        "episode_length": _dist(1200, 731, 1200, 1200, 37),
        "cpad": _dist(13.97, 9.61, 16.31, 22.86, 1.91),
    },
    ("proposed", "caps"): {
        "episode_length": _dist(113, 91, 134, 1200, 33),
        "cpad": _dist(1.29, 0.81, 1.87, 3.81, 0.14),
    },
    ("baseline", "fscaps"): {
        "episode_length": _dist(109, 87, 130, 196, 34),
        "cpad": _dist(0.58, 0.36, 0.87, 2.22, 0.02),
    },
    ("proposed", "fscaps"): {
        "episode_length": _dist(114, 92, 137, 193, 31),
        "cpad": _dist(0.06, 0.05, 0.08, 0.16, 0.00),
    },
    ("obstacle", "vanilla"): {
        "episode_length": _dist(1200, 1200, 1200, 1200, 132),
        "cpad": _dist(12.38, 10.70, 14.21, 35.03, 4.10),
        "collision_rate": 0.1238,
    },
    ("obstacle", "frame_skip"): {
        "episode_length": _dist(1200, 1200, 1200, 1200, 148),
        "cpad": _dist(6.03, 5.24, 6.90, 11.35, 2.23),
        "collision_rate": 0.0561,
    },
    ("obstacle", "caps"): {
        "episode_length": _dist(1200, 1200, 1200, 1200, 670),
        "cpad": _dist(11.35, 10.55, 12.17, 20.60, 4.10),
        "collision_rate": 0.0132,
    },
    ("obstacle", "fscaps"): {
        "episode_length": _dist(115, 113, 158, 1200, 79),
        "cpad": _dist(1.27, 1.06, 1.53, 5.87, 0.55),
        "collision_rate": 0.0061,
    },
}


# (column title, how to read a record's figure) in table order; None where a record lacks the figure.
COLUMNS: tuple[tuple[str, str], ...] = (
    ("Success %", "success_rate"),
    ("Collision %", "collision_rate"),
    ("Length (steps)", "episode_length"),
    ("CPAD m", "cpad"),
    ("CPAD m, public code", "cpad_public"),
    ("Time / optimum", "optimal_ratio_median"),
    ("Training min", "train_wall_s"),
)
_PERCENT = {"success_rate", "collision_rate"}
_DIGITS = {"episode_length": 0, "cpad": 2, "cpad_public": 2, "optimal_ratio_median": 2, "train_wall_s": 1}


@dataclass
class Row:
    """One line of a task's table: per column of ``COLUMNS`` (by key) the (median, min, max) over its
    ``seeds`` training seeds, NaN where the row has no figure, rounded to the CSV's 4 decimals, so that a row
    read back from the CSV prints as the one summarised from evaluation records."""

    task: str
    setup: str
    source: str  # "paper", "paper family", "defaults", or "planner"
    policy: str = "-"  # "final", "best", or "-" (planners, the paper's own row)
    actions: str = "-"  # "sampled", "mean", or "-"
    seeds: int = 0  # 0 for the paper's own row and the planners'
    spreads: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    @property
    def key(self) -> tuple[str, str, str, str, str]:
        """What names the row in a table: (task, setup, source, policy, actions)."""
        return self.task, self.setup, self.source, self.policy, self.actions


def figure(record: dict[str, Any], key: str) -> float:
    """A record's figure for column ``key``: distributions give their median, rates are percent, training
    time is in minutes; NaN where the record has none."""
    value = record.get(key)
    if isinstance(value, dict):
        value = value["median"]
    if value is None:
        return float("nan")
    if key in _PERCENT:
        return 100.0 * value
    return value / 60.0 if key == "train_wall_s" else float(value)


def paper_record(task: str, setup: str) -> dict[str, Any]:
    """The paper's published figures of a configuration as a record (its CPAD is the public code's)."""
    paper = PAPER_RESULTS[(task, setup)]
    record = {"episode_length": paper["episode_length"], "cpad_public": paper["cpad"]}
    if "collision_rate" in paper:
        record["collision_rate"] = paper["collision_rate"]
    return record


def spread(values: Sequence[float]) -> tuple[float, float, float]:
    """(median, min, max) over seeds, NaN figures left out; all NaN when none is left."""
    kept = [v for v in values if v == v]
    if not kept:
        return (float("nan"),) * 3
    return float(np.median(kept)), float(min(kept)), float(max(kept))


def summarise(
    task: str, setup: str, source: str, policy: str, actions: str, records: Sequence[dict[str, Any]]
) -> Row:
    """The row of ``records``: one evaluation record per training seed (``make_record``'s keys plus
    ``train_wall_s`` for learned managers; the paper's own row and a planner's: one record)."""
    seeds = 0 if source in ("paper", "planner") else len(records)
    spreads = {
        key: tuple(round(v, 4) for v in spread([figure(r, key) for r in records])) for _, key in COLUMNS
    }
    return Row(task, setup, source, policy, actions, seeds, spreads)


def _cell(row: Row, key: str) -> str:
    median, low, high = row.spreads[key]
    if median != median:
        return "-"
    digits = 1 if key in _PERCENT else _DIGITS[key]
    text = f"{median:.{digits}f}"
    return text if row.seeds < 2 or low == high else f"{text} ({low:.{digits}f} - {high:.{digits}f})"


def markdown(rows: Sequence[Row]) -> str:
    """One Markdown table per task, rows in the given order."""
    heads = ["Setup", "Source", "Policy", "Seeds", *(title for title, _ in COLUMNS)]
    out = []
    for task in dict.fromkeys(row.task for row in rows):
        out += [f"### {task.capitalize()}\n", "| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
        for row in (r for r in rows if r.task == task):
            policy = row.policy if row.actions == "-" else f"{row.policy}, {row.actions}"
            seeds = "-" if row.source in ("paper", "planner") else str(row.seeds)
            name = SETUP_TITLES.get(row.setup, row.setup)
            cells = [name, row.source, policy, seeds, *(_cell(row, key) for _, key in COLUMNS)]
            out.append("| " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def _csv_head() -> list[str]:
    stats = [f"{key}_{stat}" for _, key in COLUMNS for stat in ("median", "min", "max")]
    return ["task", "setup", "source", "policy", "actions", "seeds", *stats]


def csv_text(rows: Sequence[Row]) -> str:
    """The same rows as CSV: for every column its median, min and max over seeds."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(_csv_head())
    for row in rows:
        cells = ["" if v != v else v for _, key in COLUMNS for v in row.spreads[key]]
        writer.writerow([*row.key, row.seeds, *cells])
    return buffer.getvalue()


def read_csv(text: str) -> list[Row]:
    """The rows of a ``csv_text`` output, in its order (``csv_text(read_csv(text)) == text``)."""
    lines = list(csv.reader(io.StringIO(text)))
    if not lines or lines[0] != _csv_head():
        raise ValueError(f"not a paper-tables CSV: header {lines[0] if lines else None!r}")
    rows = []
    for number, cells in enumerate(lines[1:], start=2):
        if len(cells) != len(lines[0]):
            raise ValueError(f"paper-tables CSV line {number}: {len(cells)} cells, expected {len(lines[0])}")
        values = [float(v) if v else float("nan") for v in cells[6:]]
        spreads = {key: tuple(values[3 * i : 3 * i + 3]) for i, (_, key) in enumerate(COLUMNS)}
        rows.append(Row(*cells[:5], int(cells[5]), spreads))
    return rows


def header(episodes: int, seed: int, contact: dict[str, float]) -> str:
    """The Markdown's text above the tables: what they hold, on which ``episodes`` (seed ``seed``), and per
    task the share of its episodes that begin in contact."""
    starts = ", ".join(f"{task} {100 * share:.1f} %" for task, share in contact.items())
    return (
        '# "Planning the path with Reinforcement Learning": the paper\'s tables and ours\n\n'
        "Written by `hier-ssl reproduce` (hier_ssl/runs/reproduce.py). "
        "Every manager of a task plays the same "
        f"{episodes} episodes (seed {seed}), drawn as the paper's public code draws them; learned managers "
        "act with their own interface, frame skip and worker; the planners decide every 16 control steps. "
        "*paper*: the paper's published numbers (final models, sampled actions). *paper family*: our runs "
        "of the public code's settings (configs/paper/); *defaults*: our runs of our defaults (configs/, "
        'docs/research-notes.md "Deviations from the paper"). *Policy*: the checkpoint training ended with '
        "(final) or "
        "the one model selection kept (best), acting with sampled or mean actions.\n\n"
        "Cells: the median over training seeds of each run's figure, with the seeds' min - max. A run's "
        "figures: success and collision rates, the median episode length in control steps of 25 ms (1200 "
        "= timeout), the median CPAD as the paper defines it (sum of the sub-goal's moves) and as its "
        "public code computes it (square root of the sum of squared moves: the paper's tables), the median "
        "time over the time-optimal bound (successful episodes), the training wall time (2-core machine, "
        "usually beside another run).\n\n"
        f"Episodes that begin inside the collision distance (start 0.2 m from the target, obstacle on the "
        f"midpoint) end as collisions for every manager: {starts or 'none'}.\n\n"
    )


def header_episodes(text: str) -> tuple[int, int] | None:
    """(episodes, seed) that a Markdown ``header`` names; None where it names none."""
    found = re.search(r"same (\d+) episodes \(seed (\d+)\)", text)
    return (int(found[1]), int(found[2])) if found else None


__all__ = [
    "COLUMNS",
    "PAPER_RESULTS",
    "SETUPS",
    "SETUP_TITLES",
    "TASKS",
    "Row",
    "csv_text",
    "figure",
    "header",
    "header_episodes",
    "markdown",
    "paper_record",
    "read_csv",
    "spread",
    "summarise",
]
