"""The checks of what a caller places in a world (``World.set_state``, ``World.set_balls``): each bad
value is a ValueError naming the method, the array, the entity and its field."""

from __future__ import annotations

import numpy as np

from hier_ssl.world.frames import all_finite


def checked_fields(fields: np.ndarray | list[int], num_fields: int) -> np.ndarray:
    """``fields`` as (F,) int64, each one of a world's ``num_fields``."""
    fields = np.asarray(fields, dtype=np.int64).reshape(-1)
    if len(fields) and (fields.min() < 0 or fields.max() >= num_fields):
        bad = fields[(fields < 0) | (fields >= num_fields)]
        raise ValueError(f"field index {bad.tolist()} out of range [0, {num_fields})")
    return fields


def checked_arrays(
    method: str, kind: str, fields: np.ndarray, arrays: dict[str, tuple[object, tuple[int, ...]]]
) -> dict[str, np.ndarray]:
    """Each of ``arrays`` (name: (value, expected shape (F, E, ...))) as float64 of its shape and finite; a
    ValueError naming ``method``, the array and the first entity of ``kind`` and its field otherwise."""
    checked = {}
    for name, (value, shape) in arrays.items():
        value = np.asarray(value, dtype=np.float64)
        if value.shape != shape:
            raise ValueError(f"{method}: {name} has shape {value.shape}, expected {shape}")
        if not all_finite(value):
            f, i = np.argwhere(~np.isfinite(value.reshape(*shape[:2], -1)).all(axis=-1))[0]
            raise ValueError(
                f"{method}: {name} holds NaN or infinite values: {value[f, i].tolist()}, {kind} {i} of field "
                f"{fields[f]}"
            )
        checked[name] = value
    return checked


def check_inside(method: str, kind: str, fields: np.ndarray, pos: np.ndarray, reach: np.ndarray) -> None:
    """A ValueError naming the first entity of ``pos`` (F, E, 2) whose centre is beyond ``reach`` (x, y)."""
    outside = (np.abs(pos) > reach).any(axis=-1)
    if np.count_nonzero(outside):
        f, i = np.argwhere(outside)[0]
        raise ValueError(
            f"{method}: {kind} {i} of field {fields[f]} at {pos[f, i].tolist()} is not inside "
            f"the walls (|x| <= {reach[0]:.3f}, |y| <= {reach[1]:.3f})"
        )


def check_outside_boxes(
    method: str, kind: str, fields: np.ndarray, pos: np.ndarray, boxes: np.ndarray
) -> None:
    """A ValueError naming the first entity of ``pos`` (F, E, 2) whose centre lies inside one of ``boxes``
    (G, 4) x0, x1, y0, y1: the goal walls, grown by the ball's radius, which the ball's sweep assumes it
    starts outside of (a ball inside one leaves through the wall)."""
    x, y = pos[..., 0, None], pos[..., 1, None]
    inside = ((x > boxes[:, 0]) & (x < boxes[:, 1]) & (y > boxes[:, 2]) & (y < boxes[:, 3])).any(axis=-1)
    if np.count_nonzero(inside):
        f, i = np.argwhere(inside)[0]
        raise ValueError(
            f"{method}: {kind} {i} of field {fields[f]} at {pos[f, i].tolist()} is inside a goal wall"
        )


__all__ = ["check_inside", "check_outside_boxes", "checked_arrays", "checked_fields"]
