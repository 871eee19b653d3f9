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


ACTION_FRAMES = ("field", "target")


def _check_frame(frame: str) -> None:
    if frame not in ACTION_FRAMES:
        raise ValueError(f"unknown action frame {frame!r}; expected one of {list(ACTION_FRAMES)}")


def decode_in_frame(
    action: ArrayLike,
    form: str,
    frame: str,
    target: ArrayLike,
    half_length: float,
    half_width: float,
    max_v: float = 2.5,
    zero_velocity: bool = False,
) -> np.ndarray:
    """`decode_subgoal` in the field frame (the paper's) or the target frame.

    In the "target" frame x, y are offsets from the target, cubed and then scaled by the field's half
    length and width (|a| < 0.2 lands within 4 cm of the target, yet a detour across half the field stays
    in reach), and the turn from the target's heading is atan2(sin, 1 + cos), within +-90 deg. The zero
    action is then the direct sub-goal (the target pose), so a learner only has to find the detours.
    Velocities are field-frame in both. Every action value is clipped to [-1, 1] first (so the heading
    of an out-of-range sin/cos pair is that of the clipped pair), sub-goals to the field.

    Args:
        target: (N, 5) target poses; read only in the "target" frame.
        Other arguments as in `decode_subgoal`.
    """
    _check_frame(frame)
    action = np.clip(check_array("action", action, (None, action_dim(form))), -1.0, 1.0)
    if frame == "field":
        return decode_subgoal(action, form, half_length, half_width, max_v, zero_velocity)
    target = check_array("target", target, (action.shape[0], 5))
    action[:, 0:2] **= 3
    action[:, -1] += 1.0  # cos is last in both forms
    subgoal = decode_subgoal(action, form, half_length, half_width, max_v, zero_velocity)
    half = np.array([half_length, half_width])
    subgoal[:, 0:2] = np.clip(subgoal[:, 0:2] + target[:, 0:2], -half, half)
    subgoal[:, 2] = np.angle(np.exp(1j * (subgoal[:, 2] + target[:, 2])))
    return subgoal


def encode_in_frame(
    subgoal: ArrayLike,
    form: str,
    frame: str,
    target: ArrayLike,
    half_length: float,
    half_width: float,
    max_v: float = 2.5,
) -> np.ndarray:
    """Inverse of `decode_in_frame`, for scripted managers acting in an environment of either frame.

    In the "target" frame an offset beyond the field's half size and a turn beyond +-90 deg from the
    target's heading are clipped to what the frame can express.
    """
    _check_frame(frame)
    if frame == "field":
        return encode_subgoal(subgoal, form, half_length, half_width, max_v)
    subgoal = check_array("subgoal", subgoal, (None, 5))
    target = check_array("target", target, (subgoal.shape[0], 5))
    action = encode_subgoal(subgoal, form, half_length, half_width, max_v)
    offset = (subgoal[:, 0:2] - target[:, 0:2]) / np.array([half_length, half_width])
    action[:, 0:2] = np.cbrt(np.clip(offset, -1.0, 1.0))
    turn = np.clip(np.angle(np.exp(1j * (subgoal[:, 2] - target[:, 2]))), -np.pi / 2 + 1e-6, np.pi / 2 - 1e-6)
    # atan2(sin 2t, 1 + cos 2t) = t for |t| < 90 deg.
    action[:, -2], action[:, -1] = np.sin(2 * turn), np.cos(2 * turn)
    return action
