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

from hier_ssl.manager.success import COLLISION_DISTANCE
from hier_ssl.world.field import Field
from hier_ssl.world.physics import RobotSpec, RobotState


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
    return f"{name}\n{reached}/{len(outcomes)} reached, {len(hit)} collided{which}, {steps} steps"


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


def _legend(fig: Any, **where: Any) -> None:
    """The legend of ``legend_entries`` on one row of ``fig``, placed by ``where`` (``Figure.legend``)."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], label=label, **style) for label, style in legend_entries()]
    fig.legend(handles=handles, ncol=len(handles), frameon=False, fontsize=8, handletextpad=0.3, **where)


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
    legend_in = 0.3
    fig_height = rows * (height / 100 + 0.55) + (0.3 if title else 0) + legend_in
    fig = Figure(figsize=(max(cols * width / 100, 4.4), fig_height), dpi=100)
    FigureCanvasAgg(fig)
    for i, (name, episode) in enumerate(panels):
        ax = fig.add_subplot(rows, cols, i + 1)
        ax.imshow(_panel(field, episode, size=size, robot=robot, robots_at=0))
        ax.set_title(panel_title(name, episode), fontsize=9)
        ax.set_axis_off()
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, legend_in / fig_height, 1, 1))
    _legend(fig, loc="lower center")
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
    # here, not at the top: imageio and matplotlib, for a video alone
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
    # The names and the legend once, as an image strip above the panels.
    fig = Figure(figsize=(len(panels) * width / 100, 0.75), dpi=100, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    for i, (name, episode) in enumerate(panels):
        label = panel_title(name, episode).split("\n")[1].split(",")[0]
        fig.text((i + 0.5) / len(panels), 0.75, f"{name}: {label}", ha="center", va="center")
    _legend(fig, loc="lower center", bbox_to_anchor=(0.5, 0.0))
    canvas.draw()
    strip = np.asarray(canvas.buffer_rgba())[..., :3]
    frames = []
    for step in [*range(0, longest, stride), longest]:
        row = np.concatenate([_panel(field, e, step, size, robot) for _, e in panels], axis=1)
        frames.append(np.concatenate([strip[:, : row.shape[1]], row], axis=0))
    iio.imwrite(path, np.stack(frames), duration=1000 / fps, loop=0)
    return path


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
    "label_outcomes",
    "legend_entries",
    "outcome",
    "panel_title",
    "path_spread",
    "pick_episode",
    "start_distance",
]
