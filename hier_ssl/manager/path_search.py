"""The trajectory planner's compiled loops (``hier_ssl.manager.trajectory.TrajectoryPlanner``): TIGERs'
acceptors (``still_accepts``, ``moving_accepts``), the walk of a path along its collision checks
(``walk``, ``walk_paths``: ``trajectory.first_collisions``) and the search of a robot's paths through its
sub-destinations (``search``: steps 2 and 3 of ``hier_ssl.manager.trajectory``'s docstring, in
``TrajectoryPlanner.detour``), which tries one robot's paths in order, stops at the first acceptable one
and walks a path only as far as it can still win or be a fallback."""

from __future__ import annotations

import math

import numba
import numpy as np

from hier_ssl.game.segments import segment_breaks
from hier_ssl.manager.bangbang import profile_2d, state_1d


@numba.vectorize(["boolean(float64, complex128, complex128, complex128, float64)"], cache=True)
def still_accepts(time: float, where: complex, start: complex, goal: complex, threshold_time: float) -> bool:
    """TIGERs' motionless acceptor: no collision with a still obstacle, or its first (at ``time`` s,
    ``where``) nearer the path's end than ``time`` / ``threshold_time`` of the start's distance."""
    if math.isinf(time):
        return True
    return abs(where - goal) / max(abs(start - goal), 1e-9) < min(max(time / threshold_time, 0.0), 1.0)


@numba.vectorize(["boolean(float64, float64, float64, float64)"], cache=True)
def moving_accepts(time: float, speed: float, accel: float, offset: float) -> bool:
    """TIGERs' moving acceptor: the first collision with a moving obstacle comes later than the time to
    brake from ``speed`` at ``accel``, plus ``offset`` s."""
    return time > speed / accel + offset


@numba.njit(cache=True)
def walk(
    positions: np.ndarray,
    times: np.ndarray,
    start: complex,
    total: float,
    q: np.ndarray,
    u: np.ndarray,
    still: np.ndarray,
    radius: float,
    t_max: float,
    zones: tuple,
    judge: tuple = (False, 0.0, 0j, 0.0, 0.0, 0.0, 0.0),
) -> tuple:
    """The first collisions of one path (``first_collisions``): its ``positions`` (C,) complex at the
    check ``times`` (C,), from ``start``, lasting ``total`` s, against obstacles (K,) and the rules' zones
    (kind (S,), shape (S, 4), clearance (S,), which the robot already breaks (S,): S = 0 unchecked).
    Returns still time and position, moving time and position, zone time and position (inf, 0: none).

    ``judge``: (on, the switch time, the goal, threshold_max_collision_time, the robot's speed, its
    braking, brake_time_offset): on, the walk stops as soon as the path can neither win nor be a fallback
    of ``search``: a still collision the still acceptor refuses, a step into a zone before the switch, or
    after it with a collision the moving acceptor refuses."""
    kind, shape, clearance, leaving = zones
    judged, switch, goal, threshold_time, speed, brake, brake_offset = judge
    still_t = still_x = still_y = moving_x = moving_y = zone_x = zone_y = 0.0
    still_t = moving_t = zone_t = math.inf
    last_x, last_y = start.real, start.imag
    for c in range(positions.shape[0]):
        t = times[c]
        if not t < total:  # the checks come in order: none later is on the path
            break
        px, py = positions[c].real, positions[c].imag
        seen = min(t, t_max)
        hit_still = hit_moving = False
        for k in range(q.shape[0]):
            if still[k] and not math.isinf(still_t) or not still[k] and not math.isinf(moving_t):
                continue  # its kind's first collision is found
            nx, ny = px - (q[k].real + u[k].real * seen), py - (q[k].imag + u[k].imag * seen)
            hit = math.hypot(nx, ny) < radius
            if c > 0 and not hit:  # the closest approach on the straight stretch from the previous check
                before = min(times[c - 1], t_max)
                bx = positions[c - 1].real - (q[k].real + u[k].real * before)
                by = positions[c - 1].imag - (q[k].imag + u[k].imag * before)
                mx, my = nx - bx, ny - by
                # No point of the stretch is nearer than its nearer end less half its length: only a
                # stretch that may come within the radius is measured (the slack covers the rounding).
                reach = radius * (1.0 + 1e-9) + 0.5 * (abs(mx) + abs(my))
                if min(nx * nx + ny * ny, bx * bx + by * by) <= reach * reach:
                    move = math.hypot(mx, my)
                    along = min(max(-(bx * mx + by * my) / max(move * move, 1e-12), 0.0), 1.0)
                    hit = math.hypot(bx + along * mx, by + along * my) < radius
            hit_still |= hit and still[k]
            hit_moving |= hit and not still[k]
        broken = False
        if math.isinf(zone_t):
            for z in range(kind.shape[0]):
                broken |= not leaving[z] and segment_breaks(
                    last_x, last_y, px, py, kind[z], shape[z], clearance[z]
                )
        last_x, last_y = px, py
        if hit_still and math.isinf(still_t):
            still_t, still_x, still_y = t, px, py
        if hit_moving and math.isinf(moving_t):
            moving_t, moving_x, moving_y = t, px, py
        if broken and math.isinf(zone_t):
            zone_t, zone_x, zone_y = t, px, py
        if not (math.isinf(still_t) or math.isinf(moving_t) or (kind.shape[0] > 0 and math.isinf(zone_t))):
            break  # every first collision found: the later checks change nothing
        if judged and (
            (hit_still and not still_accepts(still_t, complex(still_x, still_y), start, goal, threshold_time))
            or (broken and zone_t <= switch)
            or (
                (broken or hit_moving)
                and not math.isinf(zone_t)
                and not moving_accepts(moving_t, speed, brake, brake_offset)
            )
        ):
            break
    return still_t, still_x, still_y, moving_t, moving_x, moving_y, zone_t, zone_x, zone_y


@numba.njit(cache=True)
def walk_paths(
    positions, times, start, total, row, q, u, still, radius, t_max, kind, shape, clearance, leaving
):
    """``walk`` of paths (P,): positions (P, C), starts and totals (P,), each path's row (P,) of the
    obstacles (N, K) and zones (N, S). Returns (9, P)."""
    out = np.empty((9, total.shape[0]))
    for p in range(total.shape[0]):
        i = row[p]
        zones = (kind[i], shape[i], clearance[i], leaving[i])
        hits = walk(positions[p], times, start[p], total[p], q[i], u[i], still[i], radius, t_max, zones)
        for j in range(9):
            out[j, p] = hits[j]
    return out


@numba.njit(cache=True)
def _switch_path(fx, fy, w, end, speed, accel, checks, buffers):
    """The path that follows the sub-path (its x and y fields ``fx``, ``fy`` (9,)) until the switch at
    ``w`` s, then the bang-bang trajectory from the state there to rest on ``end``: its positions at the
    check times, written into ``buffers`` (positions, times, the second part's fields (2, 9)), which grow
    as needed. Returns positions, times (the buffers), the number of checks and the path's duration."""
    offset, step = checks[0], checks[1]
    positions, times, then = buffers
    at_x, going_x = state_1d(w, fx)
    at_y, going_y = state_1d(w, fy)
    _, tx, ty = profile_2d(at_x, at_y, end.real, end.imag, going_x, going_y, speed, accel)
    for f in range(9):
        then[0, f], then[1, f] = tx[f], ty[f]
    total = w + max(tx[5] + tx[6] + tx[7], ty[5] + ty[6] + ty[7])
    n = 0
    while offset + n * step < total:
        if n == positions.shape[0]:
            positions = np.concatenate((positions, np.empty(n, np.complex128)))
            times = np.concatenate((times, np.empty(n)))
        t = offset + n * step
        if t < w:
            x, y = state_1d(t, fx)[0], state_1d(t, fy)[0]
        else:
            x, y = state_1d(t - w, then[0])[0], state_1d(t - w, then[1])[0]
        positions[n], times[n] = complex(x, y), t
        n += 1
    return positions, times, n, total


@numba.njit(cache=True)
def _search_row(start, now, end, speed, motion, subs, switch, miss, obstacles, checks, zones, buffers):
    """``search`` for one robot at ``start``, at speed ``now``, going to ``end`` at up to ``speed``;
    ``motion``: its acceleration, braking and brake_time_offset; ``subs``: its sub-paths' fields (S, 2, 9),
    durations and validity (S,); ``miss`` the direct path's; ``obstacles``: q, u, still (K,) and the
    collision radius; ``zones`` as ``walk``'s. Returns the winning flat index, whether one was found and the
    ``buffers`` (positions, times), which ``_switch_path`` may have grown."""
    accel, brake, brake_offset = motion
    first, first_total, valid = subs
    q, u, still, radius = obstacles
    t_max, threshold_time = checks[2], checks[3]
    checked, switches = zones[0].shape[0] > 0, switch.shape[0]
    miss_at, near, near_at = 0, math.inf, -1
    for s in range(valid.shape[0]):
        if not valid[s]:
            continue
        for j in range(switches):
            w = switch[j]
            if not w < first_total[s]:
                break  # the switches come in order: no later one is on the sub-path
            positions, times, n, total = _switch_path(
                first[s, 0], first[s, 1], w, end, speed, accel, checks, buffers
            )
            buffers = (positions, times, buffers[2])
            judge = (True, w, end, threshold_time, now, brake, brake_offset)
            hits = walk(positions[:n], times[:n], start, total, q, u, still, radius, t_max, zones, judge)
            free = still_accepts(hits[0], complex(hits[1], hits[2]), start, end, threshold_time)
            still_ok = free and math.isinf(hits[6])
            moving_ok = moving_accepts(hits[3], now, brake, brake_offset)
            flat = 1 + s * switches + j
            if still_ok and moving_ok:
                return flat, True, buffers
            if still_ok:
                gap = abs(complex(hits[4], hits[5]) - end)
                if gap * gap < miss:
                    miss, miss_at = gap * gap, flat
            if checked and free and moving_ok and hits[6] > w:
                gap = abs(complex(hits[7], hits[8]) - end)
                if gap < near:
                    near, near_at = gap, flat
    if math.isfinite(miss):
        return miss_at, True, buffers
    if checked and near_at >= 0:
        return near_at, True, buffers
    return 0, False, buffers


@numba.njit(cache=True)
def search(
    pos,
    vel,
    goal,
    speed,
    accel,
    brake,
    first,
    first_total,
    valid,
    switch,
    direct_miss,
    q,
    u,
    still,
    radius,
    checks,
    brake_offset,
    zones,
):
    """Steps 2 and 3 (``TrajectoryPlanner.detour``) for R robots, one at a time: the flat index (R,) of
    the winning path, 0 the direct one, 1 + s J + j the sub-destination s switching at ``switch[j]`` (J,),
    and whether one was found (R,). The paths are tried in order and the first acceptable wins, so the
    rest are never walked; failing all, the closest miss (ties to the first, the direct path's
    ``direct_miss`` first of all), then under the rules the closest step into a zone.

    ``first``: the sub-paths' fields (R, S, 2, 9) (``Profile2D.packed``), their durations and validity
    (R, S); ``checks``: initial_time_offset, collision_check_step, t_max, threshold_max_collision_time;
    ``zones`` as ``walk``'s with a leading R."""
    kind, shape, clearance, leaving = zones
    rows = valid.shape[0]
    best, found = np.zeros(rows, np.int64), np.zeros(rows, np.bool_)
    buffers = (np.empty(64, np.complex128), np.empty(64), np.empty((2, 9)))
    motion = (accel, brake, brake_offset)
    for r in range(rows):
        subs = (first[r], first_total[r], valid[r])
        obstacles = (q[r], u[r], still[r], radius)
        row_zones = (kind[r], shape[r], clearance[r], leaving[r])
        best[r], found[r], buffers = _search_row(
            pos[r],
            abs(vel[r]),
            goal[r],
            speed[r],
            motion,
            subs,
            switch,
            direct_miss[r],
            obstacles,
            checks,
            row_zones,
            buffers,
        )
    return best, found
