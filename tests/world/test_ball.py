"""The ball and the goals of a world with balls: the ball rolls to a stop where a constant deceleration
puts it, robots push it and touch it, it bounces off walls, posts and the goal's back wall without
crossing them at the rules' top speed, its placement is checked, and a world with balls copies and keeps
its fields apart. The core places the balls of a scenario that has them."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from hier_ssl.envs import HierarchicalCore, scenario_config
from hier_ssl.envs.scenario import Placement
from hier_ssl.envs.scenarios import Crossing
from hier_ssl.envs.state import global_state, state_columns, state_dim
from hier_ssl.world import Entities, World
from hier_ssl.world.ball import BallSpec, BallState
from hier_ssl.world.goals import goal_boxes

SPEC = BallSpec()
MAX_BALL_SPEED = 6.5  # m/s, rules "Excessive Ball Speed": a kick faster than this is a foul


def _world(num_fields: int = 1, robots: int = 1, balls: int = 1, field: str = "division_b") -> World:
    entities = Entities()
    entities.add("robot", robots, "robots")
    entities.add("ball", balls, "ball")
    return World(num_fields, entities, field)


def _park_robots(world: World) -> None:
    """Every robot at rest in a corner of its field, out of the balls' way."""
    n, r = world.num_fields, world.num_robots
    hx, hy = world.field.half_length, world.field.half_width
    spots = np.stack([-hx + 0.3 * np.arange(1, r + 1), np.full(r, -hy + 0.2)], axis=-1)
    world.set_state(np.arange(n), np.broadcast_to(spots, (n, r, 2)), np.zeros((n, r)))


def test_a_world_without_balls_has_no_ball_state_and_one_with_has_both_kinds() -> None:
    plain = World(2, 2)
    assert plain.ball is None and list(plain.states) == ["robot"]
    with pytest.raises(ValueError, match="holds no balls"):
        plain.set_balls([0], np.zeros((1, 1, 2)))
    world = _world(2, robots=2, balls=3)
    assert isinstance(world.ball, BallState) and world.ball.pos.shape == world.ball.vel.shape == (2, 3, 2)
    assert world.states["ball"] is world.ball and world.states["robot"] is world.state
    assert world.ball_touch.shape == (2, 2) and world.ball.fields([1]).pos.shape == (1, 3, 2)


def test_a_rolling_ball_stops_after_v_squared_over_2a_and_never_turns_back() -> None:
    world = _world(2, field="division_a")
    _park_robots(world)
    start = np.array([[[-3.0, -2.0]], [[1.0, 1.0]]])
    vel = np.array([[[1.5, 2.0]], [[-0.05, 0.0]]])  # 2.5 m/s, and one that stops within the first step
    world.set_balls([0, 1], start, vel)
    speed = np.linalg.norm(vel, axis=-1)
    for _ in range(round(2.5 / SPEC.deceleration / world.dt) + 5):
        world.step(np.zeros((2, 1, 3)))
        now = np.linalg.norm(world.ball.vel, axis=-1)
        assert np.all(now <= speed + 1e-12) and np.all((world.ball.vel * vel).sum(-1) >= 0.0)
        speed = now
    assert np.all(speed == 0.0)
    rolled = np.linalg.norm(world.ball.pos - start, axis=-1)
    expected = np.linalg.norm(vel, axis=-1) ** 2 / (2 * SPEC.deceleration)
    np.testing.assert_allclose(rolled, expected, rtol=1e-9)
    direction = (world.ball.pos - start) / rolled[..., None]
    np.testing.assert_allclose(direction, vel / np.linalg.norm(vel, axis=-1, keepdims=True), atol=1e-9)


def test_a_robot_driving_into_the_ball_pushes_it_and_touches_it() -> None:
    world = _world(1, robots=2)
    world.set_state([0], np.array([[[-1.0, 0.0], [1.5, 1.5]]]), np.zeros((1, 2)))
    world.set_balls([0], np.array([[[-0.8, 0.0]]]))
    touched = np.zeros(2, dtype=bool)
    command = np.zeros((1, 2, 3))
    command[0, 0, 0] = 1.5
    for _ in range(40):
        world.step(command)
        touched |= world.ball_touch[0]
    ball_x, robot_x = world.ball.pos[0, 0, 0], world.state.pos[0, 0, 0]
    assert touched.tolist() == [True, False]
    assert ball_x > -0.3 and ball_x - robot_x > world.robot.radius + SPEC.radius - 1e-3
    assert abs(world.ball.pos[0, 0, 1]) < 1e-6 and world.ball.vel[0, 0, 0] > 0.0
    world.step(np.zeros((1, 2, 3)))  # flags are per control step: cleared by the next one
    world.set_state([0], np.array([[[-2.0, 0.0], [1.5, 1.5]]]), np.zeros((1, 2)))
    assert not world.ball_touch.any()


def test_a_ball_bounces_off_a_robot_at_its_restitution() -> None:
    world = _world(1)
    world.set_state([0], np.array([[[1.0, 0.0]]]), np.zeros((1, 1)))
    world.set_balls([0], np.zeros((1, 1, 2)), np.array([[[2.0, 0.0]]]))
    before = world.ball.vel[0, 0, 0]
    while not world.ball_touch[0, 0]:
        before = world.ball.vel[0, 0, 0]
        world.step(np.zeros((1, 1, 3)))
    # The robot, 48 times heavier and held by its motors, barely moves: the ball keeps about the
    # restitution's share of its speed, less a period's rolling deceleration.
    after = world.ball.vel[0, 0, 0]
    assert -SPEC.restitution_robot * before * 1.05 < after < -SPEC.restitution_robot * before * 0.9


def _shot(world: World, start: tuple[float, float], vel: tuple[float, float], steps: int) -> np.ndarray:
    """The ball's path (T, 2) after a shot from ``start`` at ``vel`` in field 0."""
    world.set_balls([0], np.array([[start]]), np.array([[vel]]))
    path = []
    for _ in range(steps):
        world.step(np.zeros((world.num_fields, world.num_robots, 3)))
        path.append(world.ball.pos[0, 0].copy())
    return np.array(path)


def _inside_a_goal_wall(field_name: str, path: np.ndarray, tol: float) -> np.ndarray:
    boxes = goal_boxes(_world(field=field_name).field) + np.array([-1, 1, -1, 1]) * (SPEC.radius - tol)
    x, y = path[:, None, 0], path[:, None, 1]
    return ((boxes[:, 0] < x) & (x < boxes[:, 1]) & (boxes[:, 2] < y) & (y < boxes[:, 3])).any(axis=1)


@pytest.mark.parametrize("field_name", ["division_a", "division_b"])
def test_a_ball_at_top_speed_bounces_off_walls_and_posts_and_stays_in_the_goal(field_name: str) -> None:
    world = _world(1, field=field_name)
    _park_robots(world)
    field = world.field
    line, half_goal, back = field.half_length, field.goal_width / 2, field.half_length + field.goal_depth
    hx, hy = field.wall_half_extent
    tol = 2e-3  # pymunk's contact slop and a substep's overlap before a contact pushes back
    # At the side wall, head on: back at the restitution's speed less the rolling deceleration.
    path = _shot(world, (0.0, hy - 0.5), (0.0, MAX_BALL_SPEED), 12)
    assert path[:, 1].max() <= hy - SPEC.radius + 1e-9
    assert world.ball.vel[0, 0, 1] < 0 and world.ball.vel[0, 0, 1] > -SPEC.restitution_wall * MAX_BALL_SPEED
    # At a post (a side wall's front end, on the goal line): back into the field.
    path = _shot(world, (line - 0.6, half_goal + 0.01), (MAX_BALL_SPEED, 0.0), 12)
    assert path[:, 0].max() <= line - SPEC.radius + tol and world.ball.vel[0, 0, 0] < 0
    # Into the goal, then at the back wall at a slant: never through a goal wall, out of the goal mouth.
    path = _shot(world, (line - 0.5, 0.0), (MAX_BALL_SPEED, 0.5), 16)
    assert path[:, 0].max() <= back - SPEC.radius + tol and path[:, 0].max() > line
    assert not _inside_a_goal_wall(field_name, path, tol).any()
    # Inside the goal, at a side wall at top speed: stays between the side walls.
    path = _shot(world, (line + 0.09, 0.0), (0.3, MAX_BALL_SPEED), 6)
    in_goal = path[:, 0] > line
    assert in_goal.all() and np.abs(path[in_goal, 1]).max() <= half_goal - SPEC.radius + tol
    assert not _inside_a_goal_wall(field_name, path, tol).any()
    # Into a corner of the walls: two bounces within a period or two, inside the walls throughout.
    path = _shot(world, (-hx + 0.3, hy - 0.3), (-MAX_BALL_SPEED, MAX_BALL_SPEED), 12)
    assert np.all(np.abs(path) <= np.array([hx, hy]) - SPEC.radius + 1e-9)
    assert np.all(world.ball.vel[0, 0] * np.array([-1, 1]) < 0)


def test_set_balls_names_the_bad_value() -> None:
    world = _world(2, balls=2)
    with pytest.raises(ValueError, match=r"set_balls: pos has shape \(1, 1, 2\), expected \(1, 2, 2\)"):
        world.set_balls([0], np.zeros((1, 1, 2)))
    bad = np.zeros((1, 2, 2))
    bad[0, 1, 0] = np.nan
    with pytest.raises(
        ValueError, match=r"set_balls: vel holds NaN or infinite values: \[nan, 0.0\], ball 1 of field 1"
    ):
        world.set_balls([1], np.zeros((1, 2, 2)), bad)
    far = np.zeros((1, 2, 2))
    far[0, 1] = (4.0, 5.0)
    with pytest.raises(
        ValueError, match=r"set_balls: ball 1 of field 1 at \[4.0, 5.0\] is not inside the walls"
    ):
        world.set_balls([1], far)
    with pytest.raises(ValueError, match=r"field index \[2\] out of range"):
        world.set_balls([2], np.zeros((1, 2, 2)))
    # Inside the back wall of the goal at +x (Division B: goal line 4.5 m, 0.18 m deep, 0.02 m walls), where
    # the ball's sweep, which assumes a ball starts outside every wall, would let it out through the wall.
    in_wall = np.array([[[0.0, 0.0], [4.69, 0.0]]])  # 4.5 + 0.18 + 0.01
    with pytest.raises(
        ValueError, match=r"set_balls: ball 1 of field 0 at \[4.69, 0.0\] is inside a goal wall"
    ):
        world.set_balls([0], in_wall)
    in_goal = np.array([[[0.0, 0.0], [4.5 + 0.09, 0.0]]])
    world.set_balls([0], in_goal)  # inside the goal, between its walls, is a place a ball can be
    np.testing.assert_array_equal(world.ball.pos[0], in_goal[0])


def test_a_world_with_balls_pickles_and_steps_as_its_copy() -> None:
    world = _world(2, robots=2)
    world.set_state([0, 1], np.array([[[-1.0, 0.0], [1.0, 1.0]]] * 2), np.zeros((2, 2)))
    world.set_balls([0, 1], np.array([[[-0.7, 0.05]], [[2.0, -1.0]]]), np.array([[[0.0, 0.0]], [[3.0, 2.0]]]))
    command = np.zeros((2, 2, 3))
    command[:, 0, 0] = 1.0
    for _ in range(5):
        world.step(command)
    copies = [pickle.loads(pickle.dumps(world)), copy.deepcopy(world)]
    for _ in range(30):
        world.step(command)
        for other in copies:
            other.step(command)
    for other in copies:
        np.testing.assert_array_equal(other.ball.pos, world.ball.pos)
        np.testing.assert_array_equal(other.ball.vel, world.ball.vel)
        np.testing.assert_array_equal(other.state.pos, world.state.pos)


def test_each_fields_ball_rolls_as_in_a_world_of_its_own() -> None:
    many, one = _world(3), _world(1)
    for world in (many, one):
        _park_robots(world)
    pos = np.array([[[0.0, 0.0]], [[1.0, -1.0]], [[0.0, 0.0]]])
    vel = np.array([[[2.0, 1.0]], [[-4.0, 3.0]], [[2.0, 1.0]]])
    many.set_balls([0, 1, 2], pos, vel)
    one.set_balls([0], pos[:1], vel[:1])
    for _ in range(60):
        many.step(np.zeros((3, 1, 3)))
        one.step(np.zeros((1, 1, 3)))
    np.testing.assert_array_equal(many.ball.pos[0], one.ball.pos[0])
    np.testing.assert_allclose(many.ball.pos[2], one.ball.pos[0], atol=1e-9)
    assert np.abs(many.ball.pos[1] - many.ball.pos[0]).max() > 1.0


def test_blocks_stepped_in_threads_move_the_balls_as_one_thread_does() -> None:
    worlds = [_world(70, robots=2) for _ in range(2)]  # two blocks of 35 fields
    worlds[1].use_threads(2)
    rng = np.random.default_rng(3)
    robots, balls, vel = (
        rng.uniform(-1, 1, (70, 2, 2)),
        rng.uniform(-1, 1, (70, 1, 2)),
        rng.uniform(-3, 3, (70, 1, 2)),
    )
    command = np.tile([1.0, 0.0, 0.0], (70, 2, 1))
    for world in worlds:
        world.set_state(np.arange(70), robots * [1.0, 3.0], np.zeros((70, 2)))
        world.set_balls(np.arange(70), balls, vel)
        for _ in range(10):
            world.step(command)
    np.testing.assert_array_equal(worlds[0].ball.pos, worlds[1].ball.pos)
    np.testing.assert_array_equal(worlds[0].ball_touch, worlds[1].ball_touch)


class _BallCrossing(Crossing):
    """Crossing with a ball in every field, at the centre unless ``ball_pos`` is taken away."""

    with_ball = True

    def make_world(self, num_fields: int) -> World:
        world = super().make_world(num_fields)
        world.entities.add("ball", 1, "ball")
        return World(num_fields, world.entities, self.field, dt=self.config.dt, substeps=self.config.substeps)

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> Placement:
        placement = super().reset_world_at(num_fields, rng)
        if self.with_ball:
            placement.ball_pos = np.zeros((num_fields, 1, 2))
            placement.ball_vel = np.tile([1.0, 0.5], (num_fields, 1, 1))
        return placement


def test_the_core_places_the_balls_of_its_scenario() -> None:
    scenario = _BallCrossing(scenario_config("crossing", num_agents=2))
    core = HierarchicalCore(scenario, 2)
    core.reset()
    np.testing.assert_array_equal(core.world.ball.pos, np.zeros((2, 1, 2)))
    np.testing.assert_array_equal(core.world.ball.vel, np.tile([1.0, 0.5], (2, 1, 1)))
    scenario.with_ball = False
    with pytest.raises(ValueError, match="'crossing': its world holds balls, its placement has no ball_pos"):
        core.reset_fields(np.array([1]))


def test_the_global_state_ends_with_the_balls() -> None:
    core = HierarchicalCore(_BallCrossing(scenario_config("crossing", num_agents=2)), 2)
    core.reset()
    state, scales = global_state(core), core.scenario.scales
    assert state.shape == (2, state_dim(2, 0, 1)) == (2, state_dim(2, 0) + 4)
    assert state_columns(2, 0, 1)[-4:] == ["ball_0_x", "ball_0_y", "ball_0_vx", "ball_0_vy"]
    expected = np.concatenate(
        [core.world.ball.pos / scales["max_pos"], core.world.ball.vel / scales["max_v"]], -1
    )
    np.testing.assert_allclose(state[:, -4:], expected[:, 0].astype(np.float32), rtol=1e-6)
