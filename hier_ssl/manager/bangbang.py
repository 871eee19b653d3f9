"""Time-optimal bang-bang trajectories under speed and acceleration limits, batched.

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

Each piece is written once, as a compiled function of one profile (``profile_1d``, ``profile_2d``,
``state_1d``): the batched functions below loop them over any broadcasting
leading shape, and the ``trajectory`` planner's compiled path search calls them on one path at a time.
Times in s, lengths in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

SYNC_STEPS = math.ceil(math.log2((math.pi / 8) / 1e-7)) + 1  # bisection rounds: step pi/8 down to 1e-7
FIELDS = 9  # a 1-D profile's numbers, in Profile1D's order


@numba.njit(cache=True)
def profile_1d(s0: float, s1: float, v0: float, v_max: float, a_max: float) -> tuple:
    """One time-optimal profile from (s0, v0) to rest at s1 (module docstring): Profile1D's fields."""
    d = s1 - s0
    sign = 1.0 if d - v0 * abs(v0) / (2.0 * a_max) >= 0.0 else -1.0
    d, v = sign * d, sign * v0
    vp = min(v_max, math.sqrt(max(a_max * d + 0.5 * v * v, 0.0)))
    acc1 = a_max if vp >= v else -a_max
    t1 = abs(vp - v) / a_max
    t3 = vp / a_max
    d1, d3 = 0.5 * (v + vp) * t1, 0.5 * vp * t3
    t2 = max(d - d1 - d3, 0.0) / max(vp, 1e-12) if vp > 0.0 else 0.0
    return sign, s0, v, acc1, vp, t1, t2, t3, a_max


@numba.njit(cache=True)
def state_1d(t: float, f: np.ndarray) -> tuple[float, float]:
    """Position and velocity at time ``t`` of the profile whose fields are ``f`` (9,) (Profile1D's order);
    at rest on its end after its total time."""
    sign, s0, v0, acc1, vp, t1, t2, t3, a = f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8]
    t = max(t, 0.0)
    first = min(t, t1)
    cruise = min(max(t - t1, 0.0), t2)
    brake = min(max(t - (t1 + t2), 0.0), t3)
    pos = v0 * first + 0.5 * acc1 * (first * first) + vp * cruise + vp * brake - 0.5 * a * (brake * brake)
    if t < t1:
        vel = v0 + acc1 * first
    elif t < t1 + t2:
        vel = vp
    else:
        vel = max(vp - a * brake, 0.0)
    return s0 + sign * pos, sign * vel


@numba.njit(cache=True)
def _states(t: np.ndarray, fields: np.ndarray) -> np.ndarray:
    """(2, P) ``state_1d`` at times (P,) of profiles (P, 9)."""
    out = np.empty((2, t.shape[0]))
    for i in range(t.shape[0]):
        out[0, i], out[1, i] = state_1d(t[i], fields[i])
    return out


@numba.njit(cache=True)
def profile_2d(
    p0x: float, p0y: float, p1x: float, p1y: float, v0x: float, v0y: float, v_max: float, a_max: float
) -> tuple:
    """One 2-D profile (module docstring): the split angle, then the x and the y profiles' fields."""
    alpha, step = math.pi / 4, math.pi / 8
    for _ in range(SYNC_STEPS):
        c, s = math.cos(alpha), math.sin(alpha)
        x = profile_1d(p0x, p1x, v0x, v_max * c, a_max * c)
        y = profile_1d(p0y, p1y, v0y, v_max * s, a_max * s)
        # x slower: give it a larger share (smaller alpha), and the other way round.
        alpha = alpha + (-step if x[5] + x[6] + x[7] > y[5] + y[6] + y[7] else step)
        step *= 0.5
    c, s = math.cos(alpha), math.sin(alpha)
    return (
        alpha,
        profile_1d(p0x, p1x, v0x, v_max * c, a_max * c),
        profile_1d(p0y, p1y, v0y, v_max * s, a_max * s),
    )


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

    @property
    def fields(self) -> tuple[np.ndarray, ...]:
        return (self.sign, self.s0, self.v0, self.acc1, self.vp, self.t1, self.t2, self.t3, self.a)

    def at(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at time ``t`` (broadcast against the profiles); at rest on the end after
        the total time."""
        fields = np.stack(self.fields, axis=-1)
        shape = np.broadcast_shapes(np.shape(t), fields.shape[:-1])
        out = _states(
            np.ascontiguousarray(np.broadcast_to(np.asarray(t, np.float64), shape)).reshape(-1),
            np.ascontiguousarray(np.broadcast_to(fields, shape + (FIELDS,))).reshape(-1, FIELDS),
        )
        return out[0].reshape(shape), out[1].reshape(shape)


@numba.njit(cache=True)
def _profiles_1d(s0, s1, v0, v_max, a_max) -> np.ndarray:
    """(9, P) ``profile_1d`` of flat arrays (P,)."""
    out = np.empty((FIELDS, s0.shape[0]))
    for i in range(s0.shape[0]):
        out[:, i] = profile_1d(s0[i], s1[i], v0[i], v_max[i], a_max[i])
    return out


def bang_bang_1d(
    s0: np.ndarray | float,
    s1: np.ndarray | float,
    v0: np.ndarray | float,
    v_max: np.ndarray | float,
    a_max: np.ndarray | float,
) -> Profile1D:
    """The time-optimal profiles from (s0, v0) to rest at s1 (module docstring); v_max, a_max > 0."""
    args = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (s0, s1, v0, v_max, a_max)))
    flat = _profiles_1d(*(np.ascontiguousarray(x).reshape(-1) for x in args))
    return Profile1D(*flat.reshape((FIELDS,) + args[0].shape))


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

    def packed(self) -> np.ndarray:
        """(..., 2, 9) the x and y profiles' fields, for the compiled path checks."""
        return np.stack([np.stack(self.x.fields, -1), np.stack(self.y.fields, -1)], -2)


@numba.njit(cache=True)
def _profiles_2d(p0, p1, v0, v_max, a_max) -> np.ndarray:
    """(P, 1 + 2 * 9) ``profile_2d`` of flat arrays (P,): alpha, then the x and the y fields."""
    out = np.empty((p0.shape[0], 1 + 2 * FIELDS))
    for i in range(p0.shape[0]):
        alpha, x, y = profile_2d(
            p0[i].real, p0[i].imag, p1[i].real, p1[i].imag, v0[i].real, v0[i].imag, v_max[i], a_max[i]
        )
        out[i, 0] = alpha
        out[i, 1 : 1 + FIELDS] = x
        out[i, 1 + FIELDS :] = y
    return out


def bang_bang_2d(
    p0: np.ndarray | complex,
    p1: np.ndarray | complex,
    v0: np.ndarray | complex,
    v_max: np.ndarray | float,
    a_max: np.ndarray | float,
) -> Profile2D:
    """The 2-D profiles from position ``p0`` at velocity ``v0`` to rest at ``p1`` (complex x + iy, any
    broadcastable shapes), each axis within its share of the limits so that the vector never exceeds
    v_max nor a_max, and both axes arriving together (to the bisection's precision). The limits may be
    arrays that broadcast against the positions (a speed limit per robot)."""
    if not (np.all(np.asarray(v_max) > 0) and np.all(np.asarray(a_max) > 0)):
        raise ValueError(f"v_max and a_max must be > 0, got {v_max!r}, {a_max!r}")
    p0, p1, v0 = (np.asarray(x, dtype=np.complex128) for x in (p0, p1, v0))
    v_max, a_max = (np.asarray(x, dtype=np.float64) for x in (v_max, a_max))
    shape = np.broadcast_shapes(p0.shape, p1.shape, v0.shape, v_max.shape, a_max.shape)
    flat = _profiles_2d(
        *(np.ascontiguousarray(np.broadcast_to(x, shape)).reshape(-1) for x in (p0, p1, v0, v_max, a_max))
    )
    flat = flat.T.reshape((1 + 2 * FIELDS,) + shape)
    return Profile2D(Profile1D(*flat[1 : 1 + FIELDS]), Profile1D(*flat[1 + FIELDS :]), flat[0])


__all__ = [
    "SYNC_STEPS",
    "Profile1D",
    "Profile2D",
    "bang_bang_1d",
    "bang_bang_2d",
    "profile_1d",
    "profile_2d",
    "state_1d",
]
