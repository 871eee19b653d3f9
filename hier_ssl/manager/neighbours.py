"""The manager's observation for many robots: target, own state and the K nearest other robots.

Layout, 13 values (the paper's observation without obstacles, docs/paper.md "Observations") then 6 per
neighbour slot, nearest first::

    0-12      as ``hier_ssl.manager.observation`` with K = 0
    13+6k     neighbour k: relative x, y / max_pos, relative vx, vy / max_v, teammate, present

"Relative" is the neighbour's value minus the robot's own, in the field frame. ``teammate`` is 1 for
another controlled robot and 0 for an obstacle; ``present`` is 1 for a real neighbour and 0 for a padding
slot (all six values 0) when fewer than K other robots exist. The width depends on K only, not on how many
robots a scenario has, so one policy serves every robot count. Positions and velocities are clipped to
[-clip, clip] like the rest of the observation. Read it through ``NEIGHBOUR_OBS_SLICES`` and
``neighbour_obs_slice``. The paper's 1-obstacle layout stays in ``hier_ssl.manager.observation``.

The "encounters" layout is this one with 6 more values per slot appended after the K slots (closest
approaches and the neighbour in the robot -> target frame, ``hier_ssl.manager.encounter``): 13 + 12K.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike

from hier_ssl.manager.encounter import ENCOUNTER_DIM, encounter_columns
from hier_ssl.manager.observation import (
    MANAGER_OBS_BASE_DIM,
    MANAGER_OBS_SLICES,
    OBSTACLE_OBS_DIM,
    check_array,
    manager_observation,
    slot_slice,
    slots_dim,
)

NEIGHBOUR_OBS_DIM = 6

# Offsets inside one neighbour's block; `neighbour_obs_slice` gives the block itself.
NEIGHBOUR_OBS_SLICES: dict[str, slice] = {
    "rel_pos": slice(0, 2),
    "rel_vel": slice(2, 4),
    "teammate": slice(4, 5),
    "present": slice(5, 6),
}


def neighbour_obs_dim(k: int, encounters: bool = False) -> int:
    """Length of the observation with ``k`` neighbour slots (with their encounter columns)."""
    return slots_dim(k, NEIGHBOUR_OBS_DIM + ENCOUNTER_DIM * encounters, "number of neighbour slots")


def neighbour_obs_slice(k: int) -> slice:
    """Columns of neighbour slot ``k`` (0-based, 0 the nearest)."""
    return slot_slice(k, NEIGHBOUR_OBS_DIM, "neighbour index")


def nearest(pos: np.ndarray, others_pos: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the ``k`` other robots nearest to each robot, nearest first (ties: lower index first).

    Args:
        pos: (B, 2) m. others_pos: (B, J, 2) m, J >= 0.

    Returns:
        index (B, k) int into the J axis and present (B, k) bool; slots past J are padding (index 0,
        present False).
    """
    b, j = others_pos.shape[:2]
    index = np.zeros((b, k), dtype=np.int64)
    _nearest(np.asarray(pos, np.float64), np.asarray(others_pos, np.float64), index)
    present = np.zeros((b, k), dtype=bool)
    present[:, :j] = True
    return index, present


# One compiled loop, not a numpy call per step of it: the game scenarios ask this every control step. The
# lengths are ``vector_length``'s, sqrt(dx^2 + dy^2), and the sort is as stable as numpy's, so the order is
# the one numpy's ``argsort(kind="stable")`` of those lengths gave.
@numba.njit(cache=True)
def _nearest(pos: np.ndarray, others_pos: np.ndarray, index: np.ndarray) -> None:
    """Writes ``nearest``'s ``index`` (B, k) of ``pos`` (B, 2) and ``others_pos`` (B, J, 2); slots past J
    keep their 0."""
    dist = np.empty(others_pos.shape[1])
    for row in range(pos.shape[0]):
        for j in range(others_pos.shape[1]):
            dx, dy = others_pos[row, j, 0] - pos[row, 0], others_pos[row, j, 1] - pos[row, 1]
            dist[j] = math.sqrt(dx * dx + dy * dy)
        order = np.argsort(dist, kind="mergesort")
        for slot in range(min(index.shape[1], order.shape[0])):
            index[row, slot] = order[slot]


def neighbour_observation(
    target: np.ndarray,
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    ang_vel: np.ndarray,
    others_pos: np.ndarray,
    others_vel: np.ndarray,
    teammate: np.ndarray,
    k: int,
    *,
    max_pos: float = 3.8,
    max_v: float = 2.5,
    max_w: float = 10.0,
    clip: float = 1.2,
    encounters: bool = False,
) -> np.ndarray:
    """Observations of B robots, each seeing its ``k`` nearest other robots.

    Args:
        target: (B, 5) x, y, theta, vx, vy. pos: (B, 2). angle: (B,). vel: (B, 2). ang_vel: (B,).
        others_pos, others_vel: (B, J, 2) every other robot of the robot's field (teammates and
            obstacles), field frame. teammate: (B, J) bool, which of them are controlled robots.
        k: neighbour slots; max_pos, max_v, max_w, clip: as in ``manager_observation``.
        encounters: append the "encounters" columns (module docstring).

    Returns:
        (B, 13 + 6k) float32, or (B, 13 + 12k) with ``encounters``, laid out as in the module docstring.
    """
    base = manager_observation(
        target,
        pos,
        angle,
        vel,
        ang_vel,
        np.zeros((len(angle), 0, 2)),
        np.zeros((len(angle), 0, 2)),
        np.zeros((len(angle), 0)),
        max_pos=max_pos,
        max_v=max_v,
        max_w=max_w,
        clip=clip,
    )
    b = base.shape[0]
    index, present = nearest(pos, others_pos, k)
    obs = np.empty((b, base.shape[1] + neighbour_obs_dim(k, encounters) - MANAGER_OBS_BASE_DIM), np.float32)
    obs[:, : base.shape[1]] = base
    slots = obs[:, base.shape[1] : base.shape[1] + NEIGHBOUR_OBS_DIM * k].reshape(b, k, NEIGHBOUR_OBS_DIM)
    rel_pos, rel_vel = np.empty((b, k, 2)), np.empty((b, k, 2))
    _neighbour_slots(
        (np.asarray(pos, np.float64), np.asarray(vel, np.float64)),
        (np.asarray(others_pos, np.float64), np.asarray(others_vel, np.float64), np.asarray(teammate, bool)),
        index,
        (float(max_pos), float(max_v), float(clip)),
        rel_pos,
        rel_vel,
        slots,
    )
    if encounters:
        to_target = (target[:, 0:2] - pos)[:, None]
        columns = encounter_columns(rel_pos, rel_vel, vel[:, None], to_target, max_pos=max_pos, clip=clip)
        tail = obs[:, base.shape[1] + NEIGHBOUR_OBS_DIM * k :].reshape(b, k, ENCOUNTER_DIM)
        tail[...] = np.stack(columns, axis=2) * present[..., None]
    return obs


# The slots in one compiled loop, not some 20 numpy calls a control step. Each value is the numpy expression
# the layout describes in float64 (a relative value is the neighbour's minus the robot's own), rounded to
# float32 once on writing; a padding slot's values are multiplied by 0, as the numpy code this replaced did.
@numba.njit(cache=True)
def _neighbour_slots(
    own: tuple[np.ndarray, np.ndarray],
    others: tuple[np.ndarray, np.ndarray, np.ndarray],
    index: np.ndarray,
    scales: tuple[float, float, float],
    rel_pos: np.ndarray,
    rel_vel: np.ndarray,
    slots: np.ndarray,
) -> None:
    """Writes ``rel_pos``, ``rel_vel`` (B, k, 2) and ``slots`` (B, k, 6) of the neighbours ``index`` (B, k)
    (``nearest``) of robots at ``own`` = (pos, vel) (B, 2) each among ``others`` = (pos, vel (B, J, 2),
    teammate (B, J)); ``scales``: (max_pos, max_v, clip)."""
    pos, vel = own
    others_pos, others_vel, teammate = others
    max_pos, max_v, clip = scales
    j = others_pos.shape[1]
    for row in range(index.shape[0]):
        for slot in range(index.shape[1]):
            present = slot < j
            at, keep = index[row, slot], 1.0 if present else 0.0
            for axis in range(2):
                dp = others_pos[row, at, axis] - pos[row, axis] if j else 0.0
                dv = others_vel[row, at, axis] - vel[row, axis] if j else 0.0
                rel_pos[row, slot, axis], rel_vel[row, slot, axis] = dp, dv
                slots[row, slot, axis] = min(max(dp / max_pos, -clip), clip) * keep
                slots[row, slot, 2 + axis] = min(max(dv / max_v, -clip), clip) * keep
            slots[row, slot, 4] = present and teammate[row, at]
            slots[row, slot, 5] = present


def drop_encounters(obs: np.ndarray) -> np.ndarray:
    """The "neighbours" part (B, 13 + 6k) of "encounters" observations (B, 13 + 12k)."""
    k, rest = divmod(obs.shape[1] - MANAGER_OBS_BASE_DIM, NEIGHBOUR_OBS_DIM + ENCOUNTER_DIM)
    if obs.shape[1] < MANAGER_OBS_BASE_DIM or rest:
        raise ValueError(
            f"obs must have 13 + {NEIGHBOUR_OBS_DIM + ENCOUNTER_DIM}k columns, got {obs.shape[1]}"
        )
    return obs[:, : MANAGER_OBS_BASE_DIM + NEIGHBOUR_OBS_DIM * k]


def as_obstacle_observation(obs: ArrayLike) -> np.ndarray:
    """The paper's layout (B, 13 + 5P) of neighbour observations (B, 13 + 6k), for code that reads obstacles
    that way (the scripted planners of ``hier_ssl.manager.planners``).

    Every row must have the same number P of present neighbours (true of an env whose robots are all
    observable: P = min(k, robots - 1)). Neighbours become obstacles at absolute positions and velocities:
    own value plus the relative one, both already on the same scale. The angular velocity, which the
    neighbour layout lacks, is 0.
    """
    obs = check_array("obs", obs, (None, None))
    b, width = obs.shape
    k, rest = divmod(width - MANAGER_OBS_BASE_DIM, NEIGHBOUR_OBS_DIM)
    if width < MANAGER_OBS_BASE_DIM or rest:
        raise ValueError(f"obs must have 13 + 6k columns, got {width}")
    blocks = obs[:, MANAGER_OBS_BASE_DIM:].reshape(b, k, NEIGHBOUR_OBS_DIM)
    present = blocks[:, :, NEIGHBOUR_OBS_SLICES["present"]][..., 0] > 0.5
    p = int(present[0].sum()) if b else 0
    if not (present[:, :p].all() and not present[:, p:].any()):
        raise ValueError("as_obstacle_observation needs the same number of present neighbours in every row")
    s = MANAGER_OBS_SLICES
    obstacles = np.concatenate(
        [
            obs[:, None, s["robot_pos"]] + blocks[:, :p, NEIGHBOUR_OBS_SLICES["rel_pos"]],
            obs[:, None, s["robot_vel"]] + blocks[:, :p, NEIGHBOUR_OBS_SLICES["rel_vel"]],
            np.zeros((b, p, 1)),
        ],
        axis=2,
    )
    return np.concatenate(
        [obs[:, :MANAGER_OBS_BASE_DIM], obstacles.reshape(b, OBSTACLE_OBS_DIM * p)], axis=1
    ).astype(np.float32)


def nearest_gap(obs: np.ndarray, max_pos: float) -> np.ndarray:
    """Distance (B,) in m from each robot to its nearest other robot, read from observations (B, O) of
    this layout (slot 0; +inf where it is padding). Clipped positions read as at most ``clip`` x
    ``max_pos``, far beyond any gap this is used for."""
    slot = obs[:, neighbour_obs_slice(0)]
    gap = np.hypot(slot[:, 0], slot[:, 1]) * max_pos
    return np.where(slot[:, 5] > 0, gap, np.inf)
