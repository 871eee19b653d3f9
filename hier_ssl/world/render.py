"""One field of a World as an RGB image: field markings, walls, goals, robots with headings, balls,
targets, sub-goals and trails, drawn with matplotlib's Agg canvas (headless, no pyplot state)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PatchCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from hier_ssl.world.ball import BallSpec
from hier_ssl.world.field import Field
from hier_ssl.world.goals import goal_boxes
from hier_ssl.world.physics import RobotSpec, RobotState

CARPET, LINE, WALL, GOAL, BALL = "#2e7d3b", "#f4f4f4", "#3a3a3a", "#111111", "#ff6d00"
# Team 0: the controlled robots (SSL blue), team 1: obstacles (SSL yellow); further teams cycle.
TEAM_COLORS = ("#1d4ed8", "#f5c400", "#d9480f", "#7048e8")
# With several controlled robots in a field each has its own colour, shared by its path, target and
# sub-goals (11 a side in SSL); none green (the field), yellow (the obstacles), white (the lines) or black.
ROBOT_COLORS = (
    "#1d4ed8", "#e03131", "#9c36b5", "#15aabf", "#f783ac", "#fd7e14",
    "#8b5a2b", "#b197fc", "#1c2f6e", "#74c0fc", "#868e96",
)  # fmt: skip
# An SSL game (``ssl_teams``): the controlled robots are the yellow team, the others the blue, each disc in
# its team's colour; several controlled robots are ringed each in a colour of their own (neither blue nor
# yellow), which their paths, targets and sub-goals share.
SSL_YELLOW, SSL_BLUE = "#f5c400", "#1d4ed8"
GAME_ROBOT_COLORS = tuple(c for c in ROBOT_COLORS if c not in (SSL_BLUE, "#1c2f6e", "#74c0fc"))
TARGET, SUBGOAL = "#e03131", "#ff922b"
COLLISION_MARKER = "X"  # where a controlled robot hit another, in that robot's colour with a dark edge
_LINE_WIDTH_M = 0.02  # SSL field lines are 10 mm wide; drawn a little wider so they survive small images
_CENTRE_RADIUS_M = 0.5


def render_fields(
    field: Field,
    state: RobotState,
    *,
    targets: np.ndarray | None = None,
    subgoals: np.ndarray | None = None,
    subgoal_robot: Sequence[int] | None = None,
    trails: Sequence[np.ndarray] | None = None,
    trail_robot: Sequence[int] | None = None,
    field_index: int = 0,
    size: tuple[int, int] = (660, 460),
    team: Sequence[int] | None = None,
    robot: RobotSpec | None = None,
    collisions: np.ndarray | None = None,
    collision_robot: Sequence[int] | None = None,
    extra: Callable[[Axes], None] | None = None,
    balls: np.ndarray | None = None,
    ball: BallSpec | None = None,  # the balls' radius (default: ``BallSpec()``)
    ssl_teams: bool = False,
) -> np.ndarray:
    """Field ``field_index`` of a batched state as an image of ``size`` = (W, H) pixels, (H, W, 3) uint8.

    ``state`` holds every field (pos (N, R, 2) ...). ``team`` (R,) gives each robot's team (0 controlled,
    1 obstacle, ...); by default robot 0 is controlled and the others are obstacles. ``targets`` and
    ``subgoals`` are per field, (N, K) for one each or (N, M, K) for several, with columns x, y and
    optionally theta (drawn as a heading tick); sub-goals are drawn as dots. Target row j belongs to the
    j-th controlled robot, and so does sub-goal row j unless ``subgoal_robot`` names each row's robot (as
    an index among the controlled ones). ``trails`` are polylines (T, 2) of this field in the field frame,
    the i-th that of robot ``trail_robot[i]`` (default: robot i). A robot is drawn in its team's colour;
    with several controlled robots each of them, its path, target and sub-goals share a colour of
    ``ROBOT_COLORS``. ``robot`` gives the disc radius (default: ``RobotSpec()``). ``collisions`` (C, 2) are
    points of this field where controlled robots hit another robot, marked with a cross above everything
    else in the colour of the robot ``collision_robot[c]`` (an index among the controlled ones; default 0).
    ``extra`` draws on the axes (field frame, m) what a scenario adds, above the field's lines and under
    everything else. ``balls`` (N, B, 2) (a ``BallState``'s ``pos``) are orange discs above the robots.
    With ``ssl_teams`` the field is an SSL game: the controlled robots (team 0) are drawn as the yellow
    team, the others as the blue (``SSL_YELLOW``, ``SSL_BLUE``), several controlled robots ringed each in
    its own colour of ``GAME_ROBOT_COLORS``.
    """
    num_fields, num_robots = state.angle.shape
    if not 0 <= field_index < num_fields:
        raise ValueError(f"field_index {field_index} out of range [0, {num_fields})")
    width, height = size
    if not all(isinstance(v, int | np.integer) and v > 0 for v in (width, height)):
        raise ValueError(f"size must be two positive integers (W, H), got {size!r}")
    teams = np.asarray([0] + [1] * (num_robots - 1) if team is None else team, dtype=int)
    if teams.shape != (num_robots,):
        raise ValueError(f"team has shape {teams.shape}, expected ({num_robots},)")
    radius = (robot or RobotSpec()).radius
    canvas, ax, line_pt = _canvas(field, width, height)
    palette = GAME_ROBOT_COLORS if ssl_teams else ROBOT_COLORS
    colors, controlled = _robot_colors(teams, palette, (SSL_YELLOW, SSL_BLUE) if ssl_teams else TEAM_COLORS)
    _draw_field(ax, field, line_pt)
    if extra is not None:
        extra(ax)
    if trails is not None:
        _draw_trails(ax, trails, trail_robot, colors, line_pt)
    if subgoals is not None:
        points = _per_field(subgoals, field_index, "subgoals")
        dot_colors = _owned(SUBGOAL, len(points), len(controlled), palette, subgoal_robot)
        ax.scatter(
            points[:, 0], points[:, 1], s=(2.2 * line_pt) ** 2, c=dot_colors, edgecolors="none", zorder=5
        )
    if targets is not None:
        points = _per_field(targets, field_index, "targets")
        _draw_targets(ax, points, _owned(TARGET, len(points), len(controlled), palette), radius, line_pt)
    pos, angle = state.pos[field_index], state.angle[field_index]
    style = _disc_style(teams, colors, controlled, ssl_teams, line_pt)
    ax.add_collection(PatchCollection([Circle(tuple(p), radius) for p in pos], **style, zorder=6))
    ax.add_collection(_ticks(pos, angle, radius, "#101010", 1.2 * line_pt, zorder=7))
    if balls is not None:
        _draw_balls(ax, _per_field(balls, field_index, "balls"), (ball or BallSpec()).radius, line_pt)
    if collisions is not None:
        _draw_collisions(ax, collisions, collision_robot, [colors[i] for i in controlled], line_pt)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    if image.shape != (height, width, 3):
        raise RuntimeError(f"matplotlib drew {image.shape}, expected {(height, width, 3)}")
    return image


def _draw_balls(ax: Axes, points: np.ndarray, radius: float, line_pt: float) -> None:
    """Balls (B, 2) as orange discs with a dark edge, above the robots, of the ball's ``radius`` but at
    least a field line's width, so that a ball stays visible in a small image."""
    radius = max(radius, _LINE_WIDTH_M)
    ax.add_collection(
        PatchCollection(
            [Circle(tuple(p), radius) for p in points[:, :2]],
            facecolors=BALL,
            edgecolors="#101010",
            linewidths=0.4 * line_pt,
            zorder=7,
        )
    )


def _draw_collisions(
    ax: Axes, collisions: np.ndarray, owner: Sequence[int] | None, colors: list[str], line_pt: float
) -> None:
    """Crosses at the points ``collisions`` (C, 2), each in the colour of its controlled robot ``owner[c]``
    (an index into ``colors``, the controlled robots' colours; default 0), above everything else."""
    points = np.asarray(collisions, dtype=float).reshape(-1, 2)
    owner = [0] * len(points) if owner is None else owner
    marks = {"marker": COLLISION_MARKER, "edgecolors": "#101010", "linewidths": 0.8 * line_pt, "zorder": 8}
    cross = [colors[j] for j in _owner_indices(owner, len(points), len(colors))]
    ax.scatter(points[:, 0], points[:, 1], s=(12 * line_pt) ** 2, c=cross, **marks)


def _robot_colors(
    teams: np.ndarray, palette: Sequence[str], team_colors: Sequence[str]
) -> tuple[list[str], np.ndarray]:
    """Each robot's colour: its team's of ``team_colors``, or with several controlled robots (team 0) a
    colour of ``palette`` of its own for each of them. Also the indices of the controlled robots."""
    colors = [team_colors[t % len(team_colors)] for t in teams]
    controlled = np.flatnonzero(teams == 0)
    if len(controlled) > 1:
        for j, i in enumerate(controlled):
            colors[i] = palette[j % len(palette)]
    return colors, controlled


def _disc_style(
    teams: np.ndarray, colors: list[str], controlled: np.ndarray, ssl_teams: bool, line_pt: float
) -> dict[str, Any]:
    """The robots' discs' ``PatchCollection`` colours and widths: each in its colour of ``colors`` with a
    dark edge; in an SSL game each in its team's colour, several controlled robots ringed in their own."""
    faces, edges, widths = colors, ["#101010"] * len(teams), np.full(len(teams), 0.6 * line_pt)
    if ssl_teams:
        faces = [SSL_YELLOW if t == 0 else SSL_BLUE for t in teams]
        if len(controlled) > 1:
            for i in controlled:
                edges[i], widths[i] = colors[i], 2.0 * line_pt
    return {"facecolors": faces, "edgecolors": edges, "linewidths": widths}


def _owned(
    default: str, rows: int, controlled: int, palette: Sequence[str], owner: Sequence[int] | None = None
) -> list[str]:
    """Colours of ``rows`` target or sub-goal rows: the owning robot's of ``palette``, of ``controlled``
    robots, where there are several."""
    if controlled <= 1:
        return [default] * rows
    owner = range(rows) if owner is None else owner
    if len(owner) != rows or not all(0 <= j < controlled for j in owner):
        raise ValueError(f"subgoal_robot: {list(owner)} does not name one of {controlled} robots per row")
    return [palette[j % len(palette)] for j in owner]


def _canvas(field: Field, width: int, height: int) -> tuple[FigureCanvasAgg, object, float]:
    """An Agg canvas of width x height pixels showing the walled area plus a margin, centred, at one scale
    in x and y whatever the image's aspect; its axes, and the width in points of a field line."""
    dpi = 100
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor=WALL)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_axis_off()
    hx, hy = field.wall_half_extent
    metres_per_px = max(2 * (hx + 0.05) / width, 2 * (hy + 0.05) / height)
    ax.set_xlim(-width * metres_per_px / 2, width * metres_per_px / 2)
    ax.set_ylim(-height * metres_per_px / 2, height * metres_per_px / 2)
    return canvas, ax, _LINE_WIDTH_M / metres_per_px * 72 / dpi


def _draw_trails(
    ax: object, trails: Sequence[np.ndarray], owners: Sequence[int] | None, colors: list[str], line_pt: float
) -> None:
    """Polylines (T, 2), the i-th in the colour of robot ``owners[i]`` (default: robot i)."""
    owners = range(len(trails)) if owners is None else owners
    if len(owners) != len(trails) or not all(0 <= i < len(colors) for i in owners):
        raise ValueError(f"trail_robot: {list(owners)} does not name one of {len(colors)} robots per trail")
    for trail, i in zip(trails, owners, strict=True):
        trail = np.asarray(trail, dtype=float).reshape(-1, 2)
        style = {"lw": 1.2 * line_pt, "alpha": 0.85, "zorder": 3, "solid_capstyle": "round"}
        ax.plot(trail[:, 0], trail[:, 1], color=colors[i], **style)


def _draw_targets(ax: object, points: np.ndarray, colors: list[str], radius: float, line_pt: float) -> None:
    """Targets (M, K >= 2) as rings with a centre dot, and a heading tick where K >= 3."""
    x, y = points[:, 0], points[:, 1]
    ring = {"facecolors": "none", "edgecolors": colors, "linewidths": 1.2 * line_pt, "zorder": 4}
    ax.scatter(x, y, s=(9 * line_pt) ** 2, **ring)
    ax.scatter(x, y, s=(1.6 * line_pt) ** 2, c=colors, zorder=4)
    if points.shape[1] >= 3:
        ax.add_collection(_ticks(points[:, 0:2], points[:, 2], 2 * radius, colors, 1.2 * line_pt))


def _owner_indices(owner: Sequence[int], rows: int, controlled: int) -> list[int]:
    """``owner`` checked: one index among the ``controlled`` robots per row."""
    if len(owner) != rows or not all(0 <= j < controlled for j in owner):
        raise ValueError(f"collision_robot: {list(owner)} does not name one of {controlled} robots per row")
    return list(owner)


def _per_field(points: np.ndarray, field_index: int, name: str) -> np.ndarray:
    """Rows (M, K >= 2) of ``points`` (N, K) or (N, M, K) for one field."""
    points = np.asarray(points, dtype=float)
    if points.ndim not in (2, 3) or points.shape[-1] < 2:
        raise ValueError(f"{name} must have shape (N, K) or (N, M, K) with K >= 2, got {points.shape}")
    return np.atleast_2d(points[field_index])


def _ticks(
    pos: np.ndarray,
    angle: np.ndarray,
    length: float,
    color: str | Sequence[str],
    width: float,
    zorder: int = 4,
) -> LineCollection:
    """Heading ticks: segments from each point ``length`` metres along its angle."""
    tip = pos + length * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    return LineCollection(
        np.stack([pos, tip], axis=1), colors=color, linewidths=width, zorder=zorder, capstyle="round"
    )


def _draw_field(ax: object, field: Field, line_pt: float) -> None:
    """Carpet, walls, field lines, centre circle, penalty (defense) areas and goals."""
    hx, hy = field.wall_half_extent
    half_l, half_w = field.half_length, field.half_width
    ax.add_patch(
        Rectangle((-hx, -hy), 2 * hx, 2 * hy, facecolor=CARPET, edgecolor=WALL, lw=3 * line_pt, zorder=0)
    )
    line = {"color": LINE, "lw": line_pt, "zorder": 1, "solid_capstyle": "butt"}
    ax.add_patch(
        Rectangle(
            (-half_l, -half_w), 2 * half_l, 2 * half_w, fill=False, edgecolor=LINE, lw=line_pt, zorder=1
        )
    )
    ax.plot([0, 0], [-half_w, half_w], **line)
    ax.add_patch(Circle((0, 0), _CENTRE_RADIUS_M, fill=False, edgecolor=LINE, lw=line_pt, zorder=1))
    for side in (-1, 1):
        x_line, x_inner = side * half_l, side * (half_l - field.penalty_area_depth)
        py = field.penalty_area_width / 2
        ax.plot([x_line, x_inner, x_inner, x_line], [-py, -py, py, py], **line)
    # The goals' walls, as the world's bodies have them where it holds balls.
    for x0, x1, y0, y1 in goal_boxes(field):
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor=GOAL, edgecolor="none", zorder=2))
