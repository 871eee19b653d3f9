from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pymunk
import pytest

from hier_ssl.worker.scripted import PaperGoToPoint
from hier_ssl.world.frames import as_complex, heading, to_field_frame, to_robot_frame, wrap_angle
from hier_ssl.world.obstacles import make_obstacle
from hier_ssl.world.physics import RobotSpec, RobotState, World
from hier_ssl.world.space import joint_impulses, set_joint_impulses

SPEC = RobotSpec()
DT = 0.025


def _world(num_fields: int = 1, num_robots: int = 1, **options: object) -> World:
    return World(num_fields, num_robots, **options)


def _limit(world: World) -> np.ndarray:
    """Largest |x|, |y| a robot centre can have without touching a wall. Shape (2,)."""
    return np.array(world.field.wall_half_extent) - world.robot.radius


def _place(world: World, pos: list, angle: list | None = None) -> None:
    """Every field placed, robots at rest: pos (N, R, 2), angle (N, R)."""
    pos = np.asarray(pos, dtype=float)
    angle = np.zeros(pos.shape[:2]) if angle is None else np.asarray(angle, dtype=float)
    world.set_state(np.arange(world.num_fields), pos, angle)


# -- frame helpers --------------------------------------------------------------------------------------


def test_frames_rotate_by_the_heading_and_back() -> None:
    quarter = np.array([np.pi / 2])
    np.testing.assert_allclose(to_robot_frame(np.array([[1.0, 0.0]]), quarter), [[0.0, -1.0]], atol=1e-15)
    np.testing.assert_allclose(to_field_frame(np.array([[1.0, 0.0]]), quarter), [[0.0, 1.0]], atol=1e-15)
    rng = np.random.default_rng(0)
    vec, angle = rng.normal(size=(5, 3, 2)), rng.uniform(-7, 7, (5, 3))
    np.testing.assert_allclose(to_field_frame(to_robot_frame(vec, angle), angle), vec, atol=1e-14)
    np.testing.assert_allclose(heading(angle), np.cos(angle) + 1j * np.sin(angle), atol=1e-15)


def test_wrap_angle_maps_to_half_open_interval() -> None:
    wrapped = wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi / 2, -7.0, 0.25]))
    np.testing.assert_allclose(wrapped, [-np.pi, -np.pi, -np.pi / 2, -7.0 + 2 * np.pi, 0.25])


def test_as_complex_views_float_pairs_and_copies_anything_else() -> None:
    pairs = np.arange(12.0).reshape(2, 3, 2)
    view = as_complex(pairs)
    assert view.shape == (2, 3) and np.shares_memory(view, pairs)
    view[0, 0] = 7 + 8j
    np.testing.assert_array_equal(pairs[0, 0], [7.0, 8.0])
    np.testing.assert_array_equal(as_complex(pairs[..., ::-1]), pairs[..., 1] + 1j * pairs[..., 0])
    assert as_complex([[1, 2]]).tolist() == [1 + 2j]
    with pytest.raises(ValueError, match=r"\(2, 4\)"):
        as_complex(np.zeros((2, 4)))


# -- limits ---------------------------------------------------------------------------------------------


def test_speed_and_acceleration_limits_hold_every_step() -> None:
    # Fields 0-3 are driven along x at twice the speed limit and then back; fields 4-7 spin at three
    # times the spin limit and then back. Nothing reaches a wall.
    world = _world(8)
    start = np.zeros((8, 1, 2))
    start[:4, 0, 0] = -3.0
    _place(world, start)
    command = np.zeros((8, 1, 3))
    speeds, spins = [], []
    prev = world.state
    for t in range(120):
        sign = 1.0 if t < 60 else -1.0
        command[:4, 0, 0] = sign * 2 * SPEC.max_speed
        command[4:, 0, 2] = sign * 3 * SPEC.max_ang_speed
        state = world.step(command)
        dv = np.linalg.norm(state.vel - prev.vel, axis=-1)
        dw = np.abs(state.ang_vel - prev.ang_vel)
        assert dv.max() <= SPEC.max_accel * DT + 1e-9, t
        assert dw.max() <= SPEC.max_ang_accel * DT + 1e-9, t
        speeds.append(np.linalg.norm(state.vel, axis=-1).max())
        spins.append(np.abs(state.ang_vel).max())
        prev = state
    assert max(speeds) <= SPEC.max_speed + 1e-9 and max(speeds) > SPEC.max_speed - 1e-3
    assert max(spins) <= SPEC.max_ang_speed + 1e-9 and max(spins) > SPEC.max_ang_speed - 1e-3


@pytest.mark.parametrize("direction", [0.0, 0.5 * np.pi, np.pi, -0.5 * np.pi, 0.25 * np.pi])
def test_head_on_at_full_speed_never_sinks_into_a_wall(direction: float) -> None:
    # Forward in the robot's frame, facing the wall (the last case drives into a corner).
    world = _world()
    _place(world, [[[0.0, 0.0]]], [[direction]])
    limit = _limit(world)
    command = np.array([[[SPEC.max_speed, 0.0, 0.0]]])
    top_speed = 0.0
    for _ in range(160):
        state = world.step(command)
        assert np.all(np.abs(state.pos[0, 0]) <= limit + 0.01), state.pos[0, 0]
        top_speed = max(top_speed, float(np.linalg.norm(state.vel[0, 0])))
    assert top_speed > SPEC.max_speed - 0.01
    assert np.abs(state.pos[0, 0]).max() > limit.min() - 0.02  # it did arrive at the wall


def test_robots_never_leave_their_field_under_random_commands() -> None:
    rng = np.random.default_rng(1)
    world = _world(64, 3)
    limit = _limit(world)
    _place(world, rng.uniform(-limit + 0.3, limit - 0.3, (64, 3, 2)), rng.uniform(-np.pi, np.pi, (64, 3)))
    for _ in range(150):
        state = world.step(rng.uniform(-4.0, 4.0, (64, 3, 3)))
        assert np.all(np.abs(state.pos) <= limit + 0.01)


# -- contacts -------------------------------------------------------------------------------------------


def test_robot_contacts_are_reported_both_ways_and_cleared_when_apart() -> None:
    world = _world(2, 2)
    _place(world, [[[-0.4, 0.0], [0.4, 0.0]], [[-1.0, 1.0], [1.0, 1.0]]])
    towards = np.array([[[1.0, 0, 0], [-1.0, 0, 0]], [[0, 0, 0], [0, 0, 0]]])
    touched = False
    for _ in range(40):
        world.step(towards)
        touched |= bool(world.robot_contacts[0, 0, 1])
        np.testing.assert_array_equal(world.robot_touch, world.robot_contacts.any(axis=2))
    assert touched
    assert world.robot_contacts[0, 0, 1] and world.robot_contacts[0, 1, 0]  # still pressing together
    assert not world.robot_contacts[0, 0, 0] and not world.robot_contacts[1].any()
    assert world.robot_touch.tolist() == [[True, True], [False, False]]
    assert not world.wall_contacts.any()
    for _ in range(20):
        world.step(-towards)
    assert not world.robot_contacts.any() and not world.robot_touch.any()


def test_wall_contacts_are_reported_and_cleared_when_apart() -> None:
    world = _world(1, 2)
    x = _limit(world)[0] - 0.05
    _place(world, [[[x, 0.0], [0.0, 0.0]]])
    command = np.zeros((1, 2, 3))
    command[0, 0, 0] = 1.0
    for _ in range(10):
        world.step(command)
    assert world.wall_contacts.tolist() == [[True, False]]
    assert not world.robot_contacts.any()
    for _ in range(10):
        world.step(-command)
    assert not world.wall_contacts.any()


def test_set_state_clears_contacts_of_the_placed_fields() -> None:
    world = _world(1, 2)
    _place(world, [[[_limit(world)[0], 0.0], [0.0, 0.0]]])
    world.step(np.array([[[1.0, 0, 0], [0, 0, 0]]]))
    assert world.wall_contacts[0, 0]
    _place(world, [[[0.0, 0.0], [1.0, 0.0]]])
    assert not world.wall_contacts.any()


# -- state, seeding -------------------------------------------------------------------------------------


def test_set_state_places_robots_in_the_field_frame_and_leaves_other_fields() -> None:
    world = _world(3, 2)
    before = world.state
    pos = np.array([[[1.0, -0.5], [-2.0, 1.5]]])
    world.set_state([1], pos, [[0.5, -3.0]], vel=[[[0.1, 0.2], [0.0, 0.0]]], ang_vel=[[1.0, 0.0]])
    state = world.state
    np.testing.assert_allclose(state.pos[1], pos[0], atol=1e-12)
    np.testing.assert_allclose(state.angle[1], [0.5, -3.0], atol=1e-12)
    np.testing.assert_allclose(state.vel[1, 0], [0.1, 0.2], atol=1e-12)
    for f in (0, 2):
        np.testing.assert_array_equal(state.pos[f], before.pos[f])


def test_a_reset_of_a_few_fields_leaves_the_state_a_full_read_gives() -> None:
    # set_state writes the placed fields' bodies alone and unpacks their rows alone (three blocks here):
    # what it leaves must be what reading every body of every block gives, bit for bit.
    world, rng = _world(150, 3), np.random.default_rng(4)
    assert len(world.blocks) == 3
    for _ in range(20):
        world.step(rng.uniform(-2, 2, (150, 3, 3)))
    fields = np.array([3, 70, 71, 149])
    pos = rng.uniform(-1, 1, (4, 3, 2)) + np.arange(3)[:, None] * 0.5
    world.set_state(
        fields, pos, rng.uniform(-3, 3, (4, 3)), rng.normal(0, 1, (4, 3, 2)), rng.normal(0, 1, (4, 3))
    )
    kept, read = world.state, world._read_state()
    for name in ("pos", "angle", "vel", "ang_vel", "heading"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(read, name), err_msg=name)
    world.step(rng.uniform(-2, 2, (150, 3, 3)))  # and the next step starts from it
    assert np.isfinite(world.state.pos).all()


def test_a_kept_state_is_never_modified_by_later_steps() -> None:
    world = _world(2, 2)
    kept = world.state
    copy = kept.copy()
    world.step(np.ones((2, 2, 3)))
    assert world.state is not kept
    for name in ("pos", "angle", "vel", "ang_vel"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(copy, name))


def _rollout(seed: int, steps: int = 80) -> list[np.ndarray]:
    """Robot 0 on the paper worker, robot 1 a random walk, robot 2 the public code's obstacle."""
    rng = np.random.default_rng(seed)
    n = 4
    world = _world(n, 3)
    limit = _limit(world) - 0.3
    world.set_state(np.arange(n), rng.uniform(-limit, limit, (n, 3, 2)), rng.uniform(-np.pi, np.pi, (n, 3)))
    walk, public = make_obstacle("random_walk", n), make_obstacle("public_code", n)
    public.reset(np.arange(n), rng)
    worker = PaperGoToPoint()
    subgoal = np.concatenate([rng.uniform(-limit, limit, (n, 1, 2)), np.zeros((n, 1, 3))], axis=-1)
    command = np.zeros((n, 3, 3))
    out = []
    for _ in range(steps):
        s = world.state
        command[:, 0:1] = worker(s.robots(slice(0, 1)), subgoal)
        command[:, 1] = walk(s.pos[:, 1], s.angle[:, 1], rng)
        command[:, 2] = public(s.pos[:, 2], s.angle[:, 2], rng)
        s = world.step(command)
        out += [s.pos, s.angle, s.vel, s.ang_vel, world.robot_contacts.copy(), world.wall_contacts.copy()]
    return out


def test_same_seed_gives_bit_identical_trajectories() -> None:
    first, second, other = _rollout(7), _rollout(7), _rollout(8)
    assert all(np.array_equal(a, b) for a, b in zip(first, second, strict=True))
    assert not np.array_equal(first[-4], other[-4])


# -- bad input ------------------------------------------------------------------------------------------


def _with(array: np.ndarray, index: tuple[int, ...], value: float) -> np.ndarray:
    array[index] = value
    return array


def _snapshot(world: World) -> list[np.ndarray]:
    s = world.state
    return [s.pos.copy(), s.angle.copy(), s.vel.copy(), s.ang_vel.copy()]


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda w: w.step(np.zeros((2, 2, 2))), r"command has shape \(2, 2, 2\), expected \(2, 2, 3\)"),
        (lambda w: w.step(np.zeros((2, 3))), r"shape \(2, 3\)"),
        (lambda w: w.step(_with(np.zeros((2, 2, 3)), (1, 0, 1), np.nan)), r"NaN.*field 1, robot 0"),
        (lambda w: w.step(_with(np.zeros((2, 2, 3)), (0, 1, 2), -np.inf)), r"infinite.*field 0, robot 1"),
        (lambda w: w.set_state([2], np.zeros((1, 2, 2)), np.zeros((1, 2))), r"index \[2\] out of range"),
        (lambda w: w.set_state([0, -1], np.zeros((2, 2, 2)), np.zeros((2, 2))), r"field index \[-1\]"),
        (lambda w: w.set_state([0], np.zeros((1, 3, 2)), np.zeros((1, 2))), r"pos has shape \(1, 3, 2\)"),
        (lambda w: w.set_state([0], np.full((1, 2, 2), np.nan), np.zeros((1, 2))), r"pos holds NaN"),
        (lambda w: w.set_state([0], np.zeros((1, 2, 2)), np.zeros((1, 2)), vel=np.zeros(3)), "vel has shape"),
        (lambda w: w.set_state([1], np.full((1, 2, 2), 3.5), np.zeros((1, 2))), r"robot 0 of field 1"),
    ],
)
def test_bad_input_raises_naming_the_value_and_leaves_the_world_unchanged(call: object, message: str) -> None:
    world, twin = _world(2, 2), _world(2, 2)
    for w in (world, twin):
        _place(w, [[[0.0, 0.0], [1.0, 0.0]], [[-1.0, 0.5], [0.5, -0.5]]])
        w.step(np.full((2, 2, 3), 0.5))
    before = _snapshot(world)
    with pytest.raises(ValueError, match=message):
        call(world)
    assert all(np.array_equal(a, b) for a, b in zip(before, _snapshot(world), strict=True))
    # The next step is the one a world that never saw the bad call takes.
    command = np.full((2, 2, 3), -0.3)
    world.step(command)
    twin.step(command)
    assert all(np.array_equal(a, b) for a, b in zip(_snapshot(twin), _snapshot(world), strict=True))


def test_bad_construction_raises_naming_the_value() -> None:
    with pytest.raises(ValueError, match="unknown field preset 'division_c'"):
        World(1, 1, field="division_c")
    with pytest.raises(ValueError, match="num_fields must be an integer >= 1, got 0"):
        World(0, 1)
    with pytest.raises(ValueError, match="substeps"):
        World(1, 1, substeps=0)
    with pytest.raises(ValueError, match=r"RobotSpec.max_speed must be > 0, got -1"):
        RobotSpec(max_speed=-1)


def test_adding_bodies_behind_the_worlds_back_is_refused() -> None:
    world = _world(1, 1)
    world.blocks[0].space.add(pymunk.Body(1.0, 1.0))
    with pytest.raises(RuntimeError, match="added to or removed"):
        world.step(np.zeros((1, 1, 3)))


def test_division_presets_build_and_step() -> None:
    for name in ("division_a", "division_b"):
        world = World(2, 2, field=name)
        reach = world.field.half_length + world.field.boundary_width - SPEC.radius
        assert math.isclose(_limit(world)[0], reach)
        world.step(np.ones((2, 2, 3)))


def test_the_state_carries_the_heading_the_world_computed_bit_for_bit() -> None:
    world = _world(2, 3)
    rng = np.random.default_rng(5)
    _place(world, rng.uniform(-1, 1, (2, 3, 2)), rng.uniform(-3, 3, (2, 3)))
    world.step(rng.uniform(-1, 1, (2, 3, 3)))
    state = world.state
    np.testing.assert_array_equal(state.heading, heading(state.angle))
    np.testing.assert_array_equal(state.robots(slice(1, 3)).heading, heading(state.angle[:, 1:3]))
    np.testing.assert_array_equal(state.fields(np.array([1])).heading, heading(state.angle[[1]]))
    # A state made by hand computes it on first use.
    made = RobotState(state.pos, state.angle, state.vel, state.ang_vel)
    np.testing.assert_array_equal(made.heading, state.heading)


# -- pickling and copying -------------------------------------------------------------------------------


@pytest.mark.parametrize("copy_world", [lambda w: pickle.loads(pickle.dumps(w)), copy.deepcopy])
def test_a_copied_world_steps_bit_for_bit_as_its_original(copy_world) -> None:
    # Field 0: two robots pushing into each other; field 1: one robot pressing into a wall. The copy is
    # taken mid-contact, joints at their force limit: contact cache and joint impulses both matter.
    world = _world(2, 2)
    _place(world, [[[-0.3, 0.0], [0.3, 0.0]], [[0.0, 0.0], [-_limit(world)[0] + 0.3, 1.0]]])
    command = np.zeros((2, 2, 3))
    command[0, :, 0] = SPEC.max_speed
    command[0, 1, 2] = SPEC.max_ang_speed
    command[1, 1, 0] = -SPEC.max_speed
    world.set_state([0], world.state.pos[:1], np.array([[0.0, np.pi]]))
    for _ in range(20):
        world.step(command)
    assert world.robot_contacts[0, 0, 1] and world.wall_contacts[1, 1]
    copied = copy_world(world)
    np.testing.assert_array_equal(joint_impulses(copied._joints), joint_impulses(world._joints))
    np.testing.assert_array_equal(copied.robot_contacts, world.robot_contacts)
    rng = np.random.default_rng(0)
    for _ in range(40):
        step = command + rng.uniform(-0.5, 0.5, command.shape)
        a, b = world.step(step), copied.step(step)
        for name in ("pos", "angle", "vel", "ang_vel"):
            np.testing.assert_array_equal(getattr(b, name), getattr(a, name))
        np.testing.assert_array_equal(copied.robot_contacts, world.robot_contacts)
        np.testing.assert_array_equal(copied.wall_contacts, world.wall_contacts)
    assert not np.shares_memory(copied.state.pos, world.state.pos)


@pytest.mark.parametrize("impulse", [[-4.300478754062833e-298, 0.0], [3e-170, -2e-171], [1e-160, 3e-161]])
def test_a_joint_impulse_too_small_to_square_is_read_and_copied(impulse) -> None:
    # A robot's joints come to rest with impulses as small as a gear's 4.3e-298 (seen in a copied game):
    # its square underflows, and reading it as the vector's length once stopped every copy of the world.
    world = _world(1, 2)
    world.step(np.zeros((1, 2, 3)))
    impulses = joint_impulses(world._joints)
    gear = np.array([isinstance(joint, pymunk.GearJoint) for joint in world._joints])
    impulses[gear, 0], impulses[~gear] = impulse[0], impulse
    set_joint_impulses(world._joints, impulses)
    np.testing.assert_array_equal(
        joint_impulses(world._joints), np.where(gear[:, None], [[impulse[0], 0]], impulse)
    )
    np.testing.assert_array_equal(joint_impulses(copy.deepcopy(world)._joints), joint_impulses(world._joints))
