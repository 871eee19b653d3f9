"""Evaluation results in the paper's format: tables (Markdown, CSV, LaTeX), the Fig. 3 figure (field,
target, sub-goals as dots, robot path as a line, one panel per manager, same episode) and a GIF of one
episode.

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
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hier_ssl.world.field import Field
from hier_ssl.world.physics import RobotSpec, RobotState

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


def make_record(manager: str, result: dict[str, Any], **context: Any) -> dict[str, Any]:
    """The JSON record of one evaluation: ``result`` is ``hier_ssl.evaluate.evaluate``'s dict, ``context``
    holds worker, task and anything else to keep (frame_skip, seed)."""
    record = {"manager": manager, **context}
    for key in (*RECORD_KEYS[3:], "time_to_target_s_median"):
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
    """The records as a Markdown table (lengths in control steps of 25 ms, CPAD in m)."""
    lines = ["| " + " | ".join(HEADERS) + " |", "|" + "---|" * len(HEADERS)]
    lines += ["| " + " | ".join(table_cells(r)) + " |" for r in records]
    return "\n".join(lines) + "\n"


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
    """The records as CSV, one number per column (the table's IQR cell split into median, q1, q3)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for r in records:
        row = [r["manager"], r.get("worker", ""), r.get("task", ""), r.get("frame_skip", ""), r["episodes"]]
        row += [r["episode_length"][k] for k in ("median", "q1", "q3", "max", "min")]
        row += [r["cpad"][k] for k in ("median", "q1", "q3", "max", "min")]
        row += [r["collision_rate"], r["success_rate"], r["optimal_ratio_median"]]
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


# -- figures -----------------------------------------------------------------------------------------------


def outcome(success: bool, collision: bool) -> str:
    return "success" if success else "collision" if collision else "timeout"


def label_outcomes(
    result: dict[str, Any], success: np.ndarray, collision: np.ndarray, cpad: np.ndarray
) -> None:
    """Give every recorded episode of ``result`` (its "trajectories") the ``outcome`` of each of its
    controlled robots ("success", "collision", "timeout") and their ``cpad``, for figures. Shapes:
    (episodes, M) per robot."""
    for episode in result.get("trajectories", []):
        i = episode["field"]
        episode["outcome"] = [
            outcome(bool(s), bool(c)) for s, c in zip(success[i], collision[i], strict=True)
        ]
        episode["cpad"] = [float(x) for x in cpad[i]]


def _panel(
    field: Field,
    episode: dict[str, Any],
    step: int | None = None,
    size: tuple[int, int] = (440, 300),
    robot: RobotSpec | None = None,
    robots_at: int | None = None,
) -> np.ndarray:
    """One recorded episode (``hier_ssl.evaluate.Recorder.episode``) drawn up to control step ``step``
    (default: its end) as an RGB image (H, W, 3): every controlled robot's target, sub-goals so far as dots
    and path so far as a line, the obstacles' paths, and the robots where they are at step ``robots_at``
    (default: ``step``)."""
    from hier_ssl.world.render import render_fields

    robots, m = episode["robots"], episode["controlled"]
    end = len(robots) - 1 if step is None else min(step, len(robots) - 1)
    at = end if robots_at is None else min(robots_at, end)
    pos, angle = robots[at][None], episode["angles"][at][None]
    state = RobotState(pos, angle, np.zeros_like(pos), np.zeros_like(angle))
    dots, owner = [], []
    for i in range(m):  # a held sub-goal is one dot, not frame_skip of them
        subgoals = episode["subgoal"][:end, i, :2]
        keep = np.ones(len(subgoals), dtype=bool)
        keep[1:] = np.any(subgoals[1:] != subgoals[:-1], axis=1)
        dots.append(subgoals[keep])
        owner += [i] * int(keep.sum())
    dots = np.concatenate(dots) if owner else None
    return render_fields(
        field,
        state,
        targets=episode["target"][None, :, :3],
        subgoals=None if dots is None else dots[None],
        subgoal_robot=owner,
        trails=[robots[: end + 1, k] for k in range(robots.shape[1])],
        team=[0] * m + [1] * (robots.shape[1] - m),
        size=size,
        robot=robot,
    )


def panel_title(name: str, episode: dict[str, Any]) -> str:
    steps, outcomes = len(episode["robots"]) - 1, episode["outcome"]
    if len(outcomes) == 1:
        return f"{name}\n{outcomes[0]}, {steps} steps, CPAD {episode['cpad'][0]:.2f} m"
    reached, hit = outcomes.count("success"), outcomes.count("collision")
    return f"{name}\n{reached}/{len(outcomes)} reached, {hit} collided, {steps} steps"


def figure3(
    panels: Sequence[tuple[str, dict[str, Any]]],
    field: Field,
    path: str | Path,
    robot: RobotSpec | None = None,
    title: str | None = None,
    size: tuple[int, int] = (440, 300),
) -> Path:
    """The paper's Fig. 3: one panel per (name, recorded episode), the same episode in each; PNG.

    An episode is one of ``evaluate(..., record=...)["trajectories"]`` with ``outcome`` and ``cpad``
    added. Target: red ring with a heading tick; sub-goals: orange dots; the robot's path: blue line
    (from the robot, drawn where it started); the obstacles' paths: yellow lines (from where they
    started, so a still obstacle is a disc without a line).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not panels:
        raise ValueError("figure3 needs at least one panel")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    width, height = size
    cols = min(len(panels), 4)
    rows = -(-len(panels) // cols)
    fig = Figure(figsize=(cols * width / 100, rows * (height / 100 + 0.55) + (0.3 if title else 0)), dpi=100)
    FigureCanvasAgg(fig)
    for i, (name, episode) in enumerate(panels):
        ax = fig.add_subplot(rows, cols, i + 1)
        ax.imshow(_panel(field, episode, size=size, robot=robot, robots_at=0))
        ax.set_title(panel_title(name, episode), fontsize=9)
        ax.set_axis_off()
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    return path


def episode_video(
    panels: Sequence[tuple[str, dict[str, Any]]],
    field: Field,
    path: str | Path,
    robot: RobotSpec | None = None,
    fps: int = 20,
    max_frames: int = 150,
    size: tuple[int, int] = (440, 300),
) -> Path:
    """An animated GIF of the same episode under every manager, side by side, with a name strip on top.

    Frames are every ``stride`` control steps (real time at ``fps`` when stride = 1 / (fps dt)), with at
    most ``max_frames``; a finished episode stays on its last frame.
    """
    import imageio.v3 as iio
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise ValueError(f"video path must end in .gif, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    width, height = size
    longest = max(len(e["robots"]) - 1 for _, e in panels)
    stride = max(2, -(-longest // max_frames))
    # The names once, as an image strip above the panels.
    fig = Figure(figsize=(len(panels) * width / 100, 0.45), dpi=100, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    for i, (name, episode) in enumerate(panels):
        label = panel_title(name, episode).split("\n")[1].split(",")[0]
        fig.text((i + 0.5) / len(panels), 0.5, f"{name}: {label}", ha="center", va="center")
    canvas.draw()
    strip = np.asarray(canvas.buffer_rgba())[..., :3]
    frames = []
    for step in [*range(0, longest, stride), longest]:
        row = np.concatenate([_panel(field, e, step, size, robot) for _, e in panels], axis=1)
        frames.append(np.concatenate([strip[:, : row.shape[1]], row], axis=0))
    iio.imwrite(path, np.stack(frames), duration=1000 / fps, loop=0)
    return path


def pick_episode(outcomes: Sequence[Sequence[float]], spreads: Sequence[float] | None = None) -> int:
    """Index of the recorded episode to show: one in which the most managers succeed; among those the
    one whose paths differ most (``spreads``, ``path_spread`` per episode), else the first.

    ``outcomes[m][j]``: whether (or, with several robots, the share of robots for which) manager m
    succeeded in recorded episode j.
    """
    counts = np.sum(np.asarray(outcomes, dtype=float), axis=0)
    if spreads is None:
        return int(np.argmax(counts))
    return int(np.argmax(np.where(counts == counts.max(), np.asarray(spreads, dtype=float), -np.inf)))


def path_spread(episodes: Sequence[dict[str, Any]]) -> float:
    """How far apart the managers' paths of one episode run (``Recorder.episode`` dicts, one per
    manager): the mean over control steps of the largest distance (m) between a controlled robot of the
    first manager and the same robot of another, an episode that ended held at its last position."""
    m = episodes[0]["controlled"]
    paths = [e["robots"][:, :m] for e in episodes]
    steps = max(len(p) for p in paths)
    held = np.stack([np.concatenate([p, np.repeat(p[-1:], steps - len(p), axis=0)]) for p in paths])
    return float(np.linalg.norm(held - held[:1], axis=-1).max(axis=(0, 2)).mean())


# -- one evaluation's files ---------------------------------------------------------------------------------


def write_evaluation(
    evaluations: Sequence[Any],
    out_dir: str | Path,
    json_path: str | Path | None = None,
    video: bool = False,
    title: str | None = None,
) -> list[Path]:
    """What ``hier-ssl eval`` writes for ``hier_ssl.compare.compare``'s evaluations: table.md, .csv and
    .tex, fig3.png (when episodes were recorded: of the recorded episodes in which most managers succeed,
    the one where their paths differ most), episode.gif with ``video``, and the JSON records at
    ``json_path``. Returns the paths written."""
    import json

    from hier_ssl.world.field import get_field

    out_dir = Path(out_dir)
    records = [e.record for e in evaluations]
    paths = write_tables(records, out_dir)
    several_workers = len({r["worker"] for r in records}) > 1
    labels = [f"{e.name} ({e.worker})" if several_workers else e.name for e in evaluations]
    recorded = [e.result.get("trajectories") for e in evaluations]
    if evaluations and all(recorded):
        outcomes = [[np.mean(np.equal(t["outcome"], "success")) for t in ts] for ts in recorded]
        j = pick_episode(outcomes, [path_spread(episode) for episode in zip(*recorded, strict=True)])
        panels = [(label, ts[j]) for label, ts in zip(labels, recorded, strict=True)]
        fld = get_field(evaluations[0].env.field)
        episode = f"episode {panels[0][1]['field']}" + (f" - {title}" if title else "")
        paths.append(figure3(panels, fld, out_dir / "fig3.png", title=episode))
        if video:
            paths.append(episode_video(panels, fld, out_dir / "episode.gif"))
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
    "episode_video",
    "figure3",
    "latex_table",
    "make_record",
    "markdown_table",
    "outcome",
    "path_spread",
    "pick_episode",
    "table_cells",
    "write_evaluation",
    "write_tables",
]
