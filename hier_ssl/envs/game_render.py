"""What a game scenario draws over the field (docs/guide/ssl-game.md, "The game scenarios"): the zones the
referee's state forbids one of our robots, shaded; the referee's command, named; a cross where each of our
robots committed a foul. ``GameScenario.drawing`` binds it to a field's state of one control step, so that
a recorded episode (``hier_ssl.envs.play.Recorder``) draws the game as it was at each step."""

from __future__ import annotations

from typing import Any

import numpy as np

from hier_ssl.game import COMMANDS, Lineup, RefereeState, forbidden_zones
from hier_ssl.game.zones import BALL, OPPONENT_DEFENSE, OWN_DEFENSE
from hier_ssl.world.field import Field

ZONE, FOUL = "#e03131", "#e03131"


def draw_game(
    ax: Any,
    *,
    field: Field,
    lineup: Lineup,
    robot: int,
    referee: RefereeState,
    ball: np.ndarray,
    fouls: np.ndarray,
) -> None:
    """On matplotlib ``ax`` (field frame, m): the active zones of robot ``robot`` of ``lineup`` under
    ``referee`` (one field) with the ball at ``ball`` (1, 2), shaded (the ball's stadium or circle, the
    defense areas with their clearance); the referee's command above the field; a cross at each point of
    ``fouls`` (M, 2) that is not NaN."""
    zones = forbidden_zones(referee, ball, field, lineup)
    for slot in (OWN_DEFENSE, OPPONENT_DEFENSE, BALL):
        kind, (x0, y0, x1, y1), clear = (
            a[0, robot, slot] for a in (zones.kind, zones.shape, zones.clearance)
        )
        if kind == 0:
            continue
        if slot == BALL:  # a capsule: the stadium of the points within the clearance of the segment
            ax.fill(*stadium(x0, y0, x1, y1, clear).T, color=ZONE, alpha=0.25, zorder=1)
        else:
            xs, ys = (
                (x0 - clear, x1 + clear, x1 + clear, x0 - clear),
                (y0 - clear, y0 - clear, y1 + clear, y1 + clear),
            )
            ax.fill(xs, ys, color=ZONE, alpha=0.2, zorder=1)
    name = COMMANDS[int(referee.command[0])]
    ax.text(-field.half_length, field.half_width + 0.1, name, color="white", fontsize=8, zorder=6)
    fouls = fouls[~np.isnan(fouls[:, 0])]
    if len(fouls):
        ax.plot(fouls[:, 0], fouls[:, 1], "x", color=FOUL, markersize=9, mew=2.5, zorder=9)


def stadium(x0: float, y0: float, x1: float, y1: float, radius: float) -> np.ndarray:
    """The outline (P, 2) of the points within ``radius`` of the segment (x0, y0) -> (x1, y1)."""
    heading = np.arctan2(y1 - y0, x1 - x0)
    turn = np.linspace(-np.pi / 2, np.pi / 2, 16)
    ends = [(x1, y1, heading + turn), (x0, y0, heading + np.pi + turn)]
    return np.concatenate(
        [np.stack([x + radius * np.cos(a), y + radius * np.sin(a)], -1) for x, y, a in ends]
    )


__all__ = ["FOUL", "ZONE", "draw_game", "stadium"]
