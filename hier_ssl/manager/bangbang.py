"""Time-optimal bang-bang trajectories under speed and acceleration limits, batched in numpy.

1-D: from position s0 at velocity v0 to rest at s1, accelerating at +-a_max with |v| <= v_max. In the frame
where the final approach runs in +s (the point where braking at once would stop lies at or before s1), the
profile is: accelerate (or, above v_max, decelerate) at a_max towards the peak speed v_p, cruise at v_p,
brake at a_max to rest on s1; v_p = min(v_max, sqrt(a_max d + v0^2 / 2)) with d = s1 - s0 in that frame.
A start velocity pointing away is braked through zero inside the first phase; one that would overshoot
flips the frame, so the robot passes s1, stops and comes back.

2-D: two 1-D profiles whose limits are split by an angle alpha (x gets v_max cos alpha, a_max cos alpha; y
the sines), alpha found by bisection so that both axes arrive together, as TIGERs Mannheim's
``BangBangTrajectory2D`` (Sumatra, ``modules/common``) and UBC Thunderbots'
``src/software/ai/navigator/trajectory/bang_bang_trajectory_2d`` do. The bisection starts at pi/4 with a
step of pi/8 halved each round down to 1e-7, as theirs; every element runs all rounds (no early stop),
which only refines the split further.

Every function broadcasts over any leading shape; times in s, lengths in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SYNC_STEPS = math.ceil(math.log2((math.pi / 8) / 1e-7)) + 1  # bisection rounds: step pi/8 down to 1e-7


@dataclass(frozen=True)
class Profile1D:
    """A batch of 1-D bang-bang profiles, all arrays of one shape (the flipped frame: see module doc).

    sign: +1 or -1, the frame's direction; s0: start; v0: start velocity in the frame; acc1: first-phase
    acceleration in the frame; vp: peak (cruise) speed; t1, t2, t3: phase durations; a: the braking
    acceleration (a_max)."""

    sign: np.ndarray
    s0: np.ndarray
    v0: np.ndarray
    acc1: np.ndarray
    vp: np.ndarray
    t1: np.ndarray
    t2: np.ndarray
    t3: np.ndarray
    a: np.ndarray

    @property
    def total_time(self) -> np.ndarray:
        return self.t1 + self.t2 + self.t3

    def at(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at time ``t`` (broadcast against the profiles); at rest on the end after
        the total time."""
        t = np.maximum(t, 0.0)
        t1, t12 = self.t1, self.t1 + self.t2
        first = np.minimum(t, t1)
        cruise = np.clip(t - t1, 0.0, self.t2)
        brake = np.clip(t - t12, 0.0, self.t3)
        v1 = self.v0 + self.acc1 * first
        pos = (
            self.v0 * first
            + 0.5 * self.acc1 * first**2
            + self.vp * cruise
            + self.vp * brake
            - 0.5 * self.a * brake**2
        )
        vel = np.where(t < t1, v1, np.where(t < t12, self.vp, np.maximum(self.vp - self.a * brake, 0.0)))
        return self.s0 + self.sign * pos, self.sign * vel


def bang_bang_1d(
    s0: np.ndarray | float,
    s1: np.ndarray | float,
    v0: np.ndarray | float,
    v_max: np.ndarray | float,
    a_max: np.ndarray | float,
) -> Profile1D:
    """The time-optimal profiles from (s0, v0) to rest at s1 (module docstring); v_max, a_max > 0."""
    s0, s1, v0, v_max, a_max = np.broadcast_arrays(
        *(np.asarray(x, dtype=np.float64) for x in (s0, s1, v0, v_max, a_max))
    )
    d = s1 - s0
    sign = np.where(d - v0 * np.abs(v0) / (2.0 * a_max) >= 0.0, 1.0, -1.0)
    d, v = sign * d, sign * v0
    vp = np.minimum(v_max, np.sqrt(np.maximum(a_max * d + 0.5 * v * v, 0.0)))
    acc1 = np.where(vp >= v, a_max, -a_max)
    t1 = np.abs(vp - v) / a_max
    t3 = vp / a_max
    d1, d3 = 0.5 * (v + vp) * t1, 0.5 * vp * t3
    t2 = np.where(vp > 0.0, np.maximum(d - d1 - d3, 0.0) / np.maximum(vp, 1e-12), 0.0)
    return Profile1D(sign, s0, v, acc1, vp, t1, t2, t3, a_max)


@dataclass(frozen=True)
class Profile2D:
    """Two synchronised 1-D profiles and the split angle alpha (rad; x takes cos alpha of the limits)."""

    x: Profile1D
    y: Profile1D
    alpha: np.ndarray

    @property
    def total_time(self) -> np.ndarray:
        return np.maximum(self.x.total_time, self.y.total_time)

    def at(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at time ``t`` as complex numbers x + iy."""
        px, vx = self.x.at(t)
        py, vy = self.y.at(t)
        return px + 1j * py, vx + 1j * vy


def bang_bang_2d(
    p0: np.ndarray | complex,
    p1: np.ndarray | complex,
    v0: np.ndarray | complex,
    v_max: float,
    a_max: float,
) -> Profile2D:
    """The 2-D profiles from position ``p0`` at velocity ``v0`` to rest at ``p1`` (complex x + iy, any
    broadcastable shapes), each axis within its share of the limits so that the vector never exceeds
    v_max nor a_max, and both axes arriving together (to the bisection's precision). The limits may be
    arrays that broadcast against the positions (a speed limit per robot)."""
    if not (np.all(np.asarray(v_max) > 0) and np.all(np.asarray(a_max) > 0)):
        raise ValueError(f"v_max and a_max must be > 0, got {v_max!r}, {a_max!r}")
    p0, p1, v0 = np.broadcast_arrays(*(np.asarray(x, dtype=np.complex128) for x in (p0, p1, v0)))
    alpha = np.full(p0.shape, math.pi / 4)
    step = math.pi / 8
    for _ in range(SYNC_STEPS):
        c, s = np.cos(alpha), np.sin(alpha)
        tx = bang_bang_1d(p0.real, p1.real, v0.real, v_max * c, a_max * c).total_time
        ty = bang_bang_1d(p0.imag, p1.imag, v0.imag, v_max * s, a_max * s).total_time
        # x slower: give it a larger share (smaller alpha), and the other way round.
        alpha = alpha + np.where(tx > ty, -step, step)
        step *= 0.5
    c, s = np.cos(alpha), np.sin(alpha)
    x = bang_bang_1d(p0.real, p1.real, v0.real, v_max * c, a_max * c)
    y = bang_bang_1d(p0.imag, p1.imag, v0.imag, v_max * s, a_max * s)
    return Profile2D(x, y, alpha)


__all__ = ["SYNC_STEPS", "Profile1D", "Profile2D", "bang_bang_1d", "bang_bang_2d"]
