"""Decoding the manager's normalised action into a sub-goal pose for the worker, and back.

Two action forms (docs/paper.md "Actions: the sub-goal"):

- ``"pose4"`` (public code): (x, y, sin, cos); the sub-goal velocity is 0.
- ``"pose6"`` (paper text): (x, y, vx, vy, sin, cos).

x is scaled by half the field length, y by half its width, velocities by max_v, and the
angle is atan2(sin, cos). A sub-goal pose is (N, 5): x, y, theta, vx, vy in the field frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hier_ssl.manager.observation import check_array
from hier_ssl.world.frames import as_float

ACTION_DIMS: dict[str, int] = {"pose4": 4, "pose6": 6}
_ONE, _MINUS_ONE = np.array(1.0), np.array(-1.0)


def action_dim(form: str) -> int:
    """Number of action values of `form` ("pose4" or "pose6")."""
    if form not in ACTION_DIMS:
        raise ValueError(f"unknown action form {form!r}; expected one of {sorted(ACTION_DIMS)}")
    return ACTION_DIMS[form]


def _check_scales(half_length: float, half_width: float, max_v: float) -> None:
    for name, scale in (("half_length", half_length), ("half_width", half_width), ("max_v", max_v)):
        if not scale > 0:
            raise ValueError(f"{name} must be > 0, got {scale}")


ACTION_FRAMES = ("field", "target")


def _check_frame_name(frame: str) -> None:
    if frame not in ACTION_FRAMES:
        raise ValueError(f"unknown action frame {frame!r}; expected one of {list(ACTION_FRAMES)}")


def _check_frame(frame: str, target: ArrayLike | None) -> np.ndarray | None:
    """The target poses (N, 5) that the "target" frame needs; None in the "field" frame."""
    _check_frame_name(frame)
    if frame == "field":
        return None
    if target is None:
        raise ValueError("target: the 'target' action frame needs the target poses")
    return np.asarray(target, dtype=np.float64)


def decode_subgoal(
    action: ArrayLike,
    form: str,
    half_length: float,
    half_width: float,
    max_v: float = 2.5,
    zero_velocity: bool = False,
    frame: str = "field",
    target: ArrayLike | None = None,
) -> np.ndarray:
    """Turn normalised actions into sub-goal poses, in the field frame (the paper's) or the target frame.

    In the "target" frame x, y are offsets from the target, cubed and then scaled by the field's half
    length and width (|a| < 0.2 lands within 4 cm of the target, yet a detour across half the field stays
    in reach), and the turn from the target's heading is atan2(sin, 1 + cos), within +-90 deg. The zero
    action is then the direct sub-goal (the target pose), so a learner only has to find the detours.
    Velocities are field-frame in both.

    Args:
        action: (N, action_dim(form)) values in [-1, 1], trusted to have that shape (the views check
            it). Values outside are clipped first (so a noisy scripted action still names a point on
            the field, and an out-of-range sin/cos pair the heading of the clipped pair).
        form: "pose4" or "pose6".
        half_length, half_width: half the field's length (x) and width (y), m.
        max_v: speed that a velocity value of 1 stands for, m/s.
        zero_velocity: force the sub-goal velocity to 0 (the Proposed task's constraint);
            "pose4" sub-goals always have zero velocity.
        frame: "field" or "target"; target: (N, 5) target poses, read in the "target" frame.

    Returns:
        (N, 5) float64 sub-goal x, y, theta, vx, vy. theta is in (-pi, pi]; sin = cos = 0
        decodes to theta = 0 in the field frame. Target-frame sub-goals are clipped to the field.
    """
    return SubgoalDecoder(form, half_length, half_width, max_v, zero_velocity, frame)(action, target)


@dataclass(frozen=True)
class SubgoalDecoder:
    """``decode_subgoal`` with its options checked once: ``decoder(action, target)`` for a core that
    decodes every decision. ``target`` (N, 5) is read in the "target" frame only."""

    form: str
    half_length: float
    half_width: float
    max_v: float = 2.5
    zero_velocity: bool = False
    frame: str = "field"

    def __post_init__(self) -> None:
        action_dim(self.form)  # an unknown form is an error, not an unread column
        _check_scales(self.half_length, self.half_width, self.max_v)
        _check_frame_name(self.frame)
        # 0-d and (2,) arrays: a Python float operand costs numpy a conversion on every call.
        object.__setattr__(self, "_half", np.array([self.half_length, self.half_width]))
        object.__setattr__(self, "_max_v", np.array(self.max_v))
        object.__setattr__(self, "_velocity", not (self.zero_velocity or self.form == "pose4"))

    def __call__(self, action: ArrayLike, target: ArrayLike | None) -> np.ndarray:
        """Sub-goals (N, 5) of actions (N, A)."""
        # (The frame's name was checked when made.)
        target = None if self.frame == "field" else _check_frame(self.frame, target)
        # Clipped into a new array, which the target frame then changes in place.
        action = np.minimum(np.maximum(as_float(action), _MINUS_ONE), _ONE)
        if target is not None:
            action[:, 0:2] **= 3
            action[:, -1] += _ONE  # cos is last in both forms
        subgoal = np.zeros((action.shape[0], 5))
        xy, theta = subgoal[:, 0:2], subgoal[:, 2]
        np.multiply(action[:, 0:2], self._half, out=xy)
        np.arctan2(action[:, -2], action[:, -1], out=theta)
        if self._velocity:
            np.multiply(action[:, 2:4], self._max_v, out=subgoal[:, 3:5])
        if target is not None:
            np.clip(xy + target[:, 0:2], -self._half, self._half, out=xy)
            theta[:] = np.angle(np.exp(1j * (theta + target[:, 2])))
        return subgoal


def encode_subgoal(
    subgoal: ArrayLike,
    form: str,
    half_length: float,
    half_width: float,
    max_v: float = 2.5,
    frame: str = "field",
    target: ArrayLike | None = None,
) -> np.ndarray:
    """Inverse of `decode_subgoal`: the normalised action that names each sub-goal pose.

    Args:
        subgoal: (N, 5) x, y, theta, vx, vy (m, rad, m/s).
        form, half_length, half_width, max_v, frame, target: as in `decode_subgoal`.

    Returns:
        (N, action_dim(form)) float64 action in [-1, 1]: positions and velocities beyond the field or
        max_v (in the target frame: offsets beyond the field's half size, turns beyond +-90 deg) are
        clipped, and "pose4" drops the velocity, which it cannot express. decode(encode(s)) == s for
        sub-goals the form and frame can express.
    """
    action_dim(form)  # rejects an unknown form before any work
    _check_scales(half_length, half_width, max_v)
    subgoal = check_array("subgoal", subgoal, (None, 5))
    target = _check_frame(frame, target)
    if target is not None:
        target = check_array("target", target, (subgoal.shape[0], 5))
    half = np.array([half_length, half_width])
    if target is None:
        xy, turn = np.clip(subgoal[:, 0:2] / half, -1.0, 1.0), subgoal[:, 2]
    else:
        xy = np.cbrt(np.clip((subgoal[:, 0:2] - target[:, 0:2]) / half, -1.0, 1.0))
        # atan2(sin 2t, 1 + cos 2t) = t for |t| < 90 deg.
        limit = np.pi / 2 - 1e-6
        turn = 2 * np.clip(np.angle(np.exp(1j * (subgoal[:, 2] - target[:, 2]))), -limit, limit)
    sincos = np.stack([np.sin(turn), np.cos(turn)], axis=1)
    if form == "pose4":
        return np.concatenate([xy, sincos], axis=1)
    vel = np.clip(subgoal[:, 3:5] / max_v, -1.0, 1.0)
    return np.concatenate([xy, vel, sincos], axis=1)
