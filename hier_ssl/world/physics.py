"""N independent SSL fields of R omnidirectional robots each, stepped together in one pymunk space.

Every robot is a dynamic disc driven by a kinematic control body through a ``PivotJoint`` and a
``GearJoint`` whose ``max_bias`` is 0 and whose ``max_force`` is bounded: the control body carries the
commanded velocity, and the solver pulls the robot towards it with at most ``mass * max_accel`` of
force. The acceleration limit is therefore physical, contacts win over the motors, and robots stay out
of walls and each other (overwriting a dynamic body's velocity every step lets it tunnel through walls).

All state crosses this boundary as arrays with a leading (fields, robots) pair of axes, read and written
with ``pymunk.batch`` in one call each; there is no per-body Python on the hot path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymunk
import pymunk.batch as pb

from hier_ssl.world.field import Field, get_field

_ROBOT, _WALL = 1, 2
# Wall segments are centred this far outside the wall line, so their surface lies on it.
_WALL_RADIUS = 0.01
_STATE = pb.BodyFields.POSITION | pb.BodyFields.ANGLE | pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY
_VELOCITY = pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY


@dataclass(frozen=True)
class RobotSpec:
    """An SSL robot (SPEC.md "World"); speeds in m/s and rad/s, accelerations in m/s^2 and rad/s^2."""

    radius: float = 0.09
    mass: float = 2.2
    max_speed: float = 2.5
    max_accel: float = 3.0
    max_ang_speed: float = 10.0
    max_ang_accel: float = 60.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not value > 0:
                raise ValueError(f"RobotSpec.{name} must be > 0, got {value!r}")


@dataclass
class RobotState:
    """Poses and velocities of every robot, field frame.

    Shapes: pos (N, R, 2) m, angle (N, R) rad in [-pi, pi), vel (N, R, 2) m/s, ang_vel (N, R) rad/s.
    """

    pos: np.ndarray
    angle: np.ndarray
    vel: np.ndarray
    ang_vel: np.ndarray

    def robots(self, index: slice | np.ndarray | list[int]) -> RobotState:
        """The same fields, a subset of robots (a view for slices)."""
        return RobotState(self.pos[:, index], self.angle[:, index], self.vel[:, index], self.ang_vel[:, index])

    def fields(self, index: np.ndarray) -> RobotState:
        return RobotState(self.pos[index], self.angle[index], self.vel[index], self.ang_vel[index])

    def copy(self) -> RobotState:
        return RobotState(self.pos.copy(), self.angle.copy(), self.vel.copy(), self.ang_vel.copy())


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles mapped to [-pi, pi)."""
    return (angle + np.pi) % (2 * np.pi) - np.pi


def to_robot_frame(vec: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate field-frame vectors (..., 2) into the frames of robots at ``angle`` (...)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * vec[..., 0] + s * vec[..., 1], -s * vec[..., 0] + c * vec[..., 1]], axis=-1)


def to_field_frame(vec: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate robot-frame vectors (..., 2) into the field frame."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * vec[..., 0] - s * vec[..., 1], s * vec[..., 0] + c * vec[..., 1]], axis=-1)


class World:
    """``num_fields`` fields with ``num_robots`` robots each, one pymunk space, one ``step`` for all.

    Fields are laid out on a grid, far enough apart that nothing crosses from one to another. Robot
    indices are the caller's: which robots are controlled and which are obstacles is not the world's
    business.
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
        robots, controls = self._build(hx, hy)
        self._index_rows(robots, controls)

        n, r = self.num_fields, self.num_robots
        self.robot_contacts = np.zeros((n, r, r), dtype=bool)
        self.wall_contacts = np.zeros((n, r), dtype=bool)
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

    def _index_rows(self, robots: list[pymunk.Body], controls: list[pymunk.Body]) -> None:
        # pymunk.batch iterates bodies in the space's own order and adds the static body once the
        # space has stepped; map rows by id once, after a step in which nothing moves.
        self.space.step(self._sub_dt)
        self._read = pb.Buffer()
        pb.get_space_bodies(self.space, pb.BodyFields.BODY_ID, self._read)
        ids = np.frombuffer(self._read.int_buf(), dtype=np.uintp)
        row_of = {int(body_id): row for row, body_id in enumerate(ids)}
        self._rows = len(ids)
        self._robot_rows = np.array([row_of[b.id] for b in robots])
        self._control_rows = np.array([row_of[c.id] for c in controls])
        self._static_row = row_of[self.space.static_body.id]
        # Write buffers hold numpy memory; pymunk must never grow or free them, so they are only written.
        self._vel_out = np.zeros((self._rows, 3))
        self._vel_buf = pb.Buffer()
        self._vel_buf.set_float_buf(self._vel_out)
        self._state_out = np.zeros((self._rows, 6))
        self._state_buf = pb.Buffer()
        self._state_buf.set_float_buf(self._state_out)

    # -- contacts -----------------------------------------------------------------------------------------

    def _on_robot_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        a, b = arbiter.shapes
        (f, i), (_, j) = self._shape_owner[a], self._shape_owner[b]
        self.robot_contacts[f, i, j] = self.robot_contacts[f, j, i] = True

    def _on_wall_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        a, b = arbiter.shapes
        f, i = self._shape_owner[a] if a.collision_type == _ROBOT else self._shape_owner[b]
        self.wall_contacts[f, i] = True

    # -- state --------------------------------------------------------------------------------------------

    def _raw_rows(self) -> np.ndarray:
        """All bodies' (x, y, angle, vx, vy, w), one row each, in pymunk's order. Shape: (rows, 6)."""
        self._read.clear()
        pb.get_space_bodies(self.space, _STATE, self._read)
        raw = np.frombuffer(self._read.float_buf(), dtype=np.float64)
        if raw.size != self._rows * 6:
            raise RuntimeError(f"pymunk.batch returned {raw.size // 6} bodies, expected {self._rows}")
        return raw.reshape(self._rows, 6)

    def _read_state(self) -> RobotState:
        rows = self._raw_rows()[self._robot_rows].reshape(self.num_fields, self.num_robots, 6)
        return RobotState(
            pos=rows[..., 0:2] - self.offsets[:, None, :],
            angle=wrap_angle(rows[..., 2]),
            vel=rows[..., 3:5].copy(),
            ang_vel=rows[..., 5].copy(),
        )

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
        arrays = {"pos": (pos, (m, r, 2)), "angle": (angle, (m, r)), "vel": (vel, (m, r, 2)),
                  "ang_vel": (ang_vel, (m, r))}
        checked = {}
        for name, (value, shape) in arrays.items():
            value = np.asarray(value, dtype=np.float64)
            if value.shape != shape:
                raise ValueError(f"set_state: {name} has shape {value.shape}, expected {shape}")
            if not np.isfinite(value).all():
                raise ValueError(f"set_state: {name} holds NaN or infinite values")
            checked[name] = value
        if m == 0:
            return
        rows = self._raw_rows()
        out = self._state_out
        out[:] = rows
        grid = (fields[:, None] * r + np.arange(r)).reshape(-1)
        packed = np.concatenate(
            [
                (checked["pos"] + self.offsets[fields, None, :]).reshape(-1, 2),
                checked["angle"].reshape(-1, 1),
                checked["vel"].reshape(-1, 2),
                checked["ang_vel"].reshape(-1, 1),
            ],
            axis=1,
        )
        out[self._robot_rows[grid]] = packed
        out[self._control_rows[grid]] = packed
        pb.set_space_bodies(self.space, _STATE, self._state_buf)
        self.robot_contacts[fields] = False
        self.wall_contacts[fields] = False
        self.state = self._read_state()

    # -- stepping -----------------------------------------------------------------------------------------

    def step(self, command: np.ndarray) -> RobotState:
        """Advance every field by one control period.

        ``command`` (N, R, 3) is each robot's (vx, vy, w) in its own frame, m/s and rad/s. The world caps
        speed and angular speed at the robot's limits; acceleration is capped by the joints' force. After
        the call ``state`` holds the new poses and ``robot_contacts`` (N, R, R) / ``wall_contacts`` (N, R)
        tell which robots touched which robot or wall during any substep of this period.
        """
        command = np.asarray(command, dtype=np.float64)
        expected = (self.num_fields, self.num_robots, 3)
        if command.shape != expected:
            raise ValueError(f"command has shape {command.shape}, expected {expected}")
        if not np.isfinite(command).all():
            f, i = np.argwhere(~np.isfinite(command).all(axis=-1))[0]
            raise ValueError(f"command holds NaN or infinite values (field {f}, robot {i})")
        spec, state = self.robot, self.state

        target = to_field_frame(command[..., :2], state.angle)
        speed = np.sqrt(np.einsum("...i,...i->...", target, target))
        target *= np.minimum(1.0, spec.max_speed / np.maximum(speed, 1e-12))[..., None]
        spin = np.clip(command[..., 2], -spec.max_ang_speed, spec.max_ang_speed)

        out = self._vel_out
        out[self._robot_rows, :2] = self._speculative_wall_stop(state).reshape(-1, 2)
        out[self._robot_rows, 2] = state.ang_vel.reshape(-1)
        out[self._control_rows, :2] = target.reshape(-1, 2)
        out[self._control_rows, 2] = spin.reshape(-1)
        pb.set_space_bodies(self.space, _VELOCITY, self._vel_buf)

        self.robot_contacts[:] = False
        self.wall_contacts[:] = False
        for _ in range(self.substeps):
            self.space.step(self._sub_dt)
        self.state = self._read_state()
        return self.state

    def _speculative_wall_stop(self, state: RobotState) -> np.ndarray:
        """Robot velocities (N, R, 2) with the part that would carry a robot into a wall within this period
        removed: an inelastic wall impact resolved before it happens. pymunk detects contacts only after
        moving bodies, so without this a robot at 2.5 m/s would sink v * dt into a wall before the contact
        pushes back.
        """
        hx, hy = self.field.wall_half_extent
        limit = np.array([hx, hy]) - self.robot.radius
        room_hi = np.maximum(limit - state.pos, 0.0) / self.dt
        room_lo = np.maximum(limit + state.pos, 0.0) / self.dt
        return np.clip(state.vel, -room_lo, room_hi)
