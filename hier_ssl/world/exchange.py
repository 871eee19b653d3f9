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


__all__ = ["unpack_rows", "velocity_rows"]
