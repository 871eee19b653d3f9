"""N independent SSL fields of R omnidirectional robots each, stepped together in one pymunk space.

Every robot is a dynamic disc driven by a kinematic control body through a ``PivotJoint`` and a
``GearJoint`` whose ``max_bias`` is 0 and whose ``max_force`` is bounded: the control body carries the
commanded velocity, and the solver pulls the robot towards it with at most ``mass * max_accel`` of
force. The acceleration limit is therefore physical, contacts win over the motors, and robots stay out
of walls and each other (overwriting a dynamic body's velocity every step lets it tunnel through walls).

All state crosses this boundary as arrays with a leading (fields, robots) pair of axes, read and written
with ``pymunk.batch``'s iterators in one call each; there is no per-body Python on the hot path. At one
field a step costs numpy's and pymunk's per-call overheads rather than arithmetic, which is what the
layout of the hot path (``FastSpace``, ``World._prepare``) is about.
"""

from __future__ import annotations

import numpy as np
import pymunk
import pymunk.batch as pb

from hier_ssl.world.field import Field, get_field
from hier_ssl.world.frames import _COMPLEX, all_finite, as_complex, cap_speed, wrap_angle
from hier_ssl.world.robot import RobotSpec, RobotState
from hier_ssl.world.space import FastSpace, joint_impulses, set_joint_impulses

_ROBOT, _WALL = 1, 2
# Wall segments are centred this far outside the wall line, so their surface lies on it.
_WALL_RADIUS = 0.01
_VELOCITY = pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY
_STATE = pb.BodyFields.POSITION | pb.BodyFields.ANGLE | _VELOCITY
# What ``World._prepare`` makes: cffi call data and views of pymunk's memory, made again for a copy.
_PREPARED = set(
    "_fast _raw_pos _raw_angle _raw_vel _raw_spin _write_velocity _write_state _robot_vel _robot_spin "
    "_control_vel _control_spin".split()
)
# At one field numpy's per-call overhead is the whole cost of an operation, and it doubles when an operand
# is a Python scalar, of another dtype, strided or broadcast from a non-0-d array: the hot path keeps to
# contiguous arrays of one shape and dtype, and 0-d constants.


class World:
    """``num_fields`` fields with ``num_robots`` robots each, one pymunk space, one ``step`` for all.

    Fields are laid out on a grid, far enough apart that nothing crosses from one to another. Robot
    indices are the caller's: which robots are controlled and which are obstacles is not the world's
    business. ``state`` is replaced, never modified, by ``step`` and ``set_state``: a state a caller keeps
    stays as it was. Bodies must not be added to or removed from ``space``.

    A world pickles and copies: the copy has the same bodies, contacts and joint impulses and steps bit
    for bit as the original while no robot touches two bodies at once. When one does, Chipmunk's broad
    phase (which nothing pickles) may list those contacts in another order, and the two differ by the
    solver's rounding (1e-8 m measured), which later contacts can grow.
    """

    def __init__(
        self,
        num_fields: int,
        num_robots: int,
        field: Field | str = "hardware_challenge",
        robot: RobotSpec | None = None,
        dt: float = 0.025,
        substeps: int = 2,
        iterations: int = 5,
    ) -> None:
        if not (isinstance(num_fields, int | np.integer) and num_fields >= 1):
            raise ValueError(f"num_fields must be an integer >= 1, got {num_fields!r}")
        if not (isinstance(num_robots, int | np.integer) and num_robots >= 1):
            raise ValueError(f"num_robots must be an integer >= 1, got {num_robots!r}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        if not (isinstance(substeps, int) and substeps >= 1):
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.field = get_field(field) if isinstance(field, str) else field
        self.robot = robot or RobotSpec()
        self.num_fields, self.num_robots = int(num_fields), int(num_robots)
        self.dt, self.substeps = float(dt), substeps
        self._sub_dt = self.dt / substeps

        self.space = pymunk.Space()
        self.space.iterations = iterations
        # Units are metres: pymunk's default slop (0.1) would allow 10 cm of overlap.
        self.space.collision_slop = 5e-4
        # Push half of any remaining overlap out per substep (pymunk's default leaves ~92 %).
        self.space.collision_bias = 0.5 ** (1.0 / self._sub_dt)

        hx, hy = self.field.wall_half_extent
        pitch = 2 * max(hx, hy) + 2.0
        cols = int(np.ceil(np.sqrt(self.num_fields)))
        idx = np.arange(self.num_fields)
        self.offsets = np.stack([(idx % cols) * pitch, (idx // cols) * pitch], axis=-1).astype(np.float64)

        self._shape_owner: dict[pymunk.Shape, tuple[int, int]] = {}
        self._joints: list[pymunk.Constraint] = []
        robots, controls = self._build(hx, hy)
        self._check_body_order(robots, controls)
        self._prepare(hx, hy)

        n, r = self.num_fields, self.num_robots
        self.robot_contacts = np.zeros((n, r, r), dtype=bool)
        self.robot_touch = np.zeros((n, r), dtype=bool)  # robot_contacts.any(axis=2), kept by the callback
        self.wall_contacts = np.zeros((n, r), dtype=bool)
        self._contacts_set = False  # whether a callback has written a contact since the last clearing
        self.space.on_collision(_ROBOT, _ROBOT, pre_solve=self._on_robot_contact)
        self.space.on_collision(_ROBOT, _WALL, pre_solve=self._on_wall_contact)
        self.state = self._read_state()

    # -- construction -------------------------------------------------------------------------------------

    def _build(self, hx: float, hy: float) -> tuple[list[pymunk.Body], list[pymunk.Body]]:
        spec = self.robot
        moment = pymunk.moment_for_circle(spec.mass, 0, spec.radius)
        robots, controls = [], []
        parked = self._parking_spots()
        for f in range(self.num_fields):
            ox, oy = self.offsets[f]
            wx, wy = hx + _WALL_RADIUS, hy + _WALL_RADIUS
            corners = [(ox - wx, oy - wy), (ox + wx, oy - wy), (ox + wx, oy + wy), (ox - wx, oy + wy)]
            for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
                wall = pymunk.Segment(self.space.static_body, a, b, _WALL_RADIUS)
                wall.collision_type, wall.friction, wall.elasticity = _WALL, 0.2, 0.0
                self.space.add(wall)
                self._shape_owner[wall] = (f, -1)
            for i in range(self.num_robots):
                body = pymunk.Body(spec.mass, moment)
                body.position = (ox + parked[i, 0], oy + parked[i, 1])
                disc = pymunk.Circle(body, spec.radius)
                disc.collision_type, disc.friction, disc.elasticity = _ROBOT, 0.2, 0.0
                control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
                control.position = body.position
                pivot = pymunk.PivotJoint(control, body, (0, 0), (0, 0))
                pivot.max_bias, pivot.max_force = 0.0, spec.mass * spec.max_accel
                gear = pymunk.GearJoint(control, body, 0.0, 1.0)
                gear.max_bias, gear.max_force = 0.0, moment * spec.max_ang_accel
                self.space.add(body, disc, control, pivot, gear)
                self._joints += [pivot, gear]
                self._shape_owner[disc] = (f, i)
                robots.append(body)
                controls.append(control)
        return robots, controls

    def _parking_spots(self) -> np.ndarray:
        """Non-overlapping start positions (R, 2) used until the first reset."""
        gap = 3 * self.robot.radius
        cols = max(1, int(self.field.length // gap) - 1)
        i = np.arange(self.num_robots)
        spots = np.stack([(i % cols) * gap, (i // cols) * gap], axis=-1)
        return spots - spots.mean(axis=0)

    def _check_body_order(self, robots: list[pymunk.Body], controls: list[pymunk.Body]) -> None:
        # pymunk.batch lists bodies in insertion order and adds the static body once the space has
        # stepped. Checked once here, that order lets every per-step access be a strided view instead of
        # a gather through index arrays.
        self.space.step(self._sub_dt)
        ids = pb.Buffer()
        pb.get_space_bodies(self.space, pb.BodyFields.BODY_ID, ids)
        expected = [b.id for pair in zip(robots, controls, strict=True) for b in pair]
        expected.append(self.space.static_body.id)
        if np.frombuffer(ids.int_buf(), dtype=np.uintp).tolist() != expected:
            raise RuntimeError(
                f"pymunk {pymunk.version} lists bodies in an unexpected order; this World needs "
                "pymunk.batch to return robot, control, ..., static body"
            )

    def _pairs(self, rows: np.ndarray) -> np.ndarray:
        """(rows, C) body rows as (N, R, 2, C): [..., 0, :] the robots, [..., 1, :] their control bodies."""
        return rows[:-1].reshape(self.num_fields, self.num_robots, 2, rows.shape[-1])

    def _prepare(self, hx: float, hy: float) -> None:
        """Batch buffers, views into them and constants of the hot path, made once.

        numpy costs about twice as much per call when an operand is strided or broadcast than when all are
        contiguous and of one shape, or 0-d: the state is copied out of pymunk's rows into contiguous
        arrays once per read, and constants are full-shape or 0-d arrays.
        """
        n, r, spec = self.num_fields, self.num_robots, self.robot
        self._fast = FastSpace(self.space, _STATE, 6)
        robots = self._pairs(self._fast.rows)[:, :, 0]
        self._raw_pos, self._raw_angle = robots[..., 0:2], robots[..., 2]
        self._raw_vel, self._raw_spin = robots[..., 3:5], robots[..., 5]
        # The static body's row stays zero: a velocity written there throws robots out of their fields.
        self._write_velocity = self._fast.writer(_VELOCITY, np.zeros((len(self._fast.rows), 3)))
        self._write_state = self._fast.writer(_STATE, np.zeros((len(self._fast.rows), 6)))
        pairs = self._pairs(self._write_velocity.rows)
        self._robot_vel, self._robot_spin = pairs[:, :, 0, 0:2], pairs[:, :, 0, 2]
        self._control_vel, self._control_spin = as_complex(pairs[:, :, 1, 0:2]), pairs[:, :, 1, 2]

        self._command_shape = (n, r, 3)
        self._i_angle = np.zeros((n, r), dtype=_COMPLEX)
        self._field_offsets = np.ascontiguousarray(np.broadcast_to(self.offsets[:, None, :], (n, r, 2)))
        wall_limit = np.broadcast_to(np.array([hx, hy]) - spec.radius, (n, r, 2))
        self._wall_hi, self._wall_lo = wall_limit.copy(), -wall_limit
        self._clear = self._wall_hi - 1e-9
        self._max_speed = np.array(spec.max_speed)
        self._max_spin, self._min_spin = np.array(spec.max_ang_speed), np.array(-spec.max_ang_speed)
        self._zero, self._dt = np.array(0.0), np.array(self.dt)

    # -- pickling and copying -----------------------------------------------------------------------------

    def __getstate__(self) -> dict[str, object]:
        # All but what ``_prepare`` makes; pymunk pickles the space, contact cache and handlers included.
        state = {k: v for k, v in self.__dict__.items() if k not in _PREPARED}
        return {**state, "_joints": (self._joints, joint_impulses(self._joints))}

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self._joints, impulses = self._joints
        set_joint_impulses(self._joints, impulses)
        self._prepare(*self.field.wall_half_extent)
        if not np.array_equal(self._read_state().pos, self.state.pos):  # the same bodies in the same rows
            raise RuntimeError(f"pymunk {pymunk.version}: a copied space lists its bodies in another order")

    # -- contacts -----------------------------------------------------------------------------------------

    def _on_robot_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        a, b = arbiter.shapes
        (f, i), (_, j) = self._shape_owner[a], self._shape_owner[b]
        self.robot_contacts[f, i, j] = self.robot_contacts[f, j, i] = True
        self.robot_touch[f, i] = self.robot_touch[f, j] = True
        self._contacts_set = True

    def _on_wall_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        a, b = arbiter.shapes
        f, i = self._shape_owner[a] if a.collision_type == _ROBOT else self._shape_owner[b]
        self.wall_contacts[f, i] = True
        self._contacts_set = True

    # -- state --------------------------------------------------------------------------------------------

    def _read_state(self) -> RobotState:
        self._fast.read()
        angle = wrap_angle(self._raw_angle)
        # exp(i angle) as ``heading`` makes it, for the next step's robot-to-field rotation and the workers:
        # the real part of the exponent stays 0.
        self._i_angle.imag = angle
        # A copy and an in-place subtraction: faster than one subtraction from the strided rows.
        pos = self._raw_pos.copy()
        pos -= self._field_offsets
        return RobotState(pos, angle, self._raw_vel.copy(), self._raw_spin.copy(), np.exp(self._i_angle))

    def set_state(
        self,
        fields: np.ndarray | list[int],
        pos: np.ndarray,
        angle: np.ndarray,
        vel: np.ndarray | None = None,
        ang_vel: np.ndarray | None = None,
    ) -> None:
        """Place every robot of the given fields; robots of other fields are untouched.

        Shapes: fields (M,) ints; pos (M, R, 2); angle (M, R); vel (M, R, 2) and ang_vel (M, R), zero if None.
        """
        fields = np.asarray(fields, dtype=np.int64).reshape(-1)
        m, r = len(fields), self.num_robots
        if m and (fields.min() < 0 or fields.max() >= self.num_fields):
            bad = fields[(fields < 0) | (fields >= self.num_fields)]
            raise ValueError(f"field index {bad.tolist()} out of range [0, {self.num_fields})")
        vel = np.zeros((m, r, 2)) if vel is None else vel
        ang_vel = np.zeros((m, r)) if ang_vel is None else ang_vel
        arrays = {
            "pos": (pos, (m, r, 2)),
            "angle": (angle, (m, r)),
            "vel": (vel, (m, r, 2)),
            "ang_vel": (ang_vel, (m, r)),
        }
        checked = {}
        for name, (value, shape) in arrays.items():
            value = np.asarray(value, dtype=np.float64)
            if value.shape != shape:
                raise ValueError(f"set_state: {name} has shape {value.shape}, expected {shape}")
            if not np.isfinite(value).all():
                raise ValueError(f"set_state: {name} holds NaN or infinite values")
            checked[name] = value
        reach = np.array(self.field.wall_half_extent) - self.robot.radius
        outside = (np.abs(checked["pos"]) > reach).any(axis=-1)
        if outside.any():
            f, i = np.argwhere(outside)[0]
            raise ValueError(
                f"set_state: robot {i} of field {fields[f]} at {checked['pos'][f, i].tolist()} is not inside "
                f"the walls (|x| <= {reach[0]:.3f}, |y| <= {reach[1]:.3f})"
            )
        if m == 0:
            return
        out = self._write_state.rows
        out[:] = self._fast.read()
        packed = np.concatenate(
            [
                checked["pos"] + self.offsets[fields, None, :],
                checked["angle"][..., None],
                checked["vel"],
                checked["ang_vel"][..., None],
            ],
            axis=-1,
        )
        pairs = self._pairs(out)
        pairs[fields, :, 0] = packed
        pairs[fields, :, 1] = packed
        self._write_state()
        self.robot_contacts[fields] = False
        self.robot_touch[fields] = False
        self.wall_contacts[fields] = False
        self.state = self._read_state()

    # -- stepping -----------------------------------------------------------------------------------------

    def step(self, command: np.ndarray) -> RobotState:
        """Advance every field by one control period.

        ``command`` (N, R, 3) is each robot's (vx, vy, w) in its own frame, m/s and rad/s. The world caps
        speed and angular speed at the robot's limits; acceleration is capped by the joints' force. After
        the call ``state`` holds the new poses and ``robot_contacts`` (N, R, R) / ``wall_contacts`` (N, R)
        tell which robots touched which robot or wall during any substep of this period, ``robot_touch``
        (N, R) which touched any robot.
        """
        command = np.ascontiguousarray(command, dtype=np.float64)
        if command.shape != self._command_shape:
            raise ValueError(f"command has shape {command.shape}, expected {self._command_shape}")
        if not all_finite(command):
            f, i = np.argwhere(~np.isfinite(command).all(axis=-1))[0]
            raise ValueError(f"command holds NaN or infinite values (field {f}, robot {i})")
        state = self.state

        # Control bodies: the command turned into the field frame and capped at the speed limits.
        target = cap_speed(command[..., 0:2].view(_COMPLEX)[..., 0] * state.heading, self._max_speed)
        # (Results are assigned into the strided buffer views: a ufunc writing to them directly is slower.)
        self._control_vel[...] = target
        self._control_spin[...] = np.maximum(np.minimum(command[..., 2], self._max_spin), self._min_spin)
        # Robots keep their velocity, less what would carry them into a wall within this period.
        self._robot_vel[...] = self._speculative_wall_stop(state.pos, state.vel)
        self._robot_spin[...] = state.ang_vel
        self._write_velocity()

        if self._contacts_set:
            self.robot_contacts.fill(False)
            self.robot_touch.fill(False)
            self.wall_contacts.fill(False)
            self._contacts_set = False
        self._fast.step(self._sub_dt, self.substeps)
        self.state = self._read_state()
        return self.state

    def _speculative_wall_stop(self, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
        """Robot velocities (N, R, 2) less the part that would carry a robot into a wall within this
        period: an inelastic wall impact resolved before it happens. pymunk detects contacts only
        after moving bodies, so without this a robot at 2.5 m/s would sink v * dt into a wall before the
        contact pushes back.
        """
        # Most steps no robot would reach a wall: then nothing changes (the margin covers rounding).
        if not np.count_nonzero(np.abs(pos + vel * self._dt) >= self._clear):
            return vel
        room_hi = np.maximum(self._wall_hi - pos, self._zero) / self._dt
        # -limit - pos is exactly -(limit + pos): the lower bound is the upper one mirrored, bit for bit.
        room_lo = np.minimum(self._wall_lo - pos, self._zero) / self._dt
        return np.maximum(np.minimum(vel, room_hi), room_lo)
