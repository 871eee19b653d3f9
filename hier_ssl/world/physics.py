"""N independent SSL fields of R omnidirectional robots each, stepped together, in pymunk spaces of up to
``FIELDS_PER_SPACE`` fields (``hier_ssl.world.blocks``: one space for all would leave the cache).

Every robot is a dynamic disc driven by a control body (a static one: it has a velocity but never moves)
through a ``PivotJoint`` and a ``GearJoint`` whose ``max_bias`` is 0 and whose ``max_force`` is bounded:
the control body carries the commanded velocity, and the solver pulls the robot towards it with at most
``mass * max_accel`` of force. The acceleration limit is therefore physical, contacts win over the
motors, and robots stay out of walls and each other (overwriting a dynamic body's velocity every step
lets it tunnel through walls).

All state crosses this boundary as arrays with a leading (fields, robots) pair of axes, read and written
with ``pymunk.batch``'s iterators in one call per space each; there is no per-body Python on the hot path.
At one field a step costs numpy's and pymunk's per-call overheads rather than arithmetic: what a step
computes per robot (the commands as capped field-frame velocities, the state read back) is one compiled
loop each (``hier_ssl.world.exchange``), and the calls into pymunk are made once (``FastSpace``).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pymunk

from hier_ssl.world.ball import BallSpec, BallState
from hier_ssl.world.blocks import BALL, ROBOT, FieldBlock, block_bounds
from hier_ssl.world.checks import check_inside, check_outside_boxes, checked_arrays, checked_fields
from hier_ssl.world.entities import Entities, robots
from hier_ssl.world.exchange import ball_rows, unpack_balls, unpack_rows, velocity_rows
from hier_ssl.world.field import Field, get_field
from hier_ssl.world.frames import _COMPLEX, all_finite, as_float
from hier_ssl.world.goals import goal_boxes
from hier_ssl.world.robot import RobotSpec, RobotState
from hier_ssl.world.space import joint_impulses, set_joint_impulses

# What ``World._prepare`` makes: buffers, constants and the threads, made again for a copy.
_PREPARED = {
    "_read_rows",
    "_ball_read",
    "_ball_at",
    "_ball_limits",
    "_goal_boxes",
    "_velocity_rows",
    "_velocity_at",
    "_all_fields",
    "_shapes",
    "_block_of",
    "_limits",
    "_pool",
}


class World:
    """``num_fields`` fields holding the same ``entities`` each (``hier_ssl.world.entities``: groups of
    entities by kind, as a scenario adds them; an int is that many robots), one ``step`` for all.

    Fields are laid out on a grid, far enough apart that nothing crosses from one to another. Each kind's
    state has a leading (fields, entities of the kind) pair of axes: ``states["robot"]``, also ``state``,
    the robots' (``num_robots`` of them), and ``states["ball"]``, also ``ball``, the balls'
    (``num_balls``, ``hier_ssl.world.ball``) where the entities hold any. Which robots are controlled and
    which are obstacles is the groups' business, not the world's. A state is replaced, never modified, by
    ``step``, ``set_state`` and ``set_balls``: a state a caller keeps stays as it was. Bodies must not be
    added to or removed from the ``blocks``' spaces.

    With balls, every field also has its two goals (``hier_ssl.world.goals``): robots collide with them
    as with the walls, and the balls roll (a constant deceleration, ``BallSpec.deceleration``), bounce off
    walls, goals and robots, and are pushed by robots. Without balls, neither goals nor balls exist and a
    step is what it was before the ball.

    A world pickles and copies: the copy has the same bodies, contacts and joint impulses and steps bit
    for bit as the original while no robot touches two bodies at once. When one does, Chipmunk's broad
    phase (which nothing pickles) may list those contacts in another order, and the two differ by the
    solver's rounding (1e-8 m measured), which later contacts can grow.
    """

    def __init__(
        self,
        num_fields: int,
        entities: Entities | int,
        field: Field | str = "hardware_challenge",
        robot: RobotSpec | None = None,
        dt: float = 0.025,
        substeps: int = 2,
        iterations: int = 5,
        ball: BallSpec | None = None,
    ) -> None:
        if not (isinstance(num_fields, int | np.integer) and num_fields >= 1):
            raise ValueError(f"num_fields must be an integer >= 1, got {num_fields!r}")
        if isinstance(entities, int | np.integer) and entities >= 1:
            entities = robots(int(entities))
        elif not isinstance(entities, Entities):
            raise ValueError(f"num_robots must be an integer >= 1, got {entities!r}")
        num_robots = entities.count("robot")
        if num_robots < 1:
            raise ValueError("a world needs at least one robot in every field")
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        if not (isinstance(substeps, int) and substeps >= 1):
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.field = get_field(field) if isinstance(field, str) else field
        self.robot = robot or RobotSpec()
        self.ball_spec = ball or BallSpec()
        self.entities = entities
        self.num_fields, self.num_robots = int(num_fields), num_robots
        self.num_balls = entities.count("ball")
        self.dt, self.substeps = float(dt), substeps
        self._sub_dt = self.dt / substeps

        hx, hy = self.field.wall_half_extent
        pitch = 2 * max(hx, hy) + 2.0
        cols = int(np.ceil(np.sqrt(self.num_fields)))
        idx = np.arange(self.num_fields)
        self.offsets = np.stack([(idx % cols) * pitch, (idx // cols) * pitch], axis=-1).astype(np.float64)

        handlers = (self._on_robot_contact, self._on_wall_contact, self._on_ball_contact)
        parked = self._parking_spots()
        self.blocks = [
            FieldBlock(
                b,
                self.num_robots,
                self.offsets,
                self.field,
                self.robot,
                self._sub_dt,
                iterations,
                parked,
                handlers,
                self.num_balls,
                self.ball_spec,
            )
            for b in block_bounds(self.num_fields)
        ]
        self.threads = 1
        self._shape_owner = {shape: owner for block in self.blocks for shape, owner in block.owners.items()}
        self._joints = [joint for block in self.blocks for joint in block.joints]
        self._prepare(hx, hy)

        n, r = self.num_fields, self.num_robots
        self.robot_contacts = np.zeros((n, r, r), dtype=bool)
        self.robot_touch = np.zeros((n, r), dtype=bool)  # robot_contacts.any(axis=2), kept by the callback
        self.wall_contacts = np.zeros((n, r), dtype=bool)
        self.ball_touch = np.zeros((n, r), dtype=bool)
        self._contacts_set = False  # whether a callback has written a contact since the last clearing
        # What a ball's next read-back velocity lacks (``exchange.ball_rows``): nothing before a step.
        self._ball_delta = np.zeros((n, self.num_balls, 3))
        self.ball: BallState | None = None
        self.state = self._read_state()

    # -- construction -------------------------------------------------------------------------------------

    def _parking_spots(self) -> np.ndarray:
        """Non-overlapping start positions (R, 2) used until the first reset."""
        gap = 3 * self.robot.radius
        cols = max(1, int(self.field.field_length // gap) - 1)
        i = np.arange(self.num_robots)
        spots = np.stack([(i % cols) * gap, (i // cols) * gap], axis=-1)
        return spots - spots.mean(axis=0)

    def _prepare(self, hx: float, hy: float) -> None:
        """The read and write buffers of the hot path and its constants, made once."""
        n, r, spec = self.num_fields, self.num_robots, self.robot
        self._read_rows = np.zeros((n, r, 6))
        self._ball_read = np.zeros((n, self.num_balls, 6))
        self._ball_at = np.empty((n, self.num_balls), dtype=np.int64)
        self._all_fields, self._shapes = np.arange(n), ((n, r), (n, r, 2))
        self._block_of = [k for k, block in enumerate(self.blocks) for _ in range(block.start, block.stop)]
        # Every block's velocity rows, one after another, and where each robot's (field, robot, 0) and its
        # control body's (..., 1) row is among them: a step writes them all in one call, no copies.
        sizes = [len(block.fast.rows) for block in self.blocks]
        self._velocity_rows = np.zeros((sum(sizes), 3))
        self._velocity_at = np.empty((n, r, 2), dtype=np.int64)
        first = 0
        for block, size in zip(self.blocks, sizes, strict=True):
            reads = self._read_rows[block.fields], self._ball_read[block.fields]
            block.bind(self._velocity_rows[first : first + size], *reads)
            robot_at, control_at, ball_at = block.body_rows()
            self._velocity_at[block.fields, :, 0] = first + robot_at
            self._velocity_at[block.fields, :, 1] = first + control_at
            self._ball_at[block.fields] = first + ball_at
            first += size
        reach = (hx - spec.radius, hy - spec.radius)
        self._limits = np.array([spec.max_speed, spec.max_ang_speed, self.dt, *reach])
        ball = self.ball_spec
        ball_reach = (hx - ball.radius, hy - ball.radius)
        self._ball_limits = np.array([ball.deceleration, self.dt, *ball_reach, ball.restitution_wall])
        self._goal_boxes = goal_boxes(self.field) + np.array([-1, 1, -1, 1]) * ball.radius
        self._pool = ThreadPoolExecutor(self.threads - 1) if self.threads > 1 else None

    def use_threads(self, count: int) -> None:
        """Step the blocks in ``count`` threads from the next step on: this one and ``count`` - 1 of a pool
        (1, the default: this one alone). Chipmunk steps a space without holding Python's lock, so blocks
        step on as many cores as are free; each block's result is bit for bit the same."""
        if not (isinstance(count, int) and count >= 1):
            raise ValueError(f"count must be an integer >= 1, got {count!r}")
        if self._pool is not None:
            self._pool.shutdown()
        self.threads = count
        self._pool = ThreadPoolExecutor(count - 1) if count > 1 else None

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

    def _on_ball_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        a, b = arbiter.shapes
        f, i = self._shape_owner[b] if a.collision_type == BALL else self._shape_owner[a]
        self.ball_touch[f, i] = True
        # Without this the contact's restitution would be the product of the robot's 0 and the ball's own.
        arbiter.restitution = self.ball_spec.restitution_robot
        self._contacts_set = True

    def _on_wall_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        a, b = arbiter.shapes
        f, i = self._shape_owner[a] if a.collision_type == ROBOT else self._shape_owner[b]
        self.wall_contacts[f, i] = True
        self._contacts_set = True

    # -- state --------------------------------------------------------------------------------------------

    @property
    def states(self) -> dict[str, RobotState | BallState]:
        """Every kind's state, by kind: "robot", and "ball" where the world holds balls."""
        if self.ball is None:
            return {"robot": self.state}
        return {"robot": self.state, "ball": self.ball}

    def _read_state(self) -> RobotState:
        for block in self.blocks:
            block.read()
        if self.num_balls:
            self.ball = self._balls_of_rows()
        return self._state_of_rows()

    def _balls_of_rows(self, fields: np.ndarray | None = None) -> BallState:
        """A new ball state from the rows of the last read, of every field or of ``fields`` (F,) ints and
        the current ball state's other fields (as ``_state_of_rows``)."""
        if fields is None:
            fields, shape = self._all_fields, (self.num_fields, self.num_balls, 2)
            pos, vel = np.empty(shape), np.empty(shape)
        else:
            pos, vel = self.ball.pos.copy(), self.ball.vel.copy()
        unpack_balls(self._ball_read, self.offsets, self._ball_delta, fields, pos, vel)
        return BallState(pos, vel)

    def _state_of_rows(self, fields: np.ndarray | None = None) -> RobotState:
        """A new state from the rows of the last read (a state is replaced, never changed): of every field,
        or of ``fields`` (F,) ints and the current state's other fields (a reset unpacks its own alone)."""
        if fields is None:
            (shape, pairs), fields = self._shapes, self._all_fields
            pos, vel = np.empty(pairs), np.empty(pairs)
            angle, ang_vel, heading = np.empty(shape), np.empty(shape), np.empty(shape, dtype=_COMPLEX)
        else:
            s = self.state
            pos, angle, vel, ang_vel = s.pos.copy(), s.angle.copy(), s.vel.copy(), s.ang_vel.copy()
            heading = s.heading.copy()
        unpack_rows(self._read_rows, self.offsets, fields, pos, angle, vel, ang_vel, heading)
        return RobotState(pos, angle, vel, ang_vel, heading)

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
        fields = checked_fields(fields, self.num_fields)
        m, r = len(fields), self.num_robots
        vel = np.zeros((m, r, 2)) if vel is None else vel
        ang_vel = np.zeros((m, r)) if ang_vel is None else ang_vel
        arrays = {
            "pos": (pos, (m, r, 2)),
            "angle": (angle, (m, r)),
            "vel": (vel, (m, r, 2)),
            "ang_vel": (ang_vel, (m, r)),
        }
        checked = checked_arrays("set_state", "robot", fields, arrays)
        check_inside("set_state", "robot", fields, checked["pos"], self._limits[3:5])
        if m == 0:
            return
        packed = np.concatenate(
            [
                checked["pos"] + self.offsets[fields, None, :],
                checked["angle"][..., None],
                checked["vel"],
                checked["ang_vel"][..., None],
            ],
            axis=-1,
        )
        # Each field's bodies are set and read back alone: the other rows are those of their last read.
        for f, rows in zip(fields.tolist(), packed, strict=True):
            self._read_rows[f] = self.blocks[self._block_of[f]].place(f, rows)
        self.robot_contacts[fields] = False
        self.robot_touch[fields] = False
        self.wall_contacts[fields] = False
        self.ball_touch[fields] = False
        self.state = self._state_of_rows(fields)

    def set_balls(
        self, fields: np.ndarray | list[int], pos: np.ndarray, vel: np.ndarray | None = None
    ) -> None:
        """Place every ball of the given fields; balls of other fields are untouched.

        Shapes: fields (F,) ints; pos (F, B, 2) m and vel (F, B, 2) m/s, field frame, at rest if None.
        """
        if self.ball is None:
            raise ValueError("set_balls: this world holds no balls (its entities add none)")
        fields = checked_fields(fields, self.num_fields)
        shape = (len(fields), self.num_balls, 2)
        vel = np.zeros(shape) if vel is None else vel
        checked = checked_arrays("set_balls", "ball", fields, {"pos": (pos, shape), "vel": (vel, shape)})
        check_inside("set_balls", "ball", fields, checked["pos"], self._ball_limits[2:4])
        check_outside_boxes("set_balls", "ball", fields, checked["pos"], self._goal_boxes)
        rows = np.concatenate([checked["pos"] + self.offsets[fields, None, :], checked["vel"]], axis=-1)
        for f, field_rows in zip(fields.tolist(), rows, strict=True):
            self._ball_read[f] = self.blocks[self._block_of[f]].place_balls(f, field_rows)
        self._ball_delta[fields] = 0.0
        self.ball = self._balls_of_rows(fields)

    # -- stepping -----------------------------------------------------------------------------------------

    def step(self, command: np.ndarray) -> RobotState:
        """Advance every field by one control period.

        ``command`` (N, R, 3) is each robot's (vx, vy, w) in its own frame, m/s and rad/s. The world caps
        speed and angular speed at the robot's limits; acceleration is capped by the joints' force. After
        the call ``state`` holds the new poses and ``robot_contacts`` (N, R, R) / ``wall_contacts`` (N, R)
        tell which robots touched which robot or wall (a goal wall included) during any substep of this
        period, ``robot_touch`` (N, R) which touched any robot and ``ball_touch`` (N, R) which touched a
        ball; ``ball`` holds the balls' new positions and velocities.
        """
        command = as_float(command)
        expected = (self.num_fields, self.num_robots, 3)
        if command.shape != expected:
            raise ValueError(f"command has shape {command.shape}, expected {expected}")
        if not all_finite(command):
            f, i = np.argwhere(~np.isfinite(command).all(axis=-1))[0]
            raise ValueError(f"command holds NaN or infinite values (field {f}, robot {i})")
        state = self.state
        at, rows = self._velocity_at, self._velocity_rows
        velocity_rows(command, state.heading, state.pos, state.vel, state.ang_vel, self._limits, at, rows)
        if self.ball is not None:
            ball = self.ball
            ball_rows(
                ball.pos, ball.vel, self._ball_limits, self._goal_boxes, self._ball_at, rows, self._ball_delta
            )
        if self._contacts_set:
            self.robot_contacts.fill(False)
            self.robot_touch.fill(False)
            self.wall_contacts.fill(False)
            self.ball_touch.fill(False)
            self._contacts_set = False
        if self._pool is None:
            self._advance(self.blocks)
        else:
            # Every thread takes every ``threads``-th block; the contact callbacks of different blocks
            # write different fields' rows.
            groups = [self.blocks[k :: self.threads] for k in range(self.threads)]
            others = [self._pool.submit(self._advance, group) for group in groups[1:]]
            self._advance(groups[0])
            for other in others:
                other.result()
        self.state = self._state_of_rows()
        if self.ball is not None:
            self.ball = self._balls_of_rows()
        return self.state

    def _advance(self, blocks: list[FieldBlock]) -> None:
        """Write the velocity rows into ``blocks``, step them and read them back, one after another."""
        for block in blocks:
            block.step(self._sub_dt, self.substeps)
