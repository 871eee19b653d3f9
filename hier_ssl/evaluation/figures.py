"""Fig. 3 of the paper (field, target, sub-goals as dots, robot path as a line, one panel per manager, same
episode, a legend), a GIF of one episode, and which recorded episode to show. Where a controlled robot
collided is marked with a cross in its colour, and panel titles name the robots that did.

An *episode* is one dict of ``hier_ssl.envs.play.Recorder.episode`` with its ``outcome`` labels
(``label_outcomes``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from hier_ssl.manager.success import COLLISION_DISTANCE
from hier_ssl.world.field import Field
from hier_ssl.world.physics import RobotSpec, RobotState


def outcome(success: bool, collision: bool, foul: bool = False) -> str:
    return "success" if success else "collision" if collision else "foul" if foul else "timeout"


def label_outcomes(
    result: dict[str, Any],
    success: np.ndarray,
    collision: np.ndarray,
    cpad: np.ndarray,
    foul: np.ndarray | None = None,
) -> None:
    """Give every recorded episode of ``result`` (its "trajectories") the ``outcome`` of each of its
    controlled robots ("success", "collision", "foul" in a game scenario, "timeout") and their ``cpad``,
    for figures. Shapes: (episodes, M) per robot; ``foul`` None where no robot can commit one."""
    foul = np.zeros_like(success) if foul is None else foul
    for episode in result.get("trajectories", []):
        i = episode["field"]
        episode["outcome"] = [
            outcome(bool(s), bool(c), bool(f))
            for s, c, f in zip(success[i], collision[i], foul[i], strict=True)
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
    """One recorded episode (``hier_ssl.envs.play.Recorder.episode``) drawn up to control step ``step``
    (default: its end) as an RGB image (H, W, 3): every controlled robot's target, sub-goals so far as dots
    and path so far as a line, the obstacles' paths, and the robots where they are at step ``robots_at``
    (default: ``step``)."""
    # here, not at the top: matplotlib, for drawing alone
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
    hits = [(i, point) for i, t, point in collisions(episode) if t <= end]
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
        collisions=np.array([point for _, point in hits]).reshape(-1, 2) if hits else None,
        collision_robot=[i for i, _ in hits],
    )


def collisions(
    episode: dict[str, Any], distance: float = COLLISION_DISTANCE
) -> list[tuple[int, int, np.ndarray]]:
    """Where each controlled robot whose ``outcome`` is "collision" hit another robot: (robot i, control
    step t, point (2,) halfway between the two centres) at the first step another robot was within
    ``distance`` m of it (the step of the closest approach if none was: a run with a larger collision
    distance). Robots are indices into ``episode["robots"]`` (T+1, R, 2), field frame."""
    robots, found = episode["robots"], []
    for i, label in enumerate(episode["outcome"]):
        if label != "collision":
            continue
        gaps = np.linalg.norm(robots - robots[:, i : i + 1], axis=-1)  # (T+1, R)
        gaps[:, i] = np.inf
        nearest = gaps.min(axis=1)
        within = np.flatnonzero(nearest < distance)
        t = int(within[0]) if within.size else int(np.argmin(nearest))
        other = int(np.argmin(gaps[t]))
        found.append((i, t, (robots[t, i] + robots[t, other]) / 2))
    return found


def panel_title(name: str, episode: dict[str, Any]) -> str:
    steps, outcomes = len(episode["robots"]) - 1, episode["outcome"]
    if len(outcomes) == 1:
        return f"{name}\n{outcomes[0]}, {steps} steps, CPAD {episode['cpad'][0]:.2f} m"
    reached = outcomes.count("success")
    hit = [str(i) for i, label in enumerate(outcomes) if label == "collision"]
    which = f" (robot{'s' * (len(hit) > 1)} {', '.join(hit)})" if hit else ""
    fouled = outcomes.count("foul")
    fouls = f", {fouled} fouled" if fouled else ""
    return f"{name}\n{reached}/{len(outcomes)} reached, {len(hit)} collided{which}{fouls}, {steps} steps"


def legend_entries() -> list[tuple[str, dict[str, Any]]]:
    """(label, matplotlib ``Line2D`` keywords) of what the panels draw, for a legend."""
    # here, not at the top: matplotlib, for drawing alone
    from hier_ssl.world.render import COLLISION_MARKER, SUBGOAL, TARGET, TEAM_COLORS

    point = {"linestyle": "none", "markersize": 7}
    cross = {"marker": COLLISION_MARKER, "color": TARGET, "markeredgecolor": "#101010"}
    return [
        ("target", {**point, "marker": "o", "markerfacecolor": "none", "markeredgecolor": TARGET}),
        ("sub-goals", {**point, "marker": ".", "color": SUBGOAL}),
        ("robot, path", {"marker": "o", "color": TEAM_COLORS[0], "markersize": 6}),
        ("obstacle, path", {"marker": "o", "color": TEAM_COLORS[1], "markersize": 6}),
        ("collision", {**point, **cross}),
    ]


def legend_columns(width_in: float, fontsize: float = 8) -> int:
    """How many of ``legend_entries`` fit side by side in ``width_in`` inches of figure, measured by
    drawing them (at least 1): a narrow picture (one panel) wraps its legend onto more rows instead of
    cutting it at both edges."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, 1), dpi=100)
    renderer = FigureCanvasAgg(fig).get_renderer()
    for columns in range(len(legend_entries()), 1, -1):
        legend = _legend(fig, columns, fontsize, loc="center")
        fits = legend.get_window_extent(renderer).width <= fig.bbox.width
        legend.remove()
        if fits:
            return columns
    return 1


def _legend(fig: Any, columns: int, fontsize: float = 8, **where: Any) -> Any:
    """The legend of ``legend_entries`` in ``columns`` columns on ``fig``, placed by ``where``
    (``Figure.legend``)."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], label=label, **style) for label, style in legend_entries()]
    return fig.legend(
        handles=handles, ncol=columns, frameon=False, fontsize=fontsize, handletextpad=0.3, **where
    )


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
    started, so a still obstacle is a disc without a line); a collision: a cross where it happened. With
    several controlled robots each has its own colour. A legend below the panels says so.
    """
    # here, not at the top: matplotlib, for drawing alone
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not panels:
        raise ValueError("figure3 needs at least one panel")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    width, height = size
    cols = min(len(panels), 4)
    rows = -(-len(panels) // cols)
    fig_width = max(cols * width / 100, 4.4)
    columns = legend_columns(fig_width)
    legend_in = 0.3 * -(-len(legend_entries()) // columns)
    fig_height = rows * (height / 100 + 0.55) + (0.3 if title else 0) + legend_in
    fig = Figure(figsize=(fig_width, fig_height), dpi=100)
    FigureCanvasAgg(fig)
    for i, (name, episode) in enumerate(panels):
        ax = fig.add_subplot(rows, cols, i + 1)
        ax.imshow(_panel(field, episode, size=size, robot=robot, robots_at=0))
        ax.set_title(panel_title(name, episode), fontsize=9)
        ax.set_axis_off()
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, legend_in / fig_height, 1, 1))
    _legend(fig, columns, loc="lower center")
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
    fontsize: float = 10,
    progress: bool = False,
) -> Path:
    """An animated GIF of the same episode under every manager, side by side, under a strip that names
    each panel's manager, says its outcome from the frame its episode ended (not before), and holds the
    legend in ``fontsize`` points.

    Frames are every ``stride`` control steps (real time at ``fps`` when stride = 1 / (fps dt)), with at
    most ``max_frames``; a finished episode stays on its last frame. With ``progress`` a bar counts the
    frames drawn on stderr.
    """
    # here, not at the top: imageio, for a video alone
    import imageio.v3 as iio

    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise ValueError(f"video path must end in .gif, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    longest = max(len(e["robots"]) - 1 for _, e in panels)
    stride = max(2, -(-longest // max_frames))
    steps = [*range(0, longest, stride), longest]
    strips: dict[tuple[str, ...], np.ndarray] = {}  # one per set of finished panels, not one per frame
    columns = legend_columns(len(panels) * size[0] / 100, fontsize)  # the strip's width never changes
    frames = []
    for step in tqdm(steps, desc=f"drawing {path.name}", unit="frame", disable=not progress, leave=False):
        names = frame_labels(panels, step)
        if names not in strips:
            strips[names] = _strip(names, size[0], fontsize, columns)
        row = np.concatenate([_panel(field, e, step, size, robot) for _, e in panels], axis=1)
        frames.append(np.concatenate([strips[names][:, : row.shape[1]], row], axis=0))
    iio.imwrite(path, np.stack(frames), duration=1000 / fps, loop=0)
    return path


def frame_labels(panels: Sequence[tuple[str, dict[str, Any]]], step: int) -> tuple[str, ...]:
    """What the video's strip says over each panel at control step ``step``: the manager's name, and its
    outcome ("success", "3/6 reached") only from the step its episode ended."""
    ended = [step >= len(e["robots"]) - 1 for _, e in panels]
    return tuple(
        f"{name}: {panel_title(name, e).splitlines()[1].split(',')[0]}" if done else name
        for (name, e), done in zip(panels, ended, strict=True)
    )


def _strip(names: Sequence[str], panel_width: int, fontsize: float, columns: int) -> np.ndarray:
    """An RGB image strip, ``panel_width`` pixels a name: each name over its panel and the legend whole
    below them in ``columns`` (``legend_columns``), on as many rows as it needs."""
    # here, not at the top: matplotlib, for drawing alone
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    width_in = len(names) * panel_width / 100
    rows = -(-len(legend_entries()) // columns)
    line_in = fontsize / 72 * 1.6
    fig = Figure(figsize=(width_in, line_in * (1 + rows) + 0.1), dpi=100, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    top = 1 - line_in / 2 / fig.get_figheight()
    for i, name in enumerate(names):
        fig.text((i + 0.5) / len(names), top, name, ha="center", va="center", fontsize=fontsize)
    _legend(fig, columns, fontsize, loc="lower center", bbox_to_anchor=(0.5, 0.0))
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3]


def pick_episode(recorded: Sequence[Sequence[dict[str, Any]]]) -> int:
    """Index of the episode to show of ``recorded[m][j]``, manager m's recorded episode j (with its
    ``outcome`` labels): one in which the most managers succeed (with several robots, counting each
    manager's share of robots that did) and, if any such is typical, whose robots start as far from their
    targets as those of the middle half of the recorded episodes (``start_distance``: not a 0.3 m one);
    of those the one where the managers' paths differ most (``path_spread``), and where no paths differ
    (one manager) the one nearest the median start distance."""
    solved = np.sum([[np.mean(np.equal(e["outcome"], "success")) for e in row] for row in recorded], axis=0)
    spread = np.array([path_spread(episode) for episode in zip(*recorded, strict=True)])
    start = np.array([start_distance(e) for e in recorded[0]])
    low, median, high = np.percentile(start, [25, 50, 75])
    best = solved == solved.max()
    typical = best & (start >= low) & (start <= high)
    pool = typical if typical.any() else best
    order = np.lexsort((np.abs(start - median), -spread))  # the last key sorts first
    return int(order[pool[order]][0])


def start_distance(episode: dict[str, Any]) -> float:
    """Mean distance (m) from each controlled robot's start to its target in a ``Recorder.episode``."""
    m = episode["controlled"]
    return float(np.linalg.norm(episode["robots"][0, :m] - episode["target"][:m, :2], axis=-1).mean())


def path_spread(episodes: Sequence[dict[str, Any]]) -> float:
    """How far apart the managers' paths of one episode run (``Recorder.episode`` dicts, one per
    manager): the mean over control steps of the largest distance (m) between a controlled robot of the
    first manager and the same robot of another, an episode that ended held at its last position."""
    m = episodes[0]["controlled"]
    paths = [e["robots"][:, :m] for e in episodes]
    steps = max(len(p) for p in paths)
    held = np.stack([np.concatenate([p, np.repeat(p[-1:], steps - len(p), axis=0)]) for p in paths])
    return float(np.linalg.norm(held - held[:1], axis=-1).max(axis=(0, 2)).mean())


__all__ = [
    "episode_video",
    "collisions",
    "figure3",
    "frame_labels",
    "label_outcomes",
    "legend_columns",
    "legend_entries",
    "outcome",
    "panel_title",
    "path_spread",
    "pick_episode",
    "start_distance",
]
