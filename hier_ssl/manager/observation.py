"""The manager's observation: target, robot and obstacles as one normalised vector per field.

Layout (docs/paper.md "Observations"), 13 values then 5 per obstacle::

    0-1   target x, y            / max_pos
    2-3   sin, cos of target angle
    4-5   target vx, vy          / max_v
    6-7   robot x, y             / max_pos
    8-9   sin, cos of robot angle
    10-11 robot vx, vy           / max_v   (field frame)
    12    robot angular velocity / max_w   (rad/s)
    13+5k obstacle k: x, y / max_pos, vx, vy / max_v, w / max_w

Every value is clipped to [-clip, clip]. The paper's text lists cos before sin; its code and
docs/paper.md put sin first, as here. Read observations through `MANAGER_OBS_SLICES`
and `obstacle_obs_slice`, not by bare column numbers.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np
from numpy.typing import ArrayLike

from hier_ssl.world.frames import as_float
from hier_ssl.world.robot import RobotState

MANAGER_OBS_BASE_DIM = 13
OBSTACLE_OBS_DIM = 5

MANAGER_OBS_SLICES: dict[str, slice] = {
    "target_pos": slice(0, 2),
    "target_sincos": slice(2, 4),
    "target_vel": slice(4, 6),
    "robot_pos": slice(6, 8),
    "robot_sincos": slice(8, 10),
    "robot_vel": slice(10, 12),
    "robot_ang_vel": slice(12, 13),
}

# Offsets inside one obstacle's block; `obstacle_obs_slice` gives the block itself.
OBSTACLE_OBS_SLICES: dict[str, slice] = {
    "pos": slice(0, 2),
    "vel": slice(2, 4),
    "ang_vel": slice(4, 5),
}


def check_array(name: str, value: ArrayLike, shape: tuple[int | None, ...]) -> np.ndarray:
    """Return `value` as a float64 array, or raise ValueError naming it if its shape does not match.

    `shape` lists the expected size of every axis; None accepts any size. For the functions that take
    arrays from outside (planners, metrics); the per-step functions state their shapes and trust them.
    """
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != len(shape) or any(
        want is not None and want != got for want, got in zip(shape, array.shape, strict=True)
    ):
        expected = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {expected}, got {array.shape}")
    return array


def slots_dim(count: int, width: int, name: str) -> int:
    """Length of an observation of the 13 base values and ``count`` slots of ``width`` values each."""
    if count < 0:
        raise ValueError(f"{name} must be >= 0, got {count}")
    return MANAGER_OBS_BASE_DIM + width * count


def slot_slice(k: int, width: int, name: str) -> slice:
    """Columns of slot ``k`` (0-based) after the 13 base values, slots being ``width`` values wide."""
    if k < 0:
        raise ValueError(f"{name} must be >= 0, got {k}")
    start = MANAGER_OBS_BASE_DIM + width * k
    return slice(start, start + width)


def manager_obs_dim(num_obstacles: int) -> int:
    """Length of the manager observation with `num_obstacles` obstacles."""
    return slots_dim(num_obstacles, OBSTACLE_OBS_DIM, "num_obstacles")


def obstacle_obs_slice(k: int) -> slice:
    """Columns of obstacle `k` (0-based) in the manager observation."""
    return slot_slice(k, OBSTACLE_OBS_DIM, "obstacle index")


def manager_observation(
    target: np.ndarray,
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    ang_vel: np.ndarray,
    obs_pos: np.ndarray,
    obs_vel: np.ndarray,
    obs_ang_vel: np.ndarray,
    *,
    max_pos: float = 3.8,
    max_v: float = 2.5,
    max_w: float = 10.0,
    clip: float = 1.2,
) -> np.ndarray:
    """Build the manager observation of N fields.

    Args:
        target: (N, 5) target pose x, y, theta, vx, vy (m, rad, m/s).
        pos: (N, 2) robot position (m). angle: (N,) robot heading (rad).
        vel: (N, 2) robot velocity in the field frame (m/s). ang_vel: (N,) (rad/s).
        obs_pos: (N, K, 2), obs_vel: (N, K, 2), obs_ang_vel: (N, K) obstacles, K >= 0.
        max_pos, max_v, max_w: normalisers (m, m/s, rad/s); clip: bound of every value.

    Returns:
        (N, 13 + 5K) float32, laid out as in the module docstring.
    """
    n, k = obs_pos.shape[:2]
    obs = np.empty((n, MANAGER_OBS_BASE_DIM + OBSTACLE_OBS_DIM * k), dtype=np.float32)
    arrays = (target, pos, angle, vel, ang_vel, obs_pos, obs_vel, obs_ang_vel)
    scales = observation_scales(k, float(max_pos), float(max_v), float(max_w))
    _observation_rows(*map(as_float, arrays), scales, float(clip), obs)
    return obs


def first_robot_observation(
    target: np.ndarray, state: RobotState, scales: np.ndarray, clip: float = 1.2
) -> np.ndarray:
    """``manager_observation`` of robot 0 of every field, the field's other robots its obstacles, from the
    arrays of ``state`` (N, R) as they are: no slices, no conversions (the paper tasks' core observes this
    way, once a step; at one field those are most of the cost).

    Shapes: target (N, M, 5), robot 0's in column 0; ``state``'s arrays float64, as a ``World`` and the
    deploy view make them (trusted, not converted). ``scales``: ``observation_scales(R - 1, ...)``.
    Returns (N, 13 + 5 (R - 1)) float32.
    """
    n, r = state.angle.shape
    obs = np.empty((n, MANAGER_OBS_BASE_DIM + OBSTACLE_OBS_DIM * (r - 1)), dtype=np.float32)
    _first_robot_rows(target, state.pos, state.angle, state.vel, state.ang_vel, scales, clip, obs)
    return obs


@numba.njit(cache=True)
def _observation_rows(
    target: np.ndarray,
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    ang_vel: np.ndarray,
    obs_pos: np.ndarray,
    obs_vel: np.ndarray,
    obs_ang_vel: np.ndarray,
    scales: np.ndarray,
    clip: float,
    out: np.ndarray,
) -> None:
    """``manager_observation``'s rows written into ``out`` (N, 13 + 5K) float32, in one compiled loop (one
    call whatever N: at one field numpy's per-call overhead, not the arithmetic, is the cost)."""
    raw = np.empty(out.shape[1])  # one row before scaling, in layout order
    for b in range(out.shape[0]):
        own = (target[b], pos[b], angle[b], vel[b], ang_vel[b])
        _observation_row(*own, obs_pos[b], obs_vel[b], obs_ang_vel[b], scales, clip, raw, out[b])


@numba.njit(cache=True)
def _first_robot_rows(
    target: np.ndarray,
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    ang_vel: np.ndarray,
    scales: np.ndarray,
    clip: float,
    out: np.ndarray,
) -> None:
    """``first_robot_observation``'s rows written into ``out`` (N, 13 + 5 (R - 1)) float32."""
    raw = np.empty(out.shape[1])
    for b in range(out.shape[0]):
        own = (target[b, 0], pos[b, 0], angle[b, 0], vel[b, 0], ang_vel[b, 0])
        _observation_row(*own, pos[b, 1:], vel[b, 1:], ang_vel[b, 1:], scales, clip, raw, out[b])


@numba.njit(cache=True)
def _observation_row(
    target: np.ndarray,
    pos: np.ndarray,
    angle: float,
    vel: np.ndarray,
    ang_vel: float,
    obs_pos: np.ndarray,
    obs_vel: np.ndarray,
    obs_ang_vel: np.ndarray,
    scales: np.ndarray,
    clip: float,
    raw: np.ndarray,
    out: np.ndarray,
) -> None:
    """One field's observation into ``out`` (13 + 5K,) float32, by way of ``raw`` (the same length, float64:
    the row before scaling, in layout order). Shapes: target (5,); pos, vel (2,); obs_pos, obs_vel (K, 2);
    obs_ang_vel (K,)."""
    raw[0:2], raw[4:6] = target[0:2], target[3:5]
    raw[2], raw[3] = math.sin(target[2]), math.cos(target[2])
    raw[6:8], raw[8], raw[9] = pos, math.sin(angle), math.cos(angle)
    raw[10:12], raw[12] = vel, ang_vel
    for j in range(obs_pos.shape[0]):
        slot = raw[MANAGER_OBS_BASE_DIM + OBSTACLE_OBS_DIM * j :]
        slot[0:2], slot[2:4], slot[4] = obs_pos[j], obs_vel[j], obs_ang_vel[j]
    for column in range(raw.shape[0]):
        out[column] = min(max(raw[column] / scales[column], -clip), clip)


@functools.lru_cache(maxsize=64)
def observation_scales(k: int, max_pos: float, max_v: float, max_w: float) -> np.ndarray:
    """The divisor of each column of the layout with ``k`` obstacles (1 for sin and cos)."""
    base = [max_pos, max_pos, 1.0, 1.0, max_v, max_v, max_pos, max_pos, 1.0, 1.0, max_v, max_v, max_w]
    return np.array(base + [max_pos, max_pos, max_v, max_v, max_w] * k)
