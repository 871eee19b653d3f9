"""Where a planner may send a robot under the rules: the nearest legal point to a target, whether a straight
path keeps clear of the zones, and the stop speed applied to a sub-goal. Pure functions over the zones of
``hier_ssl.game.zones``.

The zones' arrays may have any leading shape (..., S) that broadcasts against the points' (..., 2): the
referee's (N, M, S) for N fields of M robots, or a planner's rows (B, S) (``row_rules``).

The nearest legal point is exact, not iterated. The legal set is what every zone leaves; its boundary is
made of pieces of the zones' boundaries, each a piece of a circle (a capsule's end, a box's inflated corner)
or of a straight line (a capsule's side, a box's inflated edge, a keep-in box's shrunk edge). The nearest
point of a closed set to an outside target lies on that boundary, either inside one piece, where it is the
target's projection onto that piece's whole circle or line, or at a piece's end, where two of those curves
cross. So the candidates are the target itself, its projections onto every curve, and every crossing of
two curves; the nearest of those that breaks no zone is the answer, overlaps of any number of zones
included. Every curve lies ``SLACK`` beyond its zone, so that a point on it keeps the clearance
despite rounding (``violates`` is False there).

The nearest legal point and a path's clearance are numba loops, one robot (one path) at a time: a planner
asks for them at every decision and, in ``trajectory``, at every collision check of every path, where
numpy's temporaries over (robots, paths, checks, zones) cost more than the arithmetic (a team of 11 in
STOP: a decision of ``direct`` from 16 ms to 0.1 ms, ``benchmarks/team_decision.py``). The compiled
planners call the one-zone pieces (``hier_ssl.game.segments`` and ``zones.zone_distance``) directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from hier_ssl.game.segments import segment_away
from hier_ssl.game.zones import BOX, CAPSULE, KEEP_IN, Zones, signed_distance, zone_distance

SLACK = 1e-9  # m a projected point keeps beyond the clearance: the rounding of a projection is ~1e-16 m
# The share of a speed limit a robot's own software caps its commands at (``cap_speed``), as every SSL
# team's does: the robots reach their commands within the acceleration limits and vision measures their
# speed with noise; a robot at the limit itself would be called for the smallest overshoot. The deploy
# controller and the game scenarios' ``speed_guard`` share it.
SPEED_MARGIN = 0.9


@dataclass(frozen=True)
class RowRules:
    """What the rules ask of B robots a planner decides at once, one row each (its batch's rows): ``zones``
    with arrays (B, S) and ``speed`` (B,) m/s, the fastest each may go (inf: no limit, 0: HALT)."""

    zones: Zones
    speed: np.ndarray


def row_rules(zones: Zones, speed: np.ndarray) -> RowRules:
    """The rules of N fields of M robots, ``forbidden_zones`` (N, M, S) and ``speed_limit`` (N,), as N * M
    planner rows, field by field (row n * M + m is field n's robot m)."""
    n, m, s = zones.kind.shape
    flat = Zones(
        zones.kind.reshape(n * m, s), zones.shape.reshape(n * m, s, 4), zones.clearance.reshape(n * m, s)
    )
    return RowRules(flat, np.repeat(np.asarray(speed, dtype=float), m))


def distances(zones: Zones, points: np.ndarray) -> np.ndarray:
    """(..., S) signed distances of ``points`` (..., 2) from their own zones (..., S): ``signed_distance``
    over any broadcasting leading shapes, where that one takes (N, M)."""
    lead = np.broadcast_shapes(points.shape[:-1], zones.kind.shape[:-1])
    flat = int(np.prod(lead, dtype=np.int64))
    s = zones.kind.shape[-1]
    z = Zones(
        np.broadcast_to(zones.kind, lead + (s,)).reshape(1, flat, s),
        np.broadcast_to(zones.shape, lead + (s, 4)).reshape(1, flat, s, 4),
        np.broadcast_to(zones.clearance, lead + (s,)).reshape(1, flat, s),
    )
    return signed_distance(z, np.broadcast_to(points, lead + (2,)).reshape(1, flat, 2)).reshape(lead + (s,))


@numba.njit(cache=True)
def _curves(kind: np.ndarray, shape: np.ndarray, clearance: np.ndarray) -> tuple:
    """One robot's zone boundaries, SLACK beyond them: circles (C, 3) x, y, radius and lines (L, 4) a point
    and a unit direction. Per slot: a capsule's two end circles and two sides; a box's four corner circles
    and four edges pushed out; a keep-in box's four edges pulled in."""
    s = kind.shape[0]
    circles, lines = np.empty((4 * s, 3)), np.empty((4 * s, 4))
    nc = nl = 0
    for k in range(s):
        x0, y0, x1, y1 = shape[k, 0], shape[k, 1], shape[k, 2], shape[k, 3]
        out = clearance[k] + SLACK
        if kind[k] == CAPSULE:
            circles[nc], circles[nc + 1] = (x0, y0, out), (x1, y1, out)
            nc += 2
            length = math.hypot(x1 - x0, y1 - y0)
            if length > 0.0:  # a point capsule (the ball) has no sides
                ux, uy = (x1 - x0) / length, (y1 - y0) / length
                lines[nl], lines[nl + 1] = (
                    (x0 - uy * out, y0 + ux * out, ux, uy),
                    (x0 + uy * out, y0 - ux * out, ux, uy),
                )
                nl += 2
        elif kind[k] == BOX or kind[k] == KEEP_IN:
            if kind[k] == BOX:
                for cx, cy in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
                    circles[nc] = (cx, cy, out)
                    nc += 1
            shift = out if kind[k] == BOX else -out
            lines[nl], lines[nl + 1] = (x0 - shift, 0.0, 0.0, 1.0), (x1 + shift, 0.0, 0.0, 1.0)
            lines[nl + 2], lines[nl + 3] = (0.0, y0 - shift, 1.0, 0.0), (0.0, y1 + shift, 1.0, 0.0)
            nl += 4
    return circles[:nc], lines[:nl]


@numba.njit(cache=True)
def _nearest_legal_row(
    px: float, py: float, kind: np.ndarray, shape: np.ndarray, clearance: np.ndarray
) -> tuple:
    """The nearest legal point to (px, py) among one robot's zones, by the candidates of the module
    docstring, in order: the target, its projections onto the circles and the lines, the crossings of two
    circles, of a circle and a line, of two lines. A candidate no nearer than the best legal one so far is
    not measured against the zones."""
    circles, lines = _curves(kind, shape, clearance)
    nc, nl, s = circles.shape[0], lines.shape[0], kind.shape[0]
    cand = np.empty((1 + nc + nl + 2 * nc * nc + 2 * nc * nl + nl * nl, 2))
    m = 0
    cand[m] = (px, py)
    m += 1
    for i in range(nc):
        cx, cy, r = circles[i, 0], circles[i, 1], circles[i, 2]
        gap = math.hypot(px - cx, py - cy)
        cand[m] = (cx + r * (px - cx) / gap, cy + r * (py - cy) / gap) if gap > 0 else (cx + r, cy)
        m += 1
    for i in range(nl):
        qx, qy, ux, uy = lines[i, 0], lines[i, 1], lines[i, 2], lines[i, 3]
        t = (px - qx) * ux + (py - qy) * uy
        cand[m] = (qx + t * ux, qy + t * uy)
        m += 1
    for i in range(nc):
        for j in range(i + 1, nc):  # the chord through both crossings: h along the centres' line, k off it
            dx, dy = circles[j, 0] - circles[i, 0], circles[j, 1] - circles[i, 1]
            d = math.hypot(dx, dy)
            if d <= 0.0:
                continue
            r1, r2 = circles[i, 2], circles[j, 2]
            h = (d * d + r1 * r1 - r2 * r2) / (2 * d)
            k2 = r1 * r1 - h * h
            if k2 < 0.0:
                continue
            k, ex, ey = math.sqrt(k2), dx / d, dy / d
            for sign in (1.0, -1.0):
                cand[m] = (circles[i, 0] + ex * h - sign * ey * k, circles[i, 1] + ey * h + sign * ex * k)
                m += 1
    for i in range(nc):
        cx, cy, r = circles[i, 0], circles[i, 1], circles[i, 2]
        for j in range(nl):  # the centre's foot on the line, then +-sqrt(r^2 - its distance^2) along it
            qx, qy, ux, uy = lines[j, 0], lines[j, 1], lines[j, 2], lines[j, 3]
            t = (cx - qx) * ux + (cy - qy) * uy
            fx, fy = qx + t * ux, qy + t * uy
            run2 = r * r - (cx - fx) ** 2 - (cy - fy) ** 2
            if run2 < 0.0:
                continue
            run = math.sqrt(run2)
            cand[m], cand[m + 1] = (fx + ux * run, fy + uy * run), (fx - ux * run, fy - uy * run)
            m += 2
    for i in range(nl):
        for j in range(i + 1, nl):  # q1 + s u1 = q2 + t u2
            q1x, q1y, u1x, u1y = lines[i, 0], lines[i, 1], lines[i, 2], lines[i, 3]
            q2x, q2y, u2x, u2y = lines[j, 0], lines[j, 1], lines[j, 2], lines[j, 3]
            cross = u1x * u2y - u1y * u2x
            if abs(cross) < 1e-12:
                continue
            t = ((q2x - q1x) * u2y - (q2y - q1y) * u2x) / cross
            cand[m] = (q1x + t * u1x, q1y + t * u1y)
            m += 1
    best, best_far, least, least_worst = -1, math.inf, 0, -math.inf
    for c in range(m):
        x, y = cand[c, 0], cand[c, 1]
        far = math.hypot(x - px, y - py)
        if far >= best_far:
            continue
        worst = math.inf
        for k in range(s):
            worst = min(worst, zone_distance(x, y, kind[k], shape[k], clearance[k]))
        if worst >= 0.0:
            best, best_far = c, far
        elif best < 0 and worst > least_worst:
            least, least_worst = c, worst
    pick = best if best >= 0 else least
    return cand[pick, 0], cand[pick, 1]


@numba.njit(cache=True)
def _nearest_legal_rows(
    points: np.ndarray, kind: np.ndarray, shape: np.ndarray, clearance: np.ndarray, broken: np.ndarray
) -> np.ndarray:
    """``_nearest_legal_row`` of every ``broken`` row of points (R, 2) and zones (R, S), the rest kept."""
    out = points.copy()
    for i in range(points.shape[0]):
        if broken[i]:
            out[i, 0], out[i, 1] = _nearest_legal_row(
                points[i, 0], points[i, 1], kind[i], shape[i], clearance[i]
            )
    return out


def nearest_legal(zones: Zones, points: np.ndarray) -> np.ndarray:
    """(..., 2) the nearest point to each target ``points`` (..., 2) m that breaks none of its zones
    (..., S): the target itself, bit for bit, where it breaks none; a point SLACK beyond the clearance of
    the zone it broke (or at the corner two zones make where they overlap) otherwise. Where no point keeps
    every zone (zones that cover all the walled area), the candidate that breaks them least (its worst
    signed distance the highest). Exact: see the module docstring; ties go to the first candidate."""
    points = np.asarray(points, dtype=float)
    broken = (distances(zones, points) < 0.0).any(-1)
    if not broken.any():
        return points
    lead, s = broken.shape, zones.kind.shape[-1]
    out = _nearest_legal_rows(
        np.ascontiguousarray(np.broadcast_to(points, lead + (2,)).reshape(-1, 2)),
        np.ascontiguousarray(np.broadcast_to(zones.kind, lead + (s,)).reshape(-1, s), np.int64),
        np.ascontiguousarray(np.broadcast_to(zones.shape, lead + (s, 4)).reshape(-1, s, 4), np.float64),
        np.ascontiguousarray(np.broadcast_to(zones.clearance, lead + (s,)).reshape(-1, s), np.float64),
        broken.reshape(-1),
    )
    return out.reshape(lead + (2,))


@numba.njit(cache=True)
def _rows_path_clearance(
    kind: np.ndarray, shape: np.ndarray, clearance: np.ndarray, start: np.ndarray, end: np.ndarray
) -> np.ndarray:
    """(N, P, S) ``path_clearance`` of the paths start -> end (N, P) complex against their row's zones:
    kind (N, S), shape (N, S, 4), clearance (N, S). One pass, no temporaries."""
    n, p, s = start.shape[0], start.shape[1], kind.shape[1]
    out = np.empty((n, p, s))
    for i in range(n):
        for j in range(p):
            x0, y0, x1, y1 = start[i, j].real, start[i, j].imag, end[i, j].real, end[i, j].imag
            for k in range(s):
                z = shape[i, k]
                out[i, j, k] = (
                    segment_away(x0, y0, x1, y1, kind[i, k], z[0], z[1], z[2], z[3]) - clearance[i, k]
                )
    return out


def segment_clearance(zones: Zones, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """(..., S) how far the straight path ``start`` -> ``end`` (..., 2) m keeps from breaking each zone
    (..., S): the least signed distance of any of its points, +inf for an empty slot. A path through a
    capsule's segment or a box's inside scores minus the clearance (its depth inside is not measured): any
    negative value means the path breaks the zone. A keep-in box is convex, so its value is the worse end's.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    return path_clearance(zones, start[..., 0] + 1j * start[..., 1], end[..., 0] + 1j * end[..., 1])


def path_clearance(zones: Zones, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """``segment_clearance`` for complex ends ``start``, ``end`` (...,): the planners' form. Zones of one
    row per leading index of the paths ((N, 1, ..., 1, S) against paths (N, ...)) are read in place; any
    other broadcast is spread out first."""
    start, end = np.broadcast_arrays(np.asarray(start, complex), np.asarray(end, complex))
    lead, s = zones.kind.shape[:-1], zones.kind.shape[-1]
    full = np.broadcast_shapes(lead, start.shape)
    # In place only where the zones' axes are the paths' own (N, 1, ..., 1): zones (N,) against paths
    # (N, N) broadcast along the paths' last axis, and are spread out like any other broadcast.
    in_place = len(lead) == len(full) >= 1 and lead[0] == full[0] and all(d == 1 for d in lead[1:])
    if full == start.shape and in_place:
        kind, shape, clearance = (
            x.reshape((lead[0], s) + x.shape[len(lead) + 1 :])
            for x in (zones.kind, zones.shape, zones.clearance)
        )
        rows = (full[0], -1)
    else:
        flat = int(np.prod(full, dtype=np.int64))
        kind = np.broadcast_to(zones.kind, full + (s,)).reshape(flat, s)
        shape = np.broadcast_to(zones.shape, full + (s, 4)).reshape(flat, s, 4)
        clearance = np.broadcast_to(zones.clearance, full + (s,)).reshape(flat, s)
        rows = (flat, 1)
    out = _rows_path_clearance(
        np.ascontiguousarray(kind, np.int64),
        np.ascontiguousarray(shape, np.float64),
        np.ascontiguousarray(clearance, np.float64),
        np.ascontiguousarray(np.broadcast_to(start, full)).reshape(rows),
        np.ascontiguousarray(np.broadcast_to(end, full)).reshape(rows),
    )
    return out.reshape(full + (s,))


def cap_speed(velocity: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """(..., 2) the velocities ``velocity`` (..., 2) m/s scaled down, direction kept, to at most ``limit``
    (...) m/s (``speed_limit``: 0 in HALT, 1.5 in STOP, inf otherwise); one within its limit is returned
    bit for bit."""
    velocity = np.asarray(velocity, dtype=float)
    limit = np.asarray(limit, dtype=float)
    speed = np.hypot(velocity[..., 0], velocity[..., 1])
    over = speed > limit
    if not over.any():  # outside STOP and HALT the limit is inf: most calls cap nothing
        return velocity
    scale = np.where(over, limit / np.where(over, speed, 1.0), 1.0)
    return np.where(over[..., None], velocity * scale[..., None], velocity)


__all__ = [
    "SLACK",
    "SPEED_MARGIN",
    "RowRules",
    "cap_speed",
    "distances",
    "nearest_legal",
    "path_clearance",
    "row_rules",
    "segment_clearance",
]
