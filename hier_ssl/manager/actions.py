"""Decoding the manager's normalised action into a sub-goal pose for the worker, and back.

Two action forms (docs/paper.md "Actions: the sub-goal"):

- ``"pose4"`` (public code): (x, y, sin, cos); the sub-goal velocity is 0.
- ``"pose6"`` (paper text): (x, y, vx, vy, sin, cos).

x is scaled by half the field length, y by half its width, velocities by max_v, and the
angle is atan2(sin, cos). A sub-goal pose is (N, 5): x, y, theta, vx, vy in the field frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from hier_ssl.manager.observation import check_array
from hier_ssl.world.frames import as_float

ACTION_DIMS: dict[str, int] = {"pose4": 4, "pose6": 6}
_NO_TARGET = np.zeros((0, 5))


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
        object.__setattr__(self, "_half", np.array([self.half_length, self.half_width]))
        object.__setattr__(self, "_velocity", not (self.zero_velocity or self.form == "pose4"))
        object.__setattr__(self, "_target_frame", self.frame == "target")

    def __call__(self, action: ArrayLike, target: ArrayLike | None) -> np.ndarray:
        """Sub-goals (N, 5) of actions (N, A)."""
        # (The frame's name was checked when made.)
        target = _check_frame(self.frame, target) if self._target_frame else _NO_TARGET
        action = as_float(action)
        subgoal = np.zeros((action.shape[0], 5))
        _decode_rows(action, target, self._half, self.max_v, self._velocity, self._target_frame, subgoal)
        return subgoal


@numba.njit(cache=True)
def _decode_rows(
    action: np.ndarray,
    target: np.ndarray,
    half: np.ndarray,
    max_v: float,
    velocity: bool,
    target_frame: bool,
    out: np.ndarray,
) -> None:
    """``SubgoalDecoder``'s sub-goals (N, 5) of actions (N, A) written into zeros ``out``, one compiled loop
    (at one field numpy's per-call overhead, not the arithmetic, is the cost). ``target`` (N, 5) is read
    in the target frame only."""
    for b in range(action.shape[0]):
        a = action[b]
        x, y, sin, cos = _unit(a[0]), _unit(a[1]), _unit(a[-2]), _unit(a[-1])
        if target_frame:
            x, y, cos = math.pow(x, 3.0), math.pow(y, 3.0), cos + 1.0  # cos is last in both forms
        out[b, 0], out[b, 1], out[b, 2] = x * half[0], y * half[1], math.atan2(sin, cos)
        if velocity:
            out[b, 3], out[b, 4] = _unit(a[2]) * max_v, _unit(a[3]) * max_v
        if target_frame:
            for axis in range(2):
                out[b, axis] = min(max(out[b, axis] + target[b, axis], -half[axis]), half[axis])
            turn = out[b, 2] + target[b, 2]
            out[b, 2] = math.atan2(math.sin(turn), math.cos(turn))


@numba.njit(cache=True)
def _unit(value: float) -> float:
    """``value`` clipped to [-1, 1]."""
    return max(min(value, 1.0), -1.0)


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
