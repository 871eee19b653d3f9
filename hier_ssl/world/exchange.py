"""What a World step computes per robot on its way into pymunk and back out, one compiled loop each.

At one field a step's arithmetic is a few dozen flops; written as numpy operations on (N, R) arrays it
was some 25 calls, each costing numpy's per-call overhead. Each loop here is one call, the same at every
N (numba compiles it once per argument layout and caches it on disk next to this module).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hier_ssl.world.frames import wrap


@numba.njit(cache=True)
def velocity_rows(
    command: np.ndarray,
    heading: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    ang_vel: np.ndarray,
    limits: np.ndarray,
    at: np.ndarray,
    out: np.ndarray,
) -> None:
    """What a step writes into pymunk: the body rows ``out`` (B, 3), (vx, vy, w) each, at row
    ``at[f, i, 1]`` robot i of field f's control body's and at ``at[f, i, 0]`` the robot's (``at``
    (N, R, 2) int).

    A control body carries the command (N, R, 3) (robot frame) turned into the field frame by ``heading``
    (N, R) (exp(i angle)), capped at the speed limits, direction kept. A robot keeps its velocity (N, R, 2)
    and ``ang_vel`` (N, R), less the part that would carry its centre (``pos`` (N, R, 2)) past its reach
    within this period: an inelastic wall impact resolved before it happens (pymunk detects contacts only
    after moving bodies, so without this a robot at 2.5 m/s would sink v * dt into a wall before the
    contact pushes back). ``limits``: max speed, max angular speed, the period dt, the x and y reach.
    """
    max_speed, max_spin, dt = limits[0], limits[1], limits[2]
    for f in range(command.shape[0]):
        for i in range(command.shape[1]):
            c, s = heading[f, i].real, heading[f, i].imag
            x, y = command[f, i, 0], command[f, i, 1]
            vx, vy = x * c - y * s, x * s + y * c
            speed = math.hypot(vx, vy)
            if speed > max_speed:
                vx, vy = vx * (max_speed / speed), vy * (max_speed / speed)
            robot, control = out[at[f, i, 0]], out[at[f, i, 1]]
            control[0], control[1] = vx, vy
            control[2] = max(min(command[f, i, 2], max_spin), -max_spin)
            for axis in range(2):
                p, reach = pos[f, i, axis], limits[3 + axis]
                room_hi, room_lo = max(reach - p, 0.0) / dt, min(-reach - p, 0.0) / dt
                robot[axis] = max(min(vel[f, i, axis], room_hi), room_lo)
            robot[2] = ang_vel[f, i]


@numba.njit(cache=True)
def unpack_rows(
    rows: np.ndarray,
    offsets: np.ndarray,
    fields: np.ndarray,
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    ang_vel: np.ndarray,
    heading: np.ndarray,
) -> None:
    """The read-back ``rows`` (N, R, 6) of the robots of ``fields`` (F,) ints (x, y, angle, vx, vy, w, at
    their fields' ``offsets`` (N, 2)) written into a state's arrays: field-frame ``pos`` (N, R, 2),
    ``angle`` (N, R) wrapped to [-pi, pi), ``vel`` (N, R, 2), ``ang_vel`` (N, R) and ``heading``
    exp(i angle) (N, R) complex; other fields' entries are left as they are."""
    for f in fields:
        for i in range(rows.shape[1]):
            row = rows[f, i]
            pos[f, i, 0], pos[f, i, 1] = row[0] - offsets[f, 0], row[1] - offsets[f, 1]
            a = wrap(row[2])
            angle[f, i], heading[f, i] = a, complex(math.cos(a), math.sin(a))
            vel[f, i, 0], vel[f, i, 1], ang_vel[f, i] = row[3], row[4], row[5]


@numba.njit(cache=True)
def _first_hit(
    px: float, py: float, vx: float, vy: float, time: float, limits: np.ndarray, boxes: np.ndarray
) -> tuple[float, int]:
    """When (s, at most ``time``) a ball at (px, py) moving at (vx, vy) first meets a wall or a goal wall,
    and along which axis (0 x, 1 y; -1 for none). The walls hold its centre within the reach ``limits[2:4]``;
    ``boxes`` (G, 4) are the goal walls grown by the ball's radius (their corners square, not round)."""
    first, axis = time, -1
    for a in range(2):
        p, v, reach = (px, vx, limits[2]) if a == 0 else (py, vy, limits[3])
        if v != 0.0:
            # Moving towards the wall it faces; at or past it already, it turns back at once.
            t = max(((reach if v > 0 else -reach) - p) / v, 0.0)
            if t < first:
                first, axis = t, a
    for g in range(boxes.shape[0]):
        enter, leave, enter_axis = -np.inf, np.inf, -1
        for a in range(2):
            p, v = (px, vx) if a == 0 else (py, vy)
            lo, hi = boxes[g, 2 * a], boxes[g, 2 * a + 1]
            if v == 0.0:
                if not lo < p < hi:
                    enter = np.inf
                continue
            t0, t1 = (lo - p) / v, (hi - p) / v
            t0, t1 = min(t0, t1), max(t0, t1)
            if t0 > enter:
                enter, enter_axis = t0, a
            leave = min(leave, t1)
        # Entering from outside (a ball already inside was pushed there and is left to pymunk).
        if 0.0 <= enter < leave and enter < first:
            first, axis = enter, enter_axis
    return first, axis


@numba.njit(cache=True)
def ball_rows(
    pos: np.ndarray,
    vel: np.ndarray,
    limits: np.ndarray,
    boxes: np.ndarray,
    at: np.ndarray,
    out: np.ndarray,
    delta: np.ndarray,
) -> None:
    """What a step writes into pymunk for the balls: at row ``at[f, b]`` of ``out`` (rows, 3) ball b of
    field f's (vx, vy, 0), and into ``delta`` (N, B, 3) how ``unpack_balls`` turns the velocity pymunk
    gives back into the period's last: add (dx, dy), then take off a speed h along it, never turning it.

    A ball at ``pos`` (N, B, 2) rolling at ``vel`` (N, B, 2) slows down by ``limits[0]`` m/s^2 over the
    period ``limits[1]`` s: pymunk carries it at the period's mean velocity, so that it travels exactly
    what the constant deceleration gives (v^2 / (2 a) to a stop), and h is the second half-period's loss
    (a robot that stops it leaves it at rest). Its straight path is also swept against the walls and
    ``boxes`` (G, 4), the goal walls grown by its radius: each bounce turns back the normal velocity times
    the restitution ``limits[4]``, and pymunk carries the ball to where the bounces leave it, (dx, dy)
    being what the bounced last velocity differs from that carrying one (h 0). Chipmunk would only see a
    wall once the ball overlaps it, and at 6.5 m/s a ball crosses a goal wall within a substep.
    """
    decel, dt, restitution = limits[0], limits[1], limits[4]
    for f in range(pos.shape[0]):
        for b in range(pos.shape[1]):
            vx, vy = vel[f, b, 0], vel[f, b, 1]
            speed = math.hypot(vx, vy)
            if speed >= decel * dt:
                mean, last = (speed - 0.5 * decel * dt) / speed, (speed - decel * dt) / speed
            else:  # it stops within the period, after speed^2 / (2 decel)
                mean, last = speed / (2.0 * decel * dt), 0.0
            mx, my, ex, ey = vx * mean, vy * mean, vx * last, vy * last
            px, py, left, bounced = pos[f, b, 0], pos[f, b, 1], dt, False
            for _ in range(4):  # a ball in a corner meets two walls within one period
                t, axis = _first_hit(px, py, mx, my, left, limits, boxes)
                px, py, left = px + mx * t, py + my * t, left - t
                if axis == 0:
                    mx, ex = -restitution * mx, -restitution * ex
                elif axis == 1:
                    my, ey = -restitution * my, -restitution * ey
                else:
                    break
                bounced = True
            row = out[at[f, b]]
            row[0], row[1], row[2] = (px - pos[f, b, 0]) / dt, (py - pos[f, b, 1]) / dt, 0.0
            if bounced:
                delta[f, b, 0], delta[f, b, 1], delta[f, b, 2] = ex - row[0], ey - row[1], 0.0
            else:
                delta[f, b, 0], delta[f, b, 1], delta[f, b, 2] = 0.0, 0.0, 0.5 * decel * dt


@numba.njit(cache=True)
def unpack_balls(
    rows: np.ndarray,
    offsets: np.ndarray,
    delta: np.ndarray,
    fields: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
) -> None:
    """The read-back ``rows`` (N, B, 6) of the balls of ``fields`` (F,) ints written into a ball state's
    field-frame ``pos`` (N, B, 2) and ``vel`` (N, B, 2): pymunk's velocity turned into the period's last
    by ``delta`` (N, B, 3), what ``ball_rows`` left out of it; other fields' entries are left as they
    are."""
    for f in fields:
        for b in range(rows.shape[1]):
            row, d = rows[f, b], delta[f, b]
            pos[f, b, 0], pos[f, b, 1] = row[0] - offsets[f, 0], row[1] - offsets[f, 1]
            vx, vy = row[3] + d[0], row[4] + d[1]
            speed = math.hypot(vx, vy)
            keep = max(speed - d[2], 0.0) / speed if speed > 0.0 else 0.0
            vel[f, b, 0], vel[f, b, 1] = vx * keep, vy * keep


__all__ = ["ball_rows", "unpack_balls", "unpack_rows", "velocity_rows"]
