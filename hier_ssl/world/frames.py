"""2-D vectors and headings as the world, the workers and the rewards compute them, batched over any
leading axes.

A 2-D vector (..., 2) float64 is also a complex number x + iy (...): a rotation is one complex multiply or
divide, where the (x, y) form needs cos/sin and a stack. These run every control step for every robot; on
the few rows of one field their cost is numpy's per-call overhead, which doubles when an operand is a
Python scalar, of another dtype, strided or broadcast: constants here are 0-d arrays.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike

_FLOAT, _COMPLEX = np.dtype(np.float64), np.dtype(np.complex128)
_PI, _TWO_PI = np.array(np.pi), np.array(2 * np.pi)
_FEW = 32


def as_float(values: ArrayLike) -> np.ndarray:
    """``values`` as a float64 array: itself if it is one (two checks here cost a third of asarray's)."""
    if type(values) is np.ndarray and values.dtype is _FLOAT:
        return values
    return np.asarray(values, dtype=_FLOAT)


def wrap_angle(angle: ArrayLike) -> np.ndarray:
    """Angles (any shape, rad) mapped to [-pi, pi)."""
    return (as_float(angle) + _PI) % _TWO_PI - _PI


@numba.njit(cache=True)
def wrap(angle: float) -> float:
    """One angle (rad) mapped to [-pi, pi): ``wrap_angle`` for the compiled per-robot loops, the same
    operations on one value (tests/manager/test_rewards.py holds the two equal). Most angles are already
    in range, and there the remainder is its argument itself (exact): the division is skipped."""
    shifted = angle + math.pi
    if 0.0 <= shifted < 2 * math.pi:
        return shifted - math.pi
    return shifted % (2 * math.pi) - math.pi


def all_finite(values: np.ndarray) -> bool:
    """Whether every value of a float64 array is finite. A sum is finite when every value is; only when it
    is not (a NaN, an infinity, or an overflow of absurd finite values) does the exact test run. The sum
    is Python's for a few values (a numpy call costs more than they do), numpy's above: not a BLAS dot
    product, which threads from a few thousand values and then waits on cores other processes hold."""
    flat = values.ravel()
    total = sum(flat.tolist()) if flat.size <= _FEW else flat.sum()
    return math.isfinite(total) or bool(np.isfinite(flat).all())


def as_complex(xy: np.ndarray) -> np.ndarray:
    """2-D vectors (..., 2) as complex numbers x + iy (...): a view when ``xy`` is float64 with a contiguous
    last axis (no copy, writes go through), a new array otherwise.

    Rotations become one complex multiply, where the (x, y) form needs cos/sin and a stack.
    """
    if type(xy) is np.ndarray and xy.dtype is _FLOAT and xy.shape[-1:] == (2,):
        try:
            return xy.view(_COMPLEX)[..., 0]
        except ValueError:  # last axis not contiguous
            pass
    xy = np.ascontiguousarray(xy, dtype=_FLOAT)
    if xy.shape[-1] != 2:
        raise ValueError(f"expected 2-D vectors (..., 2), got shape {xy.shape}")
    return xy.view(_COMPLEX)[..., 0]


def heading(angle: np.ndarray) -> np.ndarray:
    """exp(i angle) (...) complex: the unit vector of each heading, and the rotation from the robot's frame
    to the field frame."""
    # An exponent with its real part 0 from the start saves a multiply by 1j (and its dtype conversion).
    exponent = np.zeros(np.shape(angle), dtype=_COMPLEX)
    exponent.imag = angle
    return np.exp(exponent)


def to_robot_frame(vec: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate field-frame vectors (..., 2) into the frames of robots at ``angle`` (...)."""
    return (as_complex(vec) / heading(angle))[..., None].view(_FLOAT)


def to_field_frame(vec: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate robot-frame vectors (..., 2) into the field frame."""
    return (as_complex(vec) * heading(angle))[..., None].view(_FLOAT)
