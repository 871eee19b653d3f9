from __future__ import annotations

import cmath
import dataclasses
import math

import numpy as np
import pytest

from hier_ssl.envs import env_config, scenario_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.manager import decode_subgoal, manager_observation
from hier_ssl.manager.bangbang import bang_bang_2d
from hier_ssl.manager.planners import read_scene
from hier_ssl.manager.trajectory import (
    Collisions,
    TrajectoryParams,
    TrajectoryPlanner,
    accepted,
    composite,
    first_collisions,
)
from hier_ssl.world.field import get_field

FIELD = get_field("hardware_challenge")


def _obs(robot_xy, target_xy, obstacles=(), robot_vel=(0.0, 0.0), obstacle_vel=None):
    """Manager observations (1, 13 + 5K) of one hand-placed scene."""
    k = len(obstacles)
    vel = np.zeros((1, k, 2)) if obstacle_vel is None else np.asarray(obstacle_vel, float).reshape(1, k, 2)
    return manager_observation(
        np.array([[*target_xy, 0.0, 0.0, 0.0]]),
        np.array([robot_xy], dtype=float),
        np.array([0.0]),
        np.array([robot_vel], dtype=float),
        np.array([0.0]),
        np.asarray(obstacles, dtype=float).reshape(1, k, 2),
        vel,
        np.zeros((1, k)),
        max_pos=FIELD.max_pos,
    )


def _xy(action: np.ndarray) -> complex:
    subgoal = decode_subgoal(action, "pose4", FIELD.half_length, FIELD.half_width)[0]
    return complex(subgoal[0], subgoal[1])


def test_an_empty_field_goes_straight_to_the_target() -> None:
    planner = make_planner("trajectory", env_config(task="proposed"))
    assert _xy(planner(_obs((-1.0, 0.5), (2.0, -1.5), robot_vel=(1.0, 1.0)))) == pytest.approx(2.0 - 1.5j)


def test_a_still_obstacle_on_the_line_gets_a_sub_destination() -> None:
    # (-1, 0) to (1, 0) through a still robot at the origin, 3 m/s^2 and 2.2 m/s: the direct path comes
    # within 0.3 m of it at 0.683 s, found at the check of 0.7 s (x = -0.265), 1.265 m from the target over
    # the start's 2 m: 0.63 >= 0.7 s / 4 s, rejected.
    config = env_config(task="obstacle")
    planner = make_planner("trajectory", config)
    obs = _obs((-1.0, 0.0), (1.0, 0.0), obstacles=[(0.0, 0.0)])
    scene = read_scene(obs, FIELD.max_pos, 2.5)
    speed, accel = planner.limits
    direct = bang_bang_2d(-1 + 0j, 1 + 0j, 0j, speed, accel)
    obstacles = (np.zeros((1, 1), complex), np.zeros((1, 1), complex), np.ones((1, 1), bool))
    path = (lambda t: direct.at(t)[0][None], direct.total_time[None])
    hits = first_collisions(*path, obstacles, 0.3, planner.params)
    assert float(hits.still_time[0]) == pytest.approx(0.7) and np.isinf(hits.moving_time[0])
    chosen, winner = planner.plan(scene, np.array([np.nan + 0j]))
    sub = complex(chosen[0])
    assert abs(sub.imag) > 0.3 and not np.isnan(winner[0])
    # The winner is the sub-destination relative to the robot-target line (2 m long, along +x), clipped to
    # the field.
    free = -1.0 + winner[0] * 2.0
    half_l, half_w = planner.field.half_length, planner.field.half_width
    assert sub == pytest.approx(
        complex(np.clip(free.real, -half_l, half_l), np.clip(free.imag, -half_w, half_w))
    )
    angle = abs(math.degrees(cmath.phase(winner[0])))
    assert 20.0 <= angle <= 140.0 and 0.5 <= abs(winner[0]) <= 1.5
    # Its path: the sub-path, then the target from the switch, clear of the obstacle by the planner's 0.25 m
    # (collision distance 0.2 + margin 0.05).
    first = bang_bang_2d(-1 + 0j, sub, 0j, speed, accel)
    switches = 0.1 + 0.2 * np.arange(1, 40)
    switches = switches[switches < float(first.total_time)]
    clear = []
    for s in switches:
        at, vel = first.at(s)
        then = bang_bang_2d(at, 1 + 0j, vel, speed, accel)
        t = np.arange(0.1, s + float(then.total_time), 0.1)
        path = np.where(t < s, first.at(t)[0], then.at(t - s)[0])
        clear.append(np.abs(path).min() >= 0.25)
    assert any(clear)


def test_last_winner_is_tried_and_remembered_per_robot() -> None:
    # No random sub-destinations: the remembered one is the only candidate, and it is taken.
    planner = make_planner("trajectory", env_config(task="obstacle"), num_sub_destinations=0)
    obs = _obs((-1.0, 0.0), (1.0, 0.0), obstacles=[(0.0, 0.0)])
    assert _xy(planner(obs)) == pytest.approx(-1.0)  # nothing to try, nothing remembered: stop in place
    planner.forget(3)
    planner.memory[2] = 0.7 * cmath.exp(1j * math.radians(60))
    assert _xy(planner(obs, rows=np.array([2]))) == pytest.approx(
        -1.0 + 1.4 * cmath.exp(1j * math.radians(60)), abs=1e-3
    )
    assert _xy(planner(obs, rows=np.array([1]))) == pytest.approx(-1.0)
    planner.forget(3)
    assert np.isnan(planner.memory).all()


def test_the_same_seed_gives_the_same_decisions() -> None:
    config = env_config(task="obstacle", frame_skip=4)
    runs = [evaluate(make_planner("trajectory", config), config, 12, seed=5) for _ in range(2)]
    planner = make_planner("trajectory", config)
    runs.append(evaluate(planner, config, 12, seed=5))
    runs.append(evaluate(planner, config, 12, seed=5))  # the same planner again: memory and draws reset
    for key in ("length", "success", "cpad"):
        for other in runs[1:]:
            np.testing.assert_array_equal(runs[0]["per_robot"][key], other["per_robot"][key])
    # A different planner seed draws other sub-destinations.
    obs = _obs((-1.0, 0.0), (1.0, 0.0), obstacles=[(0.0, 0.0)])
    one, two = make_planner("trajectory", config), make_planner("trajectory", config, seed=1)
    assert _xy(one(obs)) != pytest.approx(_xy(two(obs)))


@pytest.mark.parametrize(
    ("config", "least"),
    [(env_config(task=t, frame_skip=8), 1.0) for t in ("baseline", "proposed", "obstacle")]
    + [(scenario_config("crowd", frame_skip=8), 1.0)]
    + [(scenario_config(s, frame_skip=8), 0.8) for s in ("crossing", "formation")],
    ids=lambda c: getattr(c, "scenario_name", ""),
)
def test_trajectory_plays_every_task_and_scenario(config, least: float) -> None:
    # Seed 0, 4 episodes: every robot of the one-robot tasks arrives, and of the 24 robots crossing or in
    # formation 22 and 21 do (from 0.8: up to 4 may fail or collide).
    result = evaluate(make_planner("trajectory", config), config, 4, seed=0)
    assert result["robots"] >= 4 and result["success_rate"] >= least


def test_params_are_checked() -> None:
    with pytest.raises(ValueError, match="step_size_on_sub_path must be > 0"):
        TrajectoryParams(step_size_on_sub_path=0.0)
    with pytest.raises(ValueError, match="min_angle <= max_angle"):
        TrajectoryParams(min_angle=150.0)
    with pytest.raises(ValueError, match="collision_distance must be > 0"):
        TrajectoryPlanner(FIELD, collision_distance=0.0)
    planner = make_planner("trajectory", env_config(worker="paper"), brake_time_offset=0.3)
    assert planner.params.brake_time_offset == 0.3 and planner.limits[0] == 2.2


def test_checks_cover_the_motion_between_them_and_the_acceptors_follow_tigers() -> None:
    # At 4.4 m/s along y = 0 from x = -1, past a still obstacle at x = -0.34: the checks at 0.1 s (x = -0.56)
    # and 0.2 s (x = -0.12) are each 0.22 m from it, outside 0.2 m, but the robot passes through it between.
    path = (lambda t: np.array([-1.0 + 4.4 * t + 0j]), np.array([0.5]))
    still = (np.array([[-0.34 + 0j]]), np.zeros((1, 1), complex), np.ones((1, 1), bool))
    hits = first_collisions(*path, still, 0.2, TrajectoryParams())
    assert float(hits.still_time[0]) == pytest.approx(0.2) and np.isinf(hits.moving_time[0])
    # Still: a collision 0.1 m short of a 2 m path's end at 2 s passes (0.05 < 2 / 4), one at 1 m does not.
    p, start, goal = TrajectoryParams(), np.zeros(2, complex), np.full(2, 2 + 0j)
    near = Collisions(
        np.full(2, 2.0), np.array([1.9 + 0j, 1.0 + 0j]), np.full(2, np.inf), np.zeros(2, complex)
    )
    assert accepted(near, start, goal, np.zeros(2), 3.0, p)[0].tolist() == [True, False]
    # Moving: at 2 m/s braking at 1 m/s^2, a first collision must come after 2 + 0.5 s.
    late = Collisions(np.full(2, np.inf), np.zeros(2, complex), np.array([2.4, 2.6]), np.zeros(2, complex))
    assert accepted(late, start, goal, np.full(2, 2.0), 1.0, p)[1].tolist() == [False, True]


def _plan(planner: TrajectoryPlanner, obstacles, last: complex = complex(np.nan, 0.0)):
    """``plan`` for the robot at rest at (-1, 0) going to (1, 0) among still ``obstacles``."""
    scene = read_scene(_obs((-1.0, 0.0), (1.0, 0.0), obstacles=obstacles), FIELD.max_pos, 2.5)
    chosen, winner = planner.plan(scene, np.array([last]))
    return complex(chosen[0]), complex(winner[0])


def test_the_direct_path_is_checked_by_position_not_velocity() -> None:
    # A still robot at (1.8, 0), 0.8 m past the target: the path from -1 to 1 never comes within 0.25 m,
    # though its velocity (0 to 2.2 m/s along x) passes through 1.8.
    chosen, winner = _plan(make_planner("trajectory", env_config(task="obstacle")), [(1.8, 0.0)])
    assert chosen == pytest.approx(1.0, abs=1e-6) and np.isnan(winner)


def test_a_remembered_sub_destination_whose_paths_all_hit_the_still_obstacle_is_refused() -> None:
    # The only candidate, 5 degrees off the line through the still robot at the origin: every switch
    # passes within 0.25 m of it, so nothing is accepted and no rejected path is clear of it: stop.
    planner = make_planner("trajectory", env_config(task="obstacle"), num_sub_destinations=0)
    chosen, winner = _plan(planner, [(0.0, 0.0)], last=cmath.exp(1j * math.radians(5)))
    assert chosen == pytest.approx(-1.0, abs=1e-6) and np.isnan(winner)


def test_the_memory_holds_the_winner_and_keeps_it_when_the_direct_path_wins() -> None:
    planner = make_planner("trajectory", env_config(task="obstacle"))
    planner.forget(2)
    blocked = _obs((-1.0, 0.0), (1.0, 0.0), obstacles=[(0.0, 0.0)])
    sub = _xy(planner(blocked, rows=np.array([1])))
    remembered = planner.memory[1]
    assert np.isnan(planner.memory[0]) and not np.isnan(remembered)
    # The winner is relative to the 2 m robot-target line along +x; its sub-goal clipped to the field.
    free = -1.0 + 2.0 * remembered
    half_l, half_w = FIELD.half_length, FIELD.half_width
    clipped = complex(np.clip(free.real, -half_l, half_l), np.clip(free.imag, -half_w, half_w))
    assert sub == pytest.approx(clipped, abs=1e-3)
    free_field = _obs((-1.0, 0.0), (1.0, 0.0), obstacles=[(0.0, 1.5)])
    assert _xy(planner(free_field, rows=np.array([1]))) == pytest.approx(1.0, abs=1e-3)
    assert planner.memory[1] == remembered


def test_a_composite_path_follows_the_sub_path_until_the_switch_and_the_target_after() -> None:
    first = bang_bang_2d(0j, 1 + 1j, 0j, 2.0, 3.0)
    then = bang_bang_2d(1j, 2 + 0j, 0.5 + 0j, 2.0, 3.0)
    switch = np.array([0.3, 0.5])
    np.testing.assert_allclose(composite(first, then, switch, 0.4), [then.at(0.1)[0], first.at(0.4)[0]])


def test_first_collisions_are_placed_in_the_plane() -> None:
    # Along y = 0.5 at 4.4 m/s past a still obstacle at (-0.34, 0.5) and a robot moving at (0.12, 0.5)
    # 0.5 m/s across: both first found at 0.2 s (x = -0.12), recorded with their y.
    path = (lambda t: np.array([-1.0 + 4.4 * t + 0.5j]), np.array([0.5]))
    obstacles = (
        np.array([[-0.34 + 0.5j, -0.02 + 0.5j]]),
        np.array([[0j, -0.5 + 0j]]),
        np.array([[True, False]]),
    )
    hits = first_collisions(*path, obstacles, 0.2, TrajectoryParams())
    assert (float(hits.still_time[0]), float(hits.moving_time[0])) == pytest.approx((0.2, 0.2))
    assert complex(hits.still_pos[0]) == pytest.approx(-0.12 + 0.5j)
    assert complex(hits.moving_pos[0]) == pytest.approx(-0.12 + 0.5j)


def _plans(planner: TrajectoryPlanner, scenes, last):
    """``plan`` over a batch of scenes (robot, target, obstacles, obstacle velocities or None), robots at
    rest."""
    obs = np.concatenate([_obs(r, t, obstacles=o, obstacle_vel=v) for r, t, o, v in scenes])
    return planner.plan(read_scene(obs, FIELD.max_pos, 2.5), np.asarray(last, complex))


def test_a_line_off_both_axes_blocked_by_a_still_obstacle_gets_a_detour() -> None:
    # (0, 1) to (2, 1) through a still robot at (1, 1): a detour from (0, 1) along the 2 m line, its
    # sub-goal clipped to the field's half width of 2 m.
    planner = make_planner("trajectory", env_config(task="obstacle"))
    chosen, winner = _plans(planner, [((0.0, 1.0), (2.0, 1.0), [(1.0, 1.0)], None)], [np.nan])
    assert not np.isnan(winner[0])
    free = 1j + 2.0 * winner[0]
    assert complex(chosen[0]) == pytest.approx(
        complex(np.clip(free.real, -3.0, 3.0), np.clip(free.imag, -2, 2))
    )


def test_an_obstacle_within_the_margin_of_the_line_blocks_it() -> None:
    # A still robot 0.2 m off the line: outside the collision distance (0.2) but inside it plus the
    # margin (0.25).
    planner = make_planner("trajectory", env_config(task="obstacle"))
    chosen, winner = _plans(planner, [((0.0, 1.0), (2.0, 1.0), [(1.0, 1.2)], None)], [np.nan])
    assert not np.isnan(winner[0]) and abs(complex(chosen[0]) - (2 + 1j)) > 0.5


def test_robots_of_one_call_are_planned_each_on_its_own() -> None:
    # Two robots blocked alike, each with its one remembered candidate: 60 degrees (clear) is taken, 5
    # degrees (through the obstacle) leaves the other robot stopped where it is.
    planner = make_planner("trajectory", env_config(task="obstacle"), num_sub_destinations=0)
    scene = ((-1.0, 0.0), (1.0, 0.0), [(0.0, 0.0)], None)
    good, bad = 0.7 * cmath.exp(1j * math.radians(60)), cmath.exp(1j * math.radians(5))
    chosen, winner = _plans(planner, [scene, scene], [good, bad])
    assert complex(chosen[0]) == pytest.approx(-1.0 + 1.4 * cmath.exp(1j * math.radians(60)), abs=1e-3)
    assert complex(winner[0]) == pytest.approx(good)
    assert complex(chosen[1]) == pytest.approx(-1.0, abs=1e-6) and np.isnan(winner[1])


def test_when_a_moving_obstacle_rejects_every_path_the_closest_miss_is_taken() -> None:
    # A robot 0.3 m above the start moving down at 0.5 m/s meets every path within 0.2 s, before the
    # 0.5 s the moving acceptor asks of a robot at rest.
    planner = make_planner("trajectory", env_config(task="obstacle"), num_sub_destinations=0)
    crossing = ((-1.0, 0.0), (1.0, 0.0), [(-1.0, 0.3)], [(0.0, -0.5)])
    # Nothing else to try: the rejected direct path, the only one, is taken: straight to the target.
    chosen, winner = _plans(planner, [crossing], [np.nan])
    assert complex(chosen[0]) == pytest.approx(1.0, abs=1e-6) and np.isnan(winner[0])
    # With a still robot on the line the direct path is out; the remembered 60-degree candidate, rejected
    # by the moving robot only, is the closest (the only) miss.
    blocked = ((-1.0, 0.0), (1.0, 0.0), [(0.0, 0.0), (-1.0, 0.3)], [(0.0, 0.0), (0.0, -0.5)])
    good = 0.7 * cmath.exp(1j * math.radians(60))
    chosen, winner = _plans(planner, [blocked], [good])
    assert complex(chosen[0]) == pytest.approx(-1.0 + 1.4 * cmath.exp(1j * math.radians(60)), abs=1e-3)
    assert complex(winner[0]) == pytest.approx(good)


def test_sub_destinations_are_drawn_either_side_within_the_angles_and_scales() -> None:
    planner = make_planner("trajectory", env_config(task="obstacle"))
    draws = planner.draw(400)
    assert draws.shape == (400, 5)
    angle, scale = np.degrees(np.abs(np.angle(draws))), np.abs(draws)
    assert angle.min() >= 20.0 and angle.max() <= 140.0
    assert angle.min() < 25.0 and angle.max() > 135.0  # the whole range, not a corner of it
    assert (np.angle(draws) > 0).any() and (np.angle(draws) < 0).any()
    assert scale.min() >= 0.5 and scale.max() <= 1.5 and np.ptp(scale, axis=1).min() > 0.0


def test_a_moving_obstacle_is_judged_by_the_workers_braking() -> None:
    # At 1.5 m/s along x from (-1, 0) to (2, 0), the direct path passes x = 1.52 at 1.2 s, where a robot
    # moving up at 0.15 m/s (predicted for 1 s: 0.15 m off the line) is met at about 1.1-1.2 s. Braking at
    # the paper worker's 1 m/s^2 that is before 1.5 / 1 + 0.5 = 2 s: rejected, a detour. A worker braking
    # at 3 m/s^2 would need only 1.5 / 3 + 0.5 = 1 s: the direct path stands.
    obs = _obs(
        (-1.0, 0.0), (2.0, 0.0), obstacles=[(1.517, 0.0)], obstacle_vel=[(0.0, 0.15)], robot_vel=(1.5, 0.0)
    )
    scene = read_scene(obs, FIELD.max_pos, 2.5)
    planner = make_planner("trajectory", env_config(task="obstacle"))
    assert planner.brake_accel == 1.0
    assert not np.isnan(planner.plan(scene, np.array([np.nan + 0j]))[1][0])
    hard = dataclasses.replace(planner, brake_accel=3.0)
    chosen, winner = hard.plan(scene, np.array([np.nan + 0j]))
    assert complex(chosen[0]) == pytest.approx(2.0, abs=1e-6) and np.isnan(winner[0])


@pytest.mark.parametrize(("x", "side", "corner"), [(2.5, 1, 3 - 2j), (-2.5, 1, -3 + 2j), (-2.5, -1, -3 - 2j)])
def test_a_sub_destination_past_the_field_is_clipped_to_its_corner(
    x: float, side: int, corner: complex
) -> None:
    # 2 m towards the centre along x, blocked half-way; the one candidate, 130 degrees off the line at 1.5
    # times its length, lies 1.93 m behind the robot and 2.30 m aside: past the 3 x 2 m half field.
    planner = make_planner("trajectory", env_config(task="obstacle"), num_sub_destinations=0)
    toward = -math.copysign(2.0, x)
    scene = ((x, 0.0), (x + toward, 0.0), [(x + toward / 2, 0.0)], None)
    chosen, _ = _plans(planner, [scene], [1.5 * cmath.exp(side * 1j * math.radians(130))])
    assert complex(chosen[0]) == pytest.approx(corner)


def _still_hit(time: float, pos: complex) -> Collisions:
    return Collisions(np.array([time]), np.array([pos]), np.array([np.inf]), np.zeros(1, complex))


@pytest.mark.parametrize(
    ("start", "goal", "time", "pos", "ok"),
    [
        # 1 to 3 (2 m), at 2 s (threshold 0.5): 0.4 m short of the end (0.2) passes, 1.5 m (0.75) does not.
        (1.0, 3.0, 2.0, 2.6, True),
        (1.0, 3.0, 2.0, 1.5, False),
        # A 0.5 m path, at 1 s (threshold 0.25): 0.2 m short of the end is 0.4 of it, rejected.
        (0.0, 0.5, 1.0, 0.3, False),
        # After 8 s the threshold stays 1: a collision farther from the end than the start is rejected.
        (0.0, 2.0, 8.0, -1.0, False),
    ],
)
def test_the_still_acceptor_compares_the_collisions_share_of_the_distance_with_its_time(
    start: float, goal: float, time: float, pos: float, ok: bool
) -> None:
    still_ok, _ = accepted(_still_hit(time, complex(pos)), start, goal, 0.0, 1.0, TrajectoryParams())
    assert bool(still_ok[0]) is ok


def test_a_moving_collision_exactly_at_the_braking_time_is_rejected() -> None:
    # 2 m/s braking at 1 m/s^2 plus 0.5 s: 2.5 s exactly is not later than it.
    hits = Collisions(np.array([np.inf]), np.zeros(1, complex), np.array([2.5]), np.zeros(1, complex))
    assert not accepted(hits, 0.0, 2.0, 2.0, 1.0, TrajectoryParams())[1][0]


def test_moving_straight_away_from_an_obstacle_is_no_collision() -> None:
    # From 0.3 m to 0.4 m from a still obstacle between the checks at 0.1 s and 0.2 s: the closest point of
    # that stretch is its start, 0.3 m, outside 0.25 m (the line through it, not the stretch, meets it).
    path = (lambda t: np.array([0.2 + 1.0 * t + 0j]), np.array([0.25]))
    still = (np.zeros((1, 1), complex), np.zeros((1, 1), complex), np.ones((1, 1), bool))
    assert np.isinf(first_collisions(*path, still, 0.25, TrajectoryParams()).still_time[0])


def test_a_check_at_the_paths_end_time_does_not_count() -> None:
    # Checks at 0.1, 0.2, 0.3 s; the path ends at the third, where it would first meet the obstacle.
    p = TrajectoryParams()
    end = p.initial_time_offset + 2 * p.collision_check_step
    path = (lambda t: np.array([-1.0 + 4.4 * t + 0j]), np.array([end]))
    still = (np.array([[-1.0 + 4.4 * end + 0j]]), np.zeros((1, 1), complex), np.ones((1, 1), bool))
    assert np.isinf(first_collisions(*path, still, 0.2, p).still_time[0])


def test_an_empty_batch_of_paths_has_no_collisions() -> None:
    obstacles = (np.zeros((0, 1), complex), np.zeros((0, 1), complex), np.ones((0, 1), bool))
    hits = first_collisions(lambda t: np.zeros(0, complex), np.zeros(0), obstacles, 0.2, TrajectoryParams())
    assert hits.still_time.shape == (0,)


def test_a_new_planner_remembers_no_robot() -> None:
    assert make_planner("trajectory", env_config(task="obstacle")).memory.shape == (0,)


def test_a_robot_exactly_at_the_collision_distance_does_not_collide() -> None:
    # Standing 0.25 m from a still obstacle through every check (and between them): "under" the distance.
    path = (lambda t: np.array([0.25 + 0j]), np.array([0.5]))
    still = (np.zeros((1, 1), complex), np.zeros((1, 1), complex), np.ones((1, 1), bool))
    assert np.isinf(first_collisions(*path, still, 0.25, TrajectoryParams()).still_time[0])


def test_params_take_their_range_ends_and_refuse_what_is_past_them() -> None:
    TrajectoryParams(min_angle=0.0, max_angle=0.0, min_scale=1.0, max_scale=1.0, num_sub_destinations=0)
    for bad in ({"min_scale": 0.0}, {"num_sub_destinations": -1}):
        with pytest.raises(ValueError, match="bad sub-destination range"):
            TrajectoryParams(**bad)
