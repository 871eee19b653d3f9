"""Direct per-step calls into pymunk's Chipmunk space for a World: batched body reads and writes, steps.

``pymunk.batch`` builds its cffi call data, and the caller a numpy view of the result, on every call,
and ``Space.step`` runs bookkeeping for objects added or removed during a step; at one field each costs as
much as the work itself. ``FastSpace`` makes the call data and views once.

A step starts each joint from the impulse it applied in the last one (Chipmunk's warm starting), which
pymunk neither exposes nor pickles: ``joint_impulses`` reads it and ``set_joint_impulses`` writes it, so
that a copied space starts its next step from the same impulses as its original.
"""

from __future__ import annotations

import numpy as np
import pymunk
import pymunk.batch as pb

# Where Chipmunk keeps a joint's accumulated impulse (``jAcc`` of cpPivotJoint, cpGearJoint), counted in
# doubles from the start of the struct; every read and write is checked against pymunk's ``impulse``.
_PIVOT_IMPULSE, _GEAR_IMPULSE = slice(25, 27), 18


class FastSpace:
    """The per-step pymunk calls of a World, for a space whose bodies, shapes and handlers never change.

    The call data and views are made once and the steps call Chipmunk directly. Reads land in the read
    buffer's own memory, which pymunk sizes on the first read and never grows again while the body count
    stays the same (checked after every read); writes come from numpy memory, which pymunk only reads.
    """

    def __init__(self, space: pymunk.Space, read_fields: pb.BodyFields, width: int) -> None:
        self._space = space._space
        # The Python-side body registry: a write with more bodies than rows would read past the rows.
        self._bodies, self._num_bodies = space._bodies, len(space._bodies)
        self._buffer = pb.Buffer()
        pb.get_space_bodies(space, read_fields, self._buffer)
        self._array = self._buffer._float_arr
        self._size, self._capacity = self._array.num, self._array.max
        # A view of pymunk's memory, refreshed in place by every read.
        self.rows = np.frombuffer(self._buffer.float_buf(), dtype=np.float64).reshape(-1, width)
        self._get = call_data(read_fields, self._buffer, "pmSpaceBodyGetIteratorFuncBatched")
        self._each_body, self._step = pb.lib.cpSpaceEachBody, pb.lib.cpSpaceStep
        check = self.rows.copy()
        self.read()
        if not np.array_equal(check, self.rows):
            raise RuntimeError(f"pymunk {pymunk.version}: direct batch read disagrees with pymunk.batch")

    def read(self) -> np.ndarray:
        """Every body's fields, one row each, in pymunk's order. Shape: (rows, width), valid until the next
        read."""
        self._array.num = 0
        self._each_body(self._space, *self._get)
        if self._array.num != self._size or self._array.max != self._capacity:
            raise RuntimeError("bodies were added to or removed from the World's pymunk space")
        return self.rows

    def writer(self, fields: pb.BodyFields, rows: np.ndarray) -> BodyWriter:
        """A call that writes ``rows`` (rows, width) float64, C-contiguous, into every body's ``fields``."""
        return BodyWriter(self, fields, rows)

    def step(self, dt: float, count: int) -> None:
        for _ in range(count):
            self._step(self._space, dt)


def call_data(fields: pb.BodyFields, buffer: pb.Buffer, function: str) -> tuple[object, object]:
    """The (iterator, data) pair pymunk.batch passes to cpSpaceEachBody."""
    data = pb.ffi.new("pmBatchedData *")
    data.fields = fields.value
    data.floatArray = buffer._float_arr
    data.intArray = buffer._int_arr
    return pb.ffi.addressof(pb.lib, function), data


class BodyWriter:
    """``FastSpace.writer``'s call: writes its ``rows`` into every body."""

    def __init__(self, fast: FastSpace, fields: pb.BodyFields, rows: np.ndarray) -> None:
        if rows.dtype != np.float64 or not rows.flags.c_contiguous or rows.shape[:1] != fast.rows.shape[:1]:
            raise ValueError("body rows to write must be C-contiguous float64, one row per body")
        self._fast, self._space, self.rows = fast, fast._space, rows
        # The Buffer must outlive every write: it holds the numpy memory pymunk reads from.
        self._buffer = pb.Buffer()
        self._buffer.set_float_buf(rows)
        self._array = self._buffer._float_arr
        self._set = call_data(fields, self._buffer, "pmSpaceBodySetIteratorFuncBatched")

    def __call__(self) -> None:
        fast = self._fast
        if len(fast._bodies) != fast._num_bodies:
            raise RuntimeError("bodies were added to or removed from the World's pymunk space")
        self._array.num = 0
        fast._each_body(self._space, *self._set)


def _impulse_memory(joint: pymunk.Constraint) -> np.ndarray:
    """The joint's accumulated impulse, as a numpy view of Chipmunk's memory: (2,) pivot, (1,) gear."""
    doubles = pb.ffi.cast("double *", joint._constraint)
    at = _PIVOT_IMPULSE if isinstance(joint, pymunk.PivotJoint) else slice(_GEAR_IMPULSE, _GEAR_IMPULSE + 1)
    buffer = pb.ffi.buffer(doubles + at.start, 8 * (at.stop - at.start))
    view = np.frombuffer(buffer, dtype=np.float64)
    # pymunk's impulse is Chipmunk's length of it, |j| of a gear's and sqrt(x x + y y) of a pivot's: equal
    # to numpy's within an ulp or two. A joint at rest can hold one too small to square (a gear's 4e-298
    # was seen), whose subnormal square rounds coarsely: a difference below 1e-150 N s is not a misread.
    length = abs(view[0]) if len(view) == 1 else np.sqrt(view[0] * view[0] + view[1] * view[1])
    if not abs(length - joint.impulse) <= 1e-12 * joint.impulse + 1e-150:
        raise RuntimeError(f"pymunk {pymunk.version} keeps a joint's impulse elsewhere than this World reads")
    return view


def joint_impulses(joints: list[pymunk.PivotJoint | pymunk.GearJoint]) -> np.ndarray:
    """Each joint's impulse of the last step, (J, 2) (a gear's in column 0, column 1 zero)."""
    out = np.zeros((len(joints), 2))
    for row, joint in zip(out, joints, strict=True):
        memory = _impulse_memory(joint)
        row[: len(memory)] = memory
    return out


def set_joint_impulses(joints: list[pymunk.PivotJoint | pymunk.GearJoint], impulses: np.ndarray) -> None:
    """Give each joint the impulse ``impulses`` (J, 2) holds for it (``joint_impulses``' layout)."""
    for joint, value in zip(joints, impulses, strict=True):
        memory = _impulse_memory(joint)
        memory[...] = value[: len(memory)]
        _impulse_memory(joint)  # read back through pymunk's getter: the write landed where it reads
