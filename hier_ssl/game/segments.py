"""A straight path against one zone's shape (``hier_ssl.game.zones``): how far it keeps from the shape,
whether it breaks the zone, and how deep it crosses a capsule's segment. Compiled scalar functions: the
planners call them in their own loops (``hier_ssl.manager.path_search``, ``sampling_rollouts``) and
``hier_ssl.game.legal`` over arrays of paths.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hier_ssl.game.zones import BOX, CAPSULE, KEEP_IN, point_segment


@numba.njit(cache=True)
def _crossing_at(
    x0: float, y0: float, x1: float, y1: float, ax: float, ay: float, bx: float, by: float
) -> float:
    """Where the segment (x0, y0) -> (x1, y1) crosses a -> b, as the fraction 0..1 of the way from a to b;
    -1 where they do not cross (each one's ends strictly either side of the other's line)."""
    dx, dy, ex, ey = x1 - x0, y1 - y0, bx - ax, by - ay
    side_a, side_b = dx * (ay - y0) - dy * (ax - x0), dx * (by - y0) - dy * (bx - x0)
    side_0, side_1 = ex * (y0 - ay) - ey * (x0 - ax), ex * (y1 - ay) - ey * (x1 - ax)
    if side_a * side_b < 0.0 and side_0 * side_1 < 0.0:
        return side_a / (side_a - side_b)
    return -1.0


@numba.njit(cache=True)
def axis_depth(
    x0: float, y0: float, x1: float, y1: float, ax: float, ay: float, bx: float, by: float, ends: int
) -> float:
    """How far along a -> b the segment (x0, y0) -> (x1, y1) crosses it, m, from the end a way round
    takes: ``ends`` 1 past a alone, 2 past b alone, else the nearer; 0 where they do not cross.
    ``segment_away`` is 0 for every path across a capsule's segment: this tells one across it near an
    open end, which a point a little farther round clears, from one across its middle."""
    t = _crossing_at(x0, y0, x1, y1, ax, ay, bx, by)
    if t < 0.0:
        return 0.0
    ex, ey = bx - ax, by - ay
    along = t if ends == 1 else 1.0 - t if ends == 2 else min(t, 1.0 - t)
    return along * math.sqrt(ex * ex + ey * ey)


@numba.njit(cache=True)
def _segment_segment(
    x0: float, y0: float, x1: float, y1: float, ax: float, ay: float, bx: float, by: float
) -> float:
    """Distance between the segments (x0, y0) -> (x1, y1) and a -> b: 0 where they cross (each one's ends
    strictly either side of the other's line), else the least distance of an end from the other."""
    if _crossing_at(x0, y0, x1, y1, ax, ay, bx, by) >= 0.0:
        return 0.0
    return min(
        min(point_segment(x0, y0, ax, ay, bx, by), point_segment(x1, y1, ax, ay, bx, by)),
        min(point_segment(ax, ay, x0, y0, x1, y1), point_segment(bx, by, x0, y0, x1, y1)),
    )


@numba.njit(cache=True)
def _segment_box(
    x0: float, y0: float, x1: float, y1: float, bx0: float, by0: float, bx1: float, by1: float
) -> float:
    """Distance of the segment (x0, y0) -> (x1, y1) from the box: 0 where it enters the box (the slab test
    on its parameter 0..1), else the least of its ends' distances from the box and the box's corners'
    from it (a segment and a convex polygon apart are nearest at a vertex of one of them)."""
    lo, hi = 0.0, 1.0
    for s, v, low, high in ((x0, x1 - x0, bx0, bx1), (y0, y1 - y0, by0, by1)):
        if v == 0.0:
            if s < low or s > high:
                lo = math.inf
        else:
            t0, t1 = (low - s) / v, (high - s) / v
            lo, hi = max(lo, min(t0, t1)), min(hi, max(t0, t1))
    if lo <= hi:
        return 0.0
    near = math.inf
    for px, py in ((x0, y0), (x1, y1)):
        ox, oy = max(max(bx0 - px, px - bx1), 0.0), max(max(by0 - py, py - by1), 0.0)
        near = min(near, math.sqrt(ox * ox + oy * oy))
    for cx, cy in ((bx0, by0), (bx1, by0), (bx1, by1), (bx0, by1)):
        near = min(near, point_segment(cx, cy, x0, y0, x1, y1))
    return near


@numba.njit(cache=True)
def segment_away(
    x0: float, y0: float, x1: float, y1: float, kind: int, ax: float, ay: float, bx: float, by: float
) -> float:
    """How far the straight path (x0, y0) -> (x1, y1) keeps from one zone's shape (``kind``, (ax, ay, bx,
    by)), before its clearance (``segment_clearance`` less the clearance); +inf for an empty slot."""
    if kind == CAPSULE:
        return _segment_segment(x0, y0, x1, y1, ax, ay, bx, by)
    if kind == BOX:
        return _segment_box(x0, y0, x1, y1, ax, ay, bx, by)
    if kind == KEEP_IN:  # convex: the worse end
        return min(
            min(min(x0 - ax, bx - x0), min(y0 - ay, by - y0)),
            min(min(x1 - ax, bx - x1), min(y1 - ay, by - y1)),
        )
    return math.inf


@numba.njit(cache=True)
def segment_breaks(
    x0: float, y0: float, x1: float, y1: float, kind: int, shape: np.ndarray, clearance: float
) -> bool:
    """Whether the straight path (x0, y0) -> (x1, y1) breaks one zone (``segment_away`` less the
    clearance below 0): a path whose bounding box keeps farther than the clearance from the shape's,
    along x or y, is not measured (no point of it is nearer; the slack covers the rounding)."""
    ax, ay, bx, by = shape[0], shape[1], shape[2], shape[3]
    if kind == CAPSULE or kind == BOX:
        gap_x = max(min(ax, bx) - max(x0, x1), min(x0, x1) - max(ax, bx))
        gap_y = max(min(ay, by) - max(y0, y1), min(y0, y1) - max(ay, by))
        if max(gap_x, gap_y) > clearance + 1e-9:
            return False
    return segment_away(x0, y0, x1, y1, kind, ax, ay, bx, by) - clearance < 0.0


__all__ = ["axis_depth", "segment_away", "segment_breaks"]
