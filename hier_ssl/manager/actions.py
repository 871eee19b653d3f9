"""Decoding the manager's normalised action into a sub-goal pose for the worker, and back.

Two action forms (SPEC "Manager action"):

- ``"pose4"`` (public code): (x, y, sin, cos); the sub-goal velocity is 0.
- ``"pose6"`` (paper text): (x, y, vx, vy, sin, cos).

x is scaled by half the field length, y by half its width, velocities by max_v, and the
angle is atan2(sin, cos). A sub-goal pose is (N, 5): x, y, theta, vx, vy in the field frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from hier_ssl.manager.observation import check_array

ACTION_DIMS: dict[str, int] = {"pose4": 4, "pose6": 6}


def action_dim(form: str) -> int:
    """Number of action values of `form` ("pose4" or "pose6")."""
    if form not in ACTION_DIMS:
        raise ValueError(f"unknown action form {form!r}; expected one of {sorted(ACTION_DIMS)}")
    return ACTION_DIMS[form]


def _check_scales(half_length: float, half_width: float, max_v: float) -> None:
    for name, scale in (("half_length", half_length), ("half_width", half_width), ("max_v", max_v)):
        if not scale > 0:
            raise ValueError(f"{name} must be > 0, got {scale}")


def decode_subgoal(
    action: ArrayLike,
    form: str,
    half_length: float,
    half_width: float,
    max_v: float = 2.5,
    zero_velocity: bool = False,
) -> np.ndarray:
    """Turn normalised actions into sub-goal poses.

    Args:
        action: (N, action_dim(form)) values in [-1, 1]. Position and velocity values outside
            are clipped, so a noisy scripted action still names a point on the field.
        form: "pose4" or "pose6".
        half_length, half_width: half the field's length (x) and width (y), m.
        max_v: speed that a velocity value of 1 stands for, m/s.
        zero_velocity: force the sub-goal velocity to 0 (the Proposed task's constraint);
            "pose4" sub-goals always have zero velocity.

    Returns:
        (N, 5) float64 sub-goal x, y, theta, vx, vy. theta is in (-pi, pi]; sin = cos = 0
        decodes to theta = 0.
    """
    dim = action_dim(form)
    _check_scales(half_length, half_width, max_v)
    action = check_array("action", action, (None, dim))
    n = action.shape[0]
    if form == "pose4":
        xy, sin, cos = action[:, 0:2], action[:, 2], action[:, 3]
        vel = np.zeros((n, 2))
    else:
        xy, sin, cos = action[:, 0:2], action[:, 4], action[:, 5]
        vel = np.zeros((n, 2)) if zero_velocity else np.clip(action[:, 2:4], -1.0, 1.0) * max_v
    xy = np.clip(xy, -1.0, 1.0) * np.array([half_length, half_width])
    theta = np.arctan2(sin, cos)
    return np.concatenate([xy, theta[:, None], vel], axis=1)


def encode_subgoal(
    subgoal: ArrayLike,
    form: str,
    half_length: float,
    half_width: float,
    max_v: float = 2.5,
) -> np.ndarray:
    """Inverse of `decode_subgoal`: the normalised action that names each sub-goal pose.

    Args:
        subgoal: (N, 5) x, y, theta, vx, vy (m, rad, m/s).
        form, half_length, half_width, max_v: as in `decode_subgoal`.

    Returns:
        (N, action_dim(form)) float64 action in [-1, 1]: positions and velocities beyond the
        field or max_v are clipped, and "pose4" drops the velocity, which it cannot express.
        encode(decode(a)) == a for in-range a whose sin^2 + cos^2 = 1.
    """
    action_dim(form)  # rejects an unknown form before any work
    _check_scales(half_length, half_width, max_v)
    subgoal = check_array("subgoal", subgoal, (None, 5))
    xy = np.clip(subgoal[:, 0:2] / np.array([half_length, half_width]), -1.0, 1.0)
    sincos = np.stack([np.sin(subgoal[:, 2]), np.cos(subgoal[:, 2])], axis=1)
    if form == "pose4":
        return np.concatenate([xy, sincos], axis=1)
    vel = np.clip(subgoal[:, 3:5] / max_v, -1.0, 1.0)
    return np.concatenate([xy, vel, sincos], axis=1)
