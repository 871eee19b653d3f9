"""A World's fields in blocks, each block its own pymunk space: the bodies, shapes and joints of a block,
and its batched reads and writes.

Chipmunk's solver sweeps every joint and contact of a space once per iteration (five per substep), each
touching two bodies. Past a few hundred fields those no longer fit in a core's cache and every sweep
reads main memory: one space of 4096 three-robot fields stepped 20x slower than 1024 (measured), where
64 spaces of 64 fields step 4096 fields in 4x the time of 1024. Fields share nothing, so a field steps as
it would in a space of its own, except that Chipmunk's broad phase may list the contacts of a robot
touching two bodies at once in another order (the solver's rounding, 1e-8 m).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pymunk
import pymunk.batch as pb

from hier_ssl.world.ball import BallSpec
from hier_ssl.world.field import Field
from hier_ssl.world.goals import box_corners, goal_boxes
from hier_ssl.world.robot import RobotSpec
from hier_ssl.world.space import FastSpace

# Collision types: goal walls are WALL too, so that a robot's contact with a goal is a wall contact.
ROBOT, WALL, BALL = 1, 2, 3
# Fields per pymunk space: a block's bodies and joints stay in a core's cache through the solver's sweeps.
FIELDS_PER_SPACE = 64
# Wall segments are centred this far outside the wall line, so their surface lies on it.
_WALL_RADIUS = 0.01
_VELOCITY = pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY
_STATE = pb.BodyFields.POSITION | pb.BodyFields.ANGLE | _VELOCITY
# What ``FieldBlock._prepare`` makes: cffi call data and views of pymunk's memory, made again for a copy.
_PREPARED = {
    "_controls_at",
    "fast",
    "robot_rows",
    "ball_rows",
    "write_velocity",
    "read_rows",
    "ball_read",
}
Handler = Callable[[pymunk.Arbiter, pymunk.Space, object], None]


def block_bounds(num_fields: int) -> list[tuple[int, int]]:
    """The (start, stop) field ranges of the blocks of ``num_fields`` fields: as few as
    ``FIELDS_PER_SPACE`` allows, of sizes differing by one at most."""
    count = -(-num_fields // FIELDS_PER_SPACE)
    edges = [round(k * num_fields / count) for k in range(count + 1)]
    return list(zip(edges[:-1], edges[1:], strict=True))


def block_groups(num_fields: int, size: int) -> list[tuple[int, int]]:
    """The (start, stop) field ranges of ``block_bounds(num_fields)``'s blocks taken ``size`` at a time (the
    last group may hold fewer)."""
    blocks = block_bounds(num_fields)
    return [(blocks[k][0], blocks[min(k + size, len(blocks)) - 1][1]) for k in range(0, len(blocks), size)]


def _wall_ends(offset: np.ndarray, wx: float, wy: float) -> list[tuple[tuple[float, float], ...]]:
    """The (start, end) points of a field's four wall segments around ``offset`` (2,), half extents wx, wy."""
    ox, oy = offset
    corners = [(ox - wx, oy - wy), (ox + wx, oy - wy), (ox + wx, oy + wy), (ox - wx, oy + wy)]
    return list(zip(corners, corners[1:] + corners[:1], strict=True))


class FieldBlock:
    """Fields ``start`` to ``stop`` - 1 of a World, ``num_robots`` robots each, in a pymunk space of theirs.

    Bodies sit at the World's field ``offsets`` (F, 2), so a field's coordinates and their rounding do
    not depend on its block. ``owners`` maps each shape to its (field, robot) index in the World, robot -1
    for walls and goal walls, (field, ball) for a ball; ``joints`` lists the block's joints. After
    ``fast.read()``, ``robot_rows`` (C, R, 6) holds each robot's x, y, angle, vx, vy, w. ``step`` writes
    the velocity rows the World gave ``bind``, at the rows ``body_rows()`` names, and reads into its read
    rows; ``place`` sets a field's bodies, ``place_balls`` its balls.

    With ``num_balls`` balls in every field (of ``ball``'s spec), every field also gets its two goals
    (``hier_ssl.world.goals``) and its balls, whose rows ``ball_rows`` (C, B, 6) are read like the
    robots'; ``handlers`` then has a third entry, called on robot-ball contacts.
    """

    def __init__(
        self,
        bounds: tuple[int, int],
        num_robots: int,
        offsets: np.ndarray,
        field: Field,
        robot: RobotSpec,
        sub_dt: float,
        iterations: int,
        parked: np.ndarray,
        handlers: tuple[Handler, ...],
        num_balls: int = 0,
        ball: BallSpec | None = None,
    ) -> None:
        self.start, self.stop = bounds
        self.fields, self.num_robots = slice(self.start, self.stop), num_robots
        self.num_balls = num_balls
        self.space = pymunk.Space()
        self.space.iterations = iterations
        # Units are metres: pymunk's default slop (0.1) would allow 10 cm of overlap.
        self.space.collision_slop = 5e-4
        # Push half of any remaining overlap out per substep (pymunk's default leaves ~92 %).
        self.space.collision_bias = 0.5 ** (1.0 / sub_dt)
        self.owners: dict[pymunk.Shape, tuple[int, int]] = {}
        self.joints: list[pymunk.Constraint] = []
        self._bodies = self._build(offsets, field, robot, parked)
        self._balls = self._build_balls(offsets, field, ball or BallSpec()) if num_balls else []
        # pymunk.batch lists the space's static body once the space has stepped.
        self.space.step(sub_dt)
        self.space.on_collision(ROBOT, ROBOT, pre_solve=handlers[0])
        self.space.on_collision(ROBOT, WALL, pre_solve=handlers[1])
        if num_balls:
            self.space.on_collision(ROBOT, BALL, pre_solve=handlers[2])
        self._prepare()

    def _build(
        self, offsets: np.ndarray, field: Field, spec: RobotSpec, parked: np.ndarray
    ) -> tuple[list[pymunk.Body], list[pymunk.Body]]:
        moment = pymunk.moment_for_circle(spec.mass, 0, spec.radius)
        wx, wy = np.array(field.wall_half_extent) + _WALL_RADIUS
        fields, count = range(self.start, self.stop), (self.stop - self.start) * self.num_robots
        # Each kind of Chipmunk object is allocated in one run, so that the solver's sweeps over bodies,
        # shapes and joints read consecutive memory. What fixes every result is the order of adding them to
        # the space, not of allocating: still a field's walls, then each robot's body, disc, control, joints.
        walls = [
            pymunk.Segment(self.space.static_body, a, b, _WALL_RADIUS)
            for f in fields
            for a, b in _wall_ends(offsets[f], wx, wy)
        ]
        robots = [pymunk.Body(spec.mass, moment) for _ in range(count)]
        discs = [pymunk.Circle(body, spec.radius) for body in robots]
        # Static bodies: Chipmunk's joints act on any body's velocity, but it moves (a sine and a cosine
        # each substep) only dynamic and kinematic ones; a control body's pose is never read.
        controls = [pymunk.Body(body_type=pymunk.Body.STATIC) for _ in range(count)]
        pivots = [pymunk.PivotJoint(c, b, (0, 0), (0, 0)) for c, b in zip(controls, robots, strict=True)]
        gears = [pymunk.GearJoint(c, b, 0.0, 1.0) for c, b in zip(controls, robots, strict=True)]
        for k, f in enumerate(fields):
            for wall in walls[4 * k : 4 * k + 4]:
                # Elasticity 1: a contact's restitution is the product of its shapes', the robots' 0 and the
                # ball's own (``_build_balls``).
                wall.collision_type, wall.friction, wall.elasticity = WALL, 0.2, 1.0
                self.space.add(wall)
                self.owners[wall] = (f, -1)
            for i in range(self.num_robots):
                j = k * self.num_robots + i
                body, disc, control, pivot, gear = robots[j], discs[j], controls[j], pivots[j], gears[j]
                body.position = control.position = tuple(offsets[f] + parked[i])
                disc.collision_type, disc.friction, disc.elasticity = ROBOT, 0.2, 0.0
                pivot.max_bias, pivot.max_force = 0.0, spec.mass * spec.max_accel
                gear.max_bias, gear.max_force = 0.0, moment * spec.max_ang_accel
                # max_bias 0 clamps the joints' position bias to zero; error_bias 0 makes it zero before
                # the clamp, with the same signs, and spares a pow per joint and substep.
                pivot.error_bias = gear.error_bias = 0.0
                self.space.add(body, disc, control, pivot, gear)
                self.joints += [pivot, gear]
                self.owners[disc] = (f, i)
        return robots, controls

    def _build_balls(self, offsets: np.ndarray, field: Field, spec: BallSpec) -> list[pymunk.Body]:
        """Each field's goals and balls, added after every robot: pymunk.batch then lists the balls (dynamic)
        right after the robots, so that both are strided views of its rows."""
        boxes = goal_boxes(field)
        # Until the first reset the balls wait on a touch line, clear of the robots parked at the centre.
        spots = np.stack(
            [4 * spec.radius * np.arange(self.num_balls), np.full(self.num_balls, field.half_width)], -1
        )
        balls = []
        for f in range(self.start, self.stop):
            for box in boxes:
                goal = pymunk.Poly(self.space.static_body, [tuple(offsets[f] + c) for c in box_corners(box)])
                goal.collision_type, goal.friction, goal.elasticity = WALL, 0.2, 1.0
                self.space.add(goal)
                self.owners[goal] = (f, -1)
            for b in range(self.num_balls):
                # No rotation: a rolling disc whose spin nothing reads, with frictionless contacts.
                body = pymunk.Body(spec.mass, float("inf"))
                body.position = tuple(offsets[f] + spots[b])
                disc = pymunk.Circle(body, spec.radius)
                disc.collision_type, disc.friction, disc.elasticity = BALL, 0.0, spec.restitution_wall
                self.space.add(body, disc)
                self.owners[disc] = (f, b)
                balls.append(body)
        return balls

    def _body_order(self) -> int:
        """The row of the first control body. pymunk.batch lists the robots (dynamic) in insertion order,
        then the balls (dynamic too), then the static bodies: the space's own (first once a wall is added,
        last in a copy) and the control bodies in insertion order. Checked whenever the views are made, so
        that every per-step access is a strided view instead of a gather through index arrays."""
        ids = pb.Buffer()
        pb.get_space_bodies(self.space, pb.BodyFields.BODY_ID, ids)
        order = np.frombuffer(ids.int_buf(), dtype=np.uintp).tolist()
        robots, controls = ([body.id for body in group] for group in self._bodies)
        robots += [body.id for body in self._balls]
        static, n = self.space.static_body.id, len(robots)
        if order[:n] != robots or order[n:] not in ([static, *controls], [*controls, static]):
            raise RuntimeError(
                f"pymunk {pymunk.version} lists bodies in an unexpected order; this World needs "
                "pymunk.batch to return the robots, then the static bodies in insertion order"
            )
        return n + 1 if order[n] == static else n

    def _pairs(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, W) body rows as three views: the robots' and their control bodies' (C, R, W), the balls'
        (C, B, W)."""
        c, r, b, w = self.stop - self.start, self.num_robots, self.num_balls, rows.shape[-1]
        at = self._controls_at
        robots, controls = rows[: c * r].reshape(c, r, w), rows[at : at + c * r].reshape(c, r, w)
        return robots, controls, rows[c * r : c * (r + b)].reshape(c, b, w)

    def _prepare(self) -> None:
        self._controls_at = self._body_order()
        self.fast = FastSpace(self.space, _STATE, 6)
        self.robot_rows, _, self.ball_rows = self._pairs(self.fast.rows)

    def __getstate__(self) -> dict[str, object]:
        # pymunk pickles the space, contact cache and handlers included.
        return {k: v for k, v in self.__dict__.items() if k not in _PREPARED}

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self._prepare()

    def body_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The rows among the block's bodies, int64, of the robots and of their control bodies (C, R), and
        of the balls (C, B)."""
        rows = np.arange(len(self.fast.rows), dtype=np.int64)[:, None]
        robots, controls, balls = self._pairs(rows)
        return robots[..., 0], controls[..., 0], balls[..., 0]

    def bind(self, velocity: np.ndarray, read: np.ndarray, ball_read: np.ndarray) -> None:
        """Make ``step`` write ``velocity`` (bodies, 3) float64, C-contiguous, (vx, vy, w) a body
        (``body_rows`` says whose), into the block's bodies and read each robot's x, y, angle, vx, vy, w
        back into ``read`` (C, R, 6), each ball's into ``ball_read`` (C, B, 6). The World fills the velocity
        rows in place, one compiled loop for all blocks. The static body's row must stay zero: a velocity
        written there throws robots out of their fields."""
        self.write_velocity, self.read_rows = self.fast.writer(_VELOCITY, velocity), read
        self.ball_read = ball_read

    def step(self, dt: float, substeps: int) -> None:
        """Write the bound velocity rows, step ``substeps`` times ``dt`` and read the robots back right
        after, while the block's bodies are still in cache."""
        self.write_velocity()
        self.fast.step(dt, substeps)
        self.read()

    def read(self) -> None:
        """Copy each robot's and each ball's x, y, angle, vx, vy, w into the bound read rows."""
        self.fast.read()
        self.read_rows[...] = self.robot_rows
        if self.num_balls:
            self.ball_read[...] = self.ball_rows

    def place(self, field: int, rows: np.ndarray) -> np.ndarray:
        """Write ``rows`` (R, 6), x, y, angle, vx, vy, w, into the robots and control bodies of the World's
        ``field`` (one of this block's), body by body: a reset touches its own bodies alone, where a batched
        write would pass every body of the block twice (in and back out). Returns the robots' rows (R, 6)
        as pymunk reads them back."""
        robots, controls = self._bodies
        first = (field - self.start) * self.num_robots
        out = np.empty((self.num_robots, 6))
        lib = pb.lib  # Chipmunk's own setters and getters, those of pymunk's properties and batches
        for i, (x, y, angle, vx, vy, w) in enumerate(rows.tolist()):
            robot = robots[first + i]._body
            for body in (robot, controls[first + i]._body):
                lib.cpBodySetPosition(body, (x, y))
                lib.cpBodySetAngle(body, angle)
                lib.cpBodySetVelocity(body, (vx, vy))
                lib.cpBodySetAngularVelocity(body, w)
            position, velocity = lib.cpBodyGetPosition(robot), lib.cpBodyGetVelocity(robot)
            spin = lib.cpBodyGetAngularVelocity(robot)
            out[i] = position.x, position.y, lib.cpBodyGetAngle(robot), velocity.x, velocity.y, spin
        return out

    def place_balls(self, field: int, rows: np.ndarray) -> np.ndarray:
        """Write ``rows`` (B, 4), x, y, vx, vy, into the balls of the World's ``field`` (one of this block's),
        ball by ball as ``place`` does; their rows (B, 6) as pymunk reads them back."""
        first = (field - self.start) * self.num_balls
        out = np.zeros((self.num_balls, 6))
        lib = pb.lib
        for b, (x, y, vx, vy) in enumerate(rows.tolist()):
            body = self._balls[first + b]._body
            lib.cpBodySetPosition(body, (x, y))
            lib.cpBodySetVelocity(body, (vx, vy))
            position, velocity = lib.cpBodyGetPosition(body), lib.cpBodyGetVelocity(body)
            out[b, [0, 1, 3, 4]] = position.x, position.y, velocity.x, velocity.y
        return out
