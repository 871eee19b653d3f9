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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hier_ssl.game.zones import BOX, CAPSULE, KEEP_IN, NONE, Zones, signed_distance

SLACK = 1e-9  # m a projected point keeps beyond the clearance: the rounding of a projection is ~1e-16 m


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


def _curves(zones: Zones) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The zones' boundaries, SLACK beyond them: circles (centres complex (..., C), radii (..., C), NaN where
    a slot has none) and lines (a point complex (..., L) and unit direction complex (..., L), NaN where
    none). Per slot: a capsule's two end circles and two sides; a box's four corner circles and four edges
    pushed out; a keep-in box's four edges pulled in."""
    kind, c = zones.kind, zones.clearance
    x0, y0, x1, y1 = np.moveaxis(zones.shape, -1, 0)
    a, b = x0 + 1j * y0, x1 + 1j * y1
    nan = np.full(kind.shape, np.nan)
    capsule, box, keep = kind == CAPSULE, kind == BOX, kind == KEEP_IN
    out, inn = c + SLACK, -(c + SLACK)

    corners = [x0 + 1j * y0, x1 + 1j * y0, x1 + 1j * y1, x0 + 1j * y1]
    centres = [np.where(capsule, a, np.nan), np.where(capsule, b, np.nan)]
    centres += [np.where(box, q, np.nan) for q in corners]
    radii = [np.where(capsule, out, nan)] * 2 + [np.where(box, out, nan)] * 4

    along = b - a
    length = np.abs(along)
    unit = np.where(length > 0, along / np.where(length > 0, length, 1.0), 1.0)
    side = 1j * unit * out  # a capsule's sides: the segment moved out either way; a point capsule has none
    real = capsule & (length > 0)
    points = [np.where(real, a + side, np.nan), np.where(real, a - side, np.nan)]
    directions = [np.where(real, unit, np.nan)] * 2
    # A box's edges (x = x0, x = x1, y = y0, y = y1), moved ``shift`` outwards: out for BOX, in for KEEP_IN.
    for shift, mask in ((out, box), (inn, keep)):
        points += [
            np.where(mask, (x0 - shift) + 0j, np.nan),
            np.where(mask, (x1 + shift) + 0j, np.nan),
            np.where(mask, 1j * (y0 - shift), np.nan),
            np.where(mask, 1j * (y1 + shift), np.nan),
        ]
        directions += [np.where(mask, 1j, np.nan)] * 2 + [np.where(mask, 1.0 + 0j, np.nan)] * 2
    flat = kind.shape[:-1] + (-1,)
    return (
        np.stack(centres, -1).reshape(flat),
        np.stack(radii, -1).reshape(flat),
        np.stack(points, -1).reshape(flat),
        np.stack(directions, -1).reshape(flat),
    )


def _candidates(p: np.ndarray, zones: Zones) -> np.ndarray:
    """(..., K) complex: the target ``p`` (...,) complex, its projections onto every boundary curve and
    every crossing of two curves (module docstring); NaN where a curve or crossing does not exist."""
    centre, radius, point, direction = _curves(zones)
    p = p[..., None]
    # Projections: onto a circle along the ray from its centre (a target at the centre goes +x, one of its
    # equally near points), onto a line at the foot of the perpendicular.
    off = p - centre
    gap = np.abs(off)
    on_circle = centre + radius * np.where(gap > 0, off / np.where(gap > 0, gap, 1.0), 1.0)
    on_line = point + direction * ((p - point) * direction.conj()).real
    # Circle-circle: the chord through both crossings, at ``h`` along the line of centres, ``k`` off it.
    c1, c2 = centre[..., :, None], centre[..., None, :]
    r1, r2 = radius[..., :, None], radius[..., None, :]
    d = np.abs(c2 - c1)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = (c2 - c1) / d
        h = (d * d + r1 * r1 - r2 * r2) / (2 * d)
        k = np.sqrt(r1 * r1 - h * h)  # NaN where they do not cross
        cc = [c1 + e * (h + 1j * k), c1 + e * (h - 1j * k)]
        # Circle-line: the foot of the centre on the line, then +-sqrt(r^2 - foot distance^2) along it.
        c, r = centre[..., :, None], radius[..., :, None]
        q, u = point[..., None, :], direction[..., None, :]
        foot = q + u * ((c - q) * u.conj()).real
        run = np.sqrt(r * r - np.abs(c - foot) ** 2)
        cl = [foot + u * run, foot - u * run]
        # Line-line: q1 + s u1 = q2 + t u2, s from the cross products; parallel lines give inf or NaN.
        q1, u1 = point[..., :, None], direction[..., :, None]
        q2, u2 = point[..., None, :], direction[..., None, :]
        cross = (u1.conj() * u2).imag
        s = ((q2 - q1).conj() * u2).imag / cross
        ll = q1 + u1 * np.where(np.abs(cross) > 1e-12, s, np.nan)
    lead = p.shape[:-1]
    parts = [p, on_circle, on_line, *cc, *cl, ll]
    return np.concatenate(
        [np.broadcast_to(x, lead + x.shape[len(lead) :]).reshape(lead + (-1,)) for x in parts], -1
    )


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
    lead = broken.shape
    rows = np.flatnonzero(broken.reshape(-1))
    target = np.broadcast_to(points, lead + (2,)).reshape(-1, 2)[rows]
    s = zones.kind.shape[-1]
    sub = Zones(
        np.broadcast_to(zones.kind, lead + (s,)).reshape(-1, s)[rows],
        np.broadcast_to(zones.shape, lead + (s, 4)).reshape(-1, s, 4)[rows],
        np.broadcast_to(zones.clearance, lead + (s,)).reshape(-1, s)[rows],
    )
    cand = _candidates(target[:, 0] + 1j * target[:, 1], sub)
    finite = np.isfinite(cand)
    xy = np.stack([np.where(finite, cand.real, 0.0), np.where(finite, cand.imag, 0.0)], -1)
    worst = distances(Zones(sub.kind[:, None], sub.shape[:, None], sub.clearance[:, None]), xy).min(-1)
    worst = np.where(finite, worst, -np.inf)
    legal = worst >= 0.0
    far = np.abs(cand - (target[:, 0] + 1j * target[:, 1])[:, None])
    score = np.where(legal.any(-1, keepdims=True), np.where(legal, far, np.inf), -worst)
    best = np.argmin(score, axis=-1)
    out = np.broadcast_to(points, lead + (2,)).reshape(-1, 2).copy()
    out[rows] = xy[np.arange(len(rows)), best]
    return out.reshape(lead + (2,))


def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of complex points ``p`` from the segments a -> b (broadcast); a point segment is a point."""
    ab = b - a
    length2 = np.abs(ab) ** 2
    t = np.clip(((p - a) * ab.conj()).real / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    return np.abs(p - a - t * ab)


def _segments_cross(p0: np.ndarray, p1: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether the segments p0 -> p1 and a -> b cross properly (each one's ends strictly either side of the
    other's line); touching counts as distance 0 through the end distances instead."""
    d, e = p1 - p0, b - a
    side_a, side_b = (d.conj() * (a - p0)).imag, (d.conj() * (b - p0)).imag
    side_0, side_1 = (e.conj() * (p0 - a)).imag, (e.conj() * (p1 - a)).imag
    return (side_a * side_b < 0) & (side_0 * side_1 < 0)


def segment_clearance(zones: Zones, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """(..., S) how far the straight path ``start`` -> ``end`` (..., 2) m keeps from breaking each zone
    (..., S): the least signed distance of any of its points, +inf for an empty slot. A path through a
    capsule's segment or a box's inside scores minus the clearance (its depth inside is not measured): any
    negative value means the path breaks the zone. A keep-in box is convex, so its value is the worse end's.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    return path_clearance(zones, start[..., 0] + 1j * start[..., 1], end[..., 0] + 1j * end[..., 1])


def path_clearance(zones: Zones, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """``segment_clearance`` for complex ends ``start``, ``end`` (...,): the planners' form."""
    p0, p1 = start[..., None], end[..., None]
    x0, y0, x1, y1 = np.moveaxis(zones.shape, -1, 0)
    a, b = x0 + 1j * y0, x1 + 1j * y1
    # Capsule: two segments are as near as an end of one to the other, unless they cross.
    ends = np.minimum(
        np.minimum(_point_segment(p0, a, b), _point_segment(p1, a, b)),
        np.minimum(_point_segment(a, p0, p1), _point_segment(b, p0, p1)),
    )
    capsule = np.where(_segments_cross(p0, p1, a, b), 0.0, ends)

    # Box: a segment outside a box is as near as its ends to the box or the box's corners to it; it is
    # inside (distance 0) if it crosses the box (slab test on the segment's parameter 0..1).
    def box_distance(q: np.ndarray) -> np.ndarray:
        dx = np.maximum(np.maximum(x0 - q.real, q.real - x1), 0.0)
        dy = np.maximum(np.maximum(y0 - q.imag, q.imag - y1), 0.0)
        return np.hypot(dx, dy)

    corners = [x0 + 1j * y0, x1 + 1j * y0, x1 + 1j * y1, x0 + 1j * y1]
    near = np.minimum(box_distance(p0), box_distance(p1))
    for q in corners:
        near = np.minimum(near, _point_segment(q, p0, p1))
    d = p1 - p0
    lo, hi = np.zeros(near.shape), np.ones(near.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        for s, v, low, high in ((p0.real, d.real, x0, x1), (p0.imag, d.imag, y0, y1)):
            t0, t1 = (low - s) / v, (high - s) / v
            still = v == 0
            lo = np.where(
                still, np.where((s >= low) & (s <= high), lo, np.inf), np.maximum(lo, np.minimum(t0, t1))
            )
            hi = np.where(still, hi, np.minimum(hi, np.maximum(t0, t1)))
    box = np.where(lo <= hi, 0.0, near)

    # Keep-in: the signed distance inside the box, at the worse end.
    def inside(q: np.ndarray) -> np.ndarray:
        return np.minimum(np.minimum(q.real - x0, x1 - q.real), np.minimum(q.imag - y0, y1 - q.imag))

    keep = np.minimum(inside(p0), inside(p1))
    kind = zones.kind
    away = np.select([kind == CAPSULE, kind == BOX, kind == KEEP_IN], [capsule, box, keep], 0.0)
    return np.where(kind == NONE, np.inf, away - zones.clearance)


def cap_speed(velocity: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """(..., 2) the velocities ``velocity`` (..., 2) m/s scaled down, direction kept, to at most ``limit``
    (...) m/s (``speed_limit``: 0 in HALT, 1.5 in STOP, inf otherwise); one within its limit is returned
    bit for bit."""
    velocity = np.asarray(velocity, dtype=float)
    limit = np.asarray(limit, dtype=float)
    speed = np.hypot(velocity[..., 0], velocity[..., 1])
    over = speed > limit
    scale = np.where(over, limit / np.where(over, speed, 1.0), 1.0)
    return np.where(over[..., None], velocity * scale[..., None], velocity)


__all__ = [
    "SLACK",
    "RowRules",
    "cap_speed",
    "distances",
    "nearest_legal",
    "path_clearance",
    "row_rules",
    "segment_clearance",
]
