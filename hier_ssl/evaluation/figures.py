"""Fig. 3 of the paper (field, target, sub-goals as dots, robot path as a line, one panel per manager, same
episode), a GIF of one episode, and which recorded episode to show.

An *episode* is one dict of ``hier_ssl.envs.play.Recorder.episode`` with its ``outcome`` labels
(``label_outcomes``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

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


def pick_episode(recorded: Sequence[Sequence[dict[str, Any]]]) -> int:
    """Index of the episode to show of ``recorded[m][j]``, manager m's recorded episode j (with its
    ``outcome`` labels): one in which the most managers succeed (with several robots, counting each
    manager's share of robots that did), and of those the one where their paths differ most
    (``path_spread``)."""
    solved = np.sum([[np.mean(np.equal(e["outcome"], "success")) for e in row] for row in recorded], axis=0)
    spread = [path_spread(episode) for episode in zip(*recorded, strict=True)]
    return int(np.argmax(np.where(solved == solved.max(), spread, -np.inf)))


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
    "figure3",
    "label_outcomes",
    "outcome",
    "panel_title",
    "path_spread",
    "pick_episode",
]
