"""The two goals of a field as walls: each goal's two side walls and its back wall, as boxes.

Rules 2.1.4 "Goals": each goal's inner width is the field's ``goal_width`` and it reaches ``goal_depth``
behind the goal line, the side walls' front ends (the posts) on the goal line, and its walls are 0.02 m
thick (grSim's ``Goal_Thickness``, RoboCup-SSL/grSim, too). The back wall spans the side walls' outer
faces, so that a goal is one closed U.
"""

from __future__ import annotations

import numpy as np

from hier_ssl.world.field import Field

GOAL_WALL_THICKNESS = 0.02  # m, rules 2.1.4


def goal_boxes(field: Field) -> np.ndarray:
    """The six walls of ``field``'s goals as boxes (6, 4): x_min, x_max, y_min, y_max each, field frame,
    m; for the goal at x = +field_length / 2 its side walls at -y and +y and its back wall, then the
    goal at -field_length / 2."""
    t, line = GOAL_WALL_THICKNESS, field.half_length
    back, half = line + field.goal_depth, field.goal_width / 2
    right = np.array(
        [
            [line, back + t, -half - t, -half],
            [line, back + t, half, half + t],
            [back, back + t, -half - t, half + t],
        ]
    )
    left = right.copy()
    left[:, 0], left[:, 1] = -right[:, 1], -right[:, 0]
    return np.concatenate([right, left])


def box_corners(box: np.ndarray) -> list[tuple[float, float]]:
    """A box's (4,) corners, counter-clockwise, as pymunk takes a polygon's vertices."""
    x0, x1, y0, y1 = (float(v) for v in box)
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


__all__ = ["GOAL_WALL_THICKNESS", "box_corners", "goal_boxes"]
