"""The sampling planner's compiled loops (``hier_ssl.manager.planners.SamplingPlanner``): the rollouts of its
candidates against the predicted obstacles (``rollouts``, ``SamplingPlanner.rollout``) and the check of
their straight legs against the rules' zones (``zone_detours``, ``SamplingPlanner.zone_detour``).

A row's candidates step together, one loop over them a step with no branch, so that it runs as vector
instructions; the helpers below are those loops, each compiled on its own and called from the row's."""

from __future__ import annotations

import math

import numba
import numpy as np

from hier_ssl.game.segments import axis_depth, segment_away
from hier_ssl.game.zones import CAPSULE, zone_distance

PASS = 0.1  # m a robot's centre needs beyond a capsule's clearance to pass round its end


@numba.njit(cache=True)
def _least(a: float, b: float) -> float:
    """min(a, b) as one select, which a loop of them can run as vector instructions (no NaN here)."""
    return a if a < b else b


@numba.njit(cache=True)
def _most(a: float, b: float) -> float:
    """max(a, b) as one select."""
    return a if a > b else b


@numba.njit(cache=True)
def _first_aims(cx, cy, gx, gy, px, py, via, hold, switch_radius) -> None:
    """``via`` (M,): heading for the sub-goal rather than the target: every candidate but the target
    itself, until the sub-goal is no longer held and the robot is within switch_radius of it."""
    for j in range(cx.shape[0]):
        away = math.sqrt((cx[j] - px[j]) ** 2 + (cy[j] - py[j]) ** 2) > switch_radius
        via[j] = (cx[j] != gx or cy[j] != gy) and (hold > 0.0 or away)


@numba.njit(cache=True)
def _drive(cx, cy, gx, gy, state, via, gap, top, held, dt, motion, switch_radius) -> None:
    """One step of every candidate's robot, ``state`` (x, y, vx, vy) each (M,): bang-bang towards its
    current aim (the sub-goal while ``via``, else the target ``gx``, ``gy``), then the aim updated. Resets
    ``gap`` (M,) to +inf for ``_measure``."""
    px, py, vx, vy = state
    step, two_brake = motion
    for j in range(cx.shape[0]):
        # Bang-bang towards the current goal: braking curve, speed cap, land on it in the last step.
        dx = (cx[j] if via[j] else gx) - px[j]
        dy = (cy[j] if via[j] else gy) - py[j]
        dist = math.sqrt(dx * dx + dy * dy)
        want = _least(_least(math.sqrt(two_brake * dist), top), dist / dt) / _most(dist, 1e-9)
        ex, ey = dx * want - vx[j], dy * want - vy[j]
        scale = _least(1.0, step / _most(math.sqrt(ex * ex + ey * ey), 1e-12))
        vx[j], vy[j] = vx[j] + ex * scale, vy[j] + ey * scale
        px[j], py[j] = px[j] + vx[j] * dt, py[j] + vy[j] * dt
        # The worker drives to the sub-goal for as long as it is held.
        sx, sy = cx[j] - px[j], cy[j] - py[j]
        via[j] = via[j] and (held or math.sqrt(sx * sx + sy * sy) > switch_radius)
        gap[j] = math.inf


@numba.njit(cache=True)
def _measure(px, py, ox, oy, gap, moving, via, figures, goal, now, radii):
    """After a step, ``now`` (t, the margin's growth then, within the prediction window): the candidates'
    distance ``gap`` (M,) to the nearest obstacle at (``ox``, ``oy``) (K,), their ``figures`` (arrival,
    clearance, hard, near; each (M,)) updated, and the ones that arrived at ``goal`` (x, y) stopped
    ``moving``. ``radii``: collision distance + margin, arrive_radius."""
    arrival, clearance, hard, near = figures
    gx, gy = goal
    t, margin, window = now
    distance, arrive_radius = radii
    for o in range(ox.shape[0]):
        for j in range(px.shape[0]):
            sx, sy = px[j] - ox[o], py[j] - oy[o]
            gap[j] = _least(gap[j], math.sqrt(sx * sx + sy * sy))
    for j in range(px.shape[0]):
        g = gap[j] - distance if moving[j] else math.inf
        hard[j] = _least(hard[j], g)
        near[j] = _least(near[j], g if window else math.inf)
        clearance[j] = _least(clearance[j], g - margin)
        sx, sy = gx - px[j], gy - py[j]
        there = moving[j] and not via[j] and math.sqrt(sx * sx + sy * sy) < arrive_radius
        arrival[j] = t if there else arrival[j]
        moving[j] = moving[j] and not there


@numba.njit(cache=True)
def _settled(moving, figures, choosable, t) -> tuple[int, bool]:
    """How many candidates are still on their way, and whether a ``choosable`` one arrived at ``t`` clear
    of the growing safety distance."""
    arrival, clearance = figures[0], figures[1]
    left, clear = 0, False
    for j in range(moving.shape[0]):
        left += moving[j]
        clear |= arrival[j] == t and clearance[j] >= 0.0 and choosable[j]
    return left, clear


@numba.njit(cache=True)
def _drop_moving(moving, figures) -> None:
    """Every candidate still on its way dropped: arrival +inf, clearances -inf."""
    arrival, clearance, hard, near = figures
    for j in range(moving.shape[0]):
        if moving[j]:
            moving[j] = False
            arrival[j], clearance[j], hard[j], near[j] = math.inf, -math.inf, -math.inf, -math.inf


@numba.njit(cache=True)
def _roll_row(cx, cy, aim, q, u, choosable, prune, settings, work, figures):
    """One row's rollouts (``rollouts``): candidates ``cx``, ``cy`` (M,), ``aim`` (the target's x, y,
    the speed), obstacles ``q``, ``u`` (K, 2), ``settings`` (``rollouts``' timing, motion, safety).
    ``work``: ``state`` (x, y, vx, vy) (M,) set to the robot's, ``flags`` (via, moving (M,), moving set)
    and ``scratch`` (ox, oy (K,), gap (M,)); writes ``figures`` (M,) each, set to +inf."""
    gx, gy, top = aim
    timing, motion, safety = settings
    dt, horizon, hold, switch_radius, arrive_radius = timing
    distance, growth, predict = safety
    state, flags, scratch = work
    px, py = state[0], state[1]
    via, moving = flags
    ox, oy, gap = scratch
    arrival = figures[0]
    _first_aims(cx, cy, gx, gy, px, py, via, hold, switch_radius)
    for i in range(1, math.ceil(horizon / dt) + 1):
        t = i * dt
        seen = min(t, predict)
        margin, held, window = growth * seen**1.5, t < hold, t <= predict
        for o in range(q.shape[0]):
            ox[o], oy[o] = q[o, 0] + u[o, 0] * seen, q[o, 1] + u[o, 1] * seen
        _drive(cx, cy, gx, gy, state, via, gap, top, held, dt, motion, switch_radius)
        now = (t, margin, window)
        _measure(px, py, ox, oy, gap, moving, via, figures, (gx, gy), now, (distance, arrive_radius))
        left, clear = _settled(moving, figures, choosable, t)
        if not left:
            break
        if prune and clear:  # every candidate still on its way arrives later than this one
            _drop_moving(moving, figures)
            break
    for j in range(cx.shape[0]):
        if moving[j]:
            arrival[j] = horizon + math.sqrt((gx - px[j]) ** 2 + (gy - py[j]) ** 2) / top


@numba.njit(cache=True)
def rollouts(pos, vel, goal, cand, speed, q, u, choosable, prune, timing, motion, safety) -> np.ndarray:
    """``SamplingPlanner.rollout`` compiled: (4, N, M) arrival, clearance, hard, near. Positions and
    velocities (N, 2), candidates (N, M, 2), obstacles (N, K, 2). ``timing``: dt, horizon, hold,
    switch_radius, arrive_radius; ``motion``: the speed change a step, twice the braking; ``safety``:
    collision distance + margin, margin_growth, predict_horizon.

    A row's candidates step together, one loop over them a step with no branch, so that it runs as
    vector instructions; a candidate that arrived keeps moving there, its figures no longer counted. Under
    ``prune``, the row stops the step after a choosable candidate arrived clear of the growing safety
    distance: every candidate still on its way arrives later, and is dropped (arrival +inf, clearances
    -inf). Lengths are sqrt(x^2 + y^2), a few times faster than libm's hypot (which guards against
    overflows metres never reach), both within a unit in the last place of numpy's abs."""
    n, m, k = cand.shape[0], cand.shape[1], q.shape[1]
    out = np.empty((4, n, m))
    state = (np.empty(m), np.empty(m), np.empty(m), np.empty(m))
    flags = (np.empty(m, np.bool_), np.empty(m, np.bool_))
    scratch = (np.empty(k), np.empty(k), np.empty(m))
    settings, work = (timing, motion, safety), (state, flags, scratch)
    for r in range(n):
        cx, cy = cand[r, :, 0].copy(), cand[r, :, 1].copy()
        figures = (out[0, r], out[1, r], out[2, r], out[3, r])
        state[0][:], state[1][:], state[2][:], state[3][:] = pos[r, 0], pos[r, 1], vel[r, 0], vel[r, 1]
        flags[1][:] = True
        for figure in figures:
            figure[:] = math.inf
        aim = (goal[r, 0], goal[r, 1], speed[r])
        _roll_row(cx, cy, aim, q[r], u[r], choosable[r], prune, settings, work, figures)
    return out


@numba.njit(cache=True)
def open_ends(kind: np.ndarray, shape: np.ndarray, clearance: np.ndarray, z: int) -> int:
    """Which ends of the capsule ``z`` of a row's zones (S,) a robot can pass round: 1 the first alone, 2
    the second alone, 0 both or neither (or not a capsule). An end is closed where the point ``PASS`` m
    beyond its round cap, on the capsule's axis, breaks another zone: a ball placement's corridor that
    reaches the wall, or a defense area."""
    x0, y0, x1, y1 = shape[z, 0], shape[z, 1], shape[z, 2], shape[z, 3]
    length = math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2)
    if kind[z] != CAPSULE or length == 0.0:
        return 0
    reach = (clearance[z] + PASS) / length
    ux, uy = (x1 - x0) * reach, (y1 - y0) * reach
    first = second = True
    for k in range(kind.shape[0]):
        if k != z:
            first = first and zone_distance(x0 - ux, y0 - uy, kind[k], shape[k], clearance[k]) >= 0.0
            second = second and zone_distance(x1 + ux, y1 + uy, kind[k], shape[k], clearance[k]) >= 0.0
    return 1 if first and not second else 2 if second and not first else 0


@numba.njit(cache=True)
def zone_detours(robot, goal, cand, kind, shape, clearance) -> tuple[np.ndarray, np.ndarray]:
    """``SamplingPlanner.zone_detour`` compiled: robots and targets (N,), candidates (N, M) complex, the
    rows' zones (N, S)."""
    n, m, s = cand.shape[0], cand.shape[1], kind.shape[1]
    clear, detour = np.empty((n, m), np.bool_), np.empty((n, m))
    for r in range(n):
        x0, y0, gx, gy = robot[r].real, robot[r].imag, goal[r].real, goal[r].imag
        leaving = np.array(
            [zone_distance(x0, y0, kind[r, z], shape[r, z], clearance[r, z]) < 0.0 for z in range(s)]
        )
        ends = np.array([open_ends(kind[r], shape[r], clearance[r], z) for z in range(s)])
        any_first = False
        for j in range(m):
            x, y = cand[r, j].real, cand[r, j].imag
            first, second = True, math.inf
            for z in range(s):
                a = shape[r, z]
                legal = zone_distance(x, y, kind[r, z], a, clearance[r, z]) >= 0.0
                leg = segment_away(x0, y0, x, y, kind[r, z], a[0], a[1], a[2], a[3]) - clearance[r, z]
                first = first and legal and (leg >= 0.0 or leaving[z])
                away = segment_away(x, y, gx, gy, kind[r, z], a[0], a[1], a[2], a[3]) - clearance[r, z]
                if kind[r, z] == CAPSULE:
                    away -= axis_depth(x, y, gx, gy, a[0], a[1], a[2], a[3], ends[z])
                second = min(second, away)
            clear[r, j] = first and second >= 0.0
            detour[r, j] = second if first else -math.inf
            any_first |= first
        if not any_first:  # column 0, the target, is legal
            detour[r, 0] = 0.0
    return clear, detour
