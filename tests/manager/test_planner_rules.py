"""The scripted planners under the rules: zones as obstacles, targets made legal, STOP's speed, HALT.

The 6 x 4 m field of the paper (walls at |x| <= 3.3, |y| <= 2.3, kept 0.09 m inside) and, in STOP, the
ball at the origin, kept 0.5 + 0.09 = 0.59 m from. The planners move a target inside a zone to ZONE_MARGIN
(0.05 m) beyond the clearance: 0.64 m from the ball. Paths are checked against the geometry directly, at
1 mm steps, not through the planners' own clearance functions.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hier_ssl.envs import env_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.game import zones as z
from hier_ssl.game.legal import RowRules
from hier_ssl.manager import decode_subgoal, manager_observation
from hier_ssl.manager.bangbang import bang_bang_2d
from hier_ssl.manager.planners import ZONE_MARGIN, read_scene
from hier_ssl.manager.trajectory import Collisions, TrajectoryParams, accepted, first_collisions
from hier_ssl.world.field import get_field

FIELD = get_field("hardware_challenge")
WALLS = (z.KEEP_IN, (-3.3, -2.3, 3.3, 2.3), 0.09)
BALL = (z.CAPSULE, (0.0, 0.0, 0.0, 0.0), 0.59)
EMPTY = (z.NONE, (0.0, 0.0, 0.0, 0.0), 0.0)


def _rules(*slots, speed: float = np.inf, rows: int = 1) -> RowRules:
    zones = z.Zones(
        np.array([[s[0] for s in slots]] * rows),
        np.array([[s[1] for s in slots]] * rows, float),
        np.array([[s[2] for s in slots]] * rows, float),
    )
    return RowRules(zones, np.full(rows, speed))


STOP = _rules(WALLS, EMPTY, EMPTY, BALL, speed=1.5)


def _obs(robot, target, obstacles=(), target_vel=(0.0, 0.0)) -> np.ndarray:
    k = len(obstacles)
    return manager_observation(
        np.array([[*target, 0.0, *target_vel]]),
        np.array([robot], float),
        np.array([0.0]),
        np.zeros((1, 2)),
        np.array([0.0]),
        np.asarray(obstacles, float).reshape(1, k, 2),
        np.zeros((1, k, 2)),
        np.zeros((1, k)),
        max_pos=FIELD.max_pos,
    )


def _subgoal(planner, action: np.ndarray) -> np.ndarray:
    return decode_subgoal(action, planner.action_form, FIELD.half_length, FIELD.half_width)


def _planner(name: str, task: str = "proposed", **kwargs):
    return make_planner(name, env_config(task=task, **kwargs))


def _leg_gap(start, end) -> float:
    """The least distance of the straight leg start -> end from the ball, at 1 mm steps."""
    a, b = complex(*start), complex(*end)
    steps = max(int(abs(b - a) / 1e-3), 1)
    return float(np.abs(a + (b - a) * np.linspace(0.0, 1.0, steps + 1)).min())


@pytest.mark.parametrize("name", ["direct", "sampling", "trajectory"])
def test_rules_that_forbid_nothing_a_planner_does_change_nothing(name: str) -> None:
    # Walls only (every target and candidate is inside them) and no speed limit: bit for bit.
    rng = np.random.default_rng(5)
    obs = np.concatenate(
        [_obs(rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2), [rng.uniform(-1, 1, 2)]) for _ in range(6)]
    )
    free = _rules(WALLS, EMPTY, EMPTY, EMPTY, rows=6)
    plain = _planner(name, "obstacle")(obs)
    ruled = _planner(name, "obstacle")(obs, rules=free)
    assert ruled.tobytes() == plain.tobytes()


def test_direct_hands_the_legal_target_at_the_stop_speed() -> None:
    planner = _planner("direct", action_form="pose6")
    obs = _obs((-1.5, 0.0), (0.3, 0.0), target_vel=(2.0, 2.0))
    subgoal = _subgoal(planner, planner(obs, rules=STOP))[0]
    # (0.3, 0) is 0.29 m inside the ball's zone: out along the ray from the ball to 0.59 + 0.05 m.
    assert subgoal[:2] == pytest.approx([0.59 + ZONE_MARGIN, 0.0], abs=1e-6)
    # 2.83 m/s at 45 degrees, capped at 1.5 m/s: 1.5 / sqrt(2) = 1.0607 each way.
    assert subgoal[3:] == pytest.approx([1.5 / np.sqrt(2)] * 2, abs=1e-4)
    assert np.hypot(*subgoal[3:]) <= 1.5 + 1e-4
    plain = _subgoal(planner, planner(obs))[0]
    assert plain[:2] == pytest.approx([0.3, 0.0], abs=1e-6)  # without the rules: the target as it is


@pytest.mark.parametrize("name", ["direct", "sampling", "trajectory"])
def test_a_target_inside_a_zone_becomes_its_nearest_legal_point(name: str) -> None:
    # From (1.5, 0) the straight way to (0.64, 0) keeps clear of the ball: every planner hands it.
    planner = _planner(name)
    subgoal = _subgoal(planner, planner(_obs((1.5, 0.0), (0.3, 0.0)), rules=STOP))[0]
    assert subgoal[:2] == pytest.approx([0.59 + ZONE_MARGIN, 0.0], abs=1e-6)


def test_sampling_goes_round_a_zone_across_the_straight_path() -> None:
    planner = _planner("sampling")
    obs = _obs((-1.5, 0.0), (1.5, 0.0))
    assert _subgoal(planner, planner(obs))[0, :2] == pytest.approx([1.5, 0.0], abs=1e-6)  # straight
    subgoal = _subgoal(planner, planner(obs, rules=STOP))[0, :2]
    assert np.hypot(*subgoal) >= 0.59  # the sub-goal is out of the zone
    assert _leg_gap((-1.5, 0.0), subgoal) >= 0.59 - 1e-3  # and both legs keep clear of it
    assert _leg_gap(subgoal, (1.5, 0.0)) >= 0.59 - 1e-3


def test_sampling_never_hands_a_sub_goal_inside_a_zone() -> None:
    # The target (0.3, 0) is made (0.64, 0), behind the ball from the robot: no one sub-goal reaches it by
    # two straight legs clear of the ball, so the planner goes round it, one clear first leg at a time.
    planner = _planner("sampling")
    subgoal = _subgoal(planner, planner(_obs((-1.5, 0.0), (0.3, 0.0)), rules=STOP))[0, :2]
    assert np.hypot(*subgoal) >= 0.59
    assert _leg_gap((-1.5, 0.0), subgoal) >= 0.59 - 1e-3


def test_trajectory_goes_round_a_zone_across_the_straight_path() -> None:
    planner = _planner("trajectory")
    obs = _obs((-1.5, 0.0), (1.5, 0.0))
    assert _subgoal(planner, planner(obs))[0, :2] == pytest.approx([1.5, 0.0], abs=1e-6)
    subgoal = _subgoal(_planner("trajectory"), _planner("trajectory")(obs, rules=STOP))[0, :2]
    assert np.hypot(*subgoal) >= 0.59 and abs(subgoal[1]) > 0.59  # a sub-destination beside the ball
    # The robot, at rest, drives a straight bang-bang path to it: clear of the ball all the way.
    path = bang_bang_2d(-1.5 + 0j, complex(*subgoal), 0j, 1.5, 3.0)
    times = np.linspace(0.0, float(path.total_time), 2000)
    assert np.abs(path.at(times)[0]).min() >= 0.59 - 1e-3


def test_the_sampling_rollout_keeps_the_stop_speed() -> None:
    # 3 m straight ahead from rest: at 1.5 m/s it takes at least 3 / 1.5 = 2 s; at the planner's own
    # speed (2.5 m/s here) less, though more than 3 / 2.5 = 1.2 s (it brakes at the worker's 1 m/s^2).
    planner = _planner("sampling")
    scene = planner.read(_obs((-1.5, 0.0), (1.5, 0.0)))
    cand = planner.candidates(scene)[:, :1]  # the target itself
    stopped = planner.rollout(scene, cand, np.array([1.5]))[0][0, 0]
    free = planner.rollout(scene, cand)[0][0, 0]
    assert stopped >= 2.0 and 1.2 <= free < stopped


@pytest.mark.parametrize("name", ["direct", "sampling", "trajectory"])
def test_halt_holds_the_robot_where_it_is(name: str) -> None:
    planner = _planner(name, action_form="pose6")
    halt = _rules(WALLS, EMPTY, EMPTY, EMPTY, speed=0.0)
    subgoal = _subgoal(planner, planner(_obs((-1.5, 0.5), (1.5, 0.0), target_vel=(1.0, 0.0)), rules=halt))[0]
    assert subgoal[:2] == pytest.approx([-1.5, 0.5], abs=1e-6) and subgoal[3:].tolist() == [0.0, 0.0]


def test_trajectory_checks_find_the_first_step_into_a_zone() -> None:
    # A path along the x axis at 1 m/s from x = -1.5: checked at 0.1 s, 0.2 s, ...; the step from the check
    # at 0.9 s (x = -0.6) to the one at 1.0 s (x = -0.5) crosses x = -0.59 into the ball's zone.
    def path(t: float) -> np.ndarray:
        return np.array([-1.5 + t + 0j])

    none = (np.zeros((1, 0), complex), np.zeros((1, 0), complex), np.zeros((1, 0), bool))
    params, total = TrajectoryParams(), np.array([3.0])

    def check(leaving: list[bool]):
        return first_collisions(path, total, none, 0.25, params, (STOP.zones, np.array([leaving])))

    hits = check([False] * 4)
    assert hits.zone_time[0] == pytest.approx(1.0) and np.isinf(hits.still_time[0])
    # Its still obstacles accept it otherwise, but not with that step: no leniency near the end for a zone.
    still_ok, _ = accepted(hits, -1.5 + 0j, 1.5 + 0j, 0.0, 1.0, params)
    assert not still_ok[0]
    # A robot that starts in the zone is leaving it: that zone does not stop its path.
    assert np.isinf(check([False, False, False, True]).zone_time[0])


@pytest.mark.parametrize("name", ["sampling", "trajectory"])
def test_a_robot_inside_a_zone_is_sent_out_of_it(name: str) -> None:
    # STOP is called with the robot 0.2 m from the ball: its sub-goal is outside the zone (0.59 m or more
    # from the ball), and the zone it is in does not keep it from moving.
    planner = _planner(name)
    subgoal = _subgoal(planner, planner(_obs((0.2, 0.0), (-1.5, 0.0)), rules=STOP))[0, :2]
    assert np.hypot(*subgoal) >= 0.59
    assert np.hypot(*(subgoal - [0.2, 0.0])) > 0.3


def test_rules_for_other_rows_are_refused() -> None:
    with pytest.raises(ValueError, match="rules for 2 robots, observations of 1"):
        _planner("direct")(_obs((0.0, 0.0), (1.0, 0.0)), rules=_rules(WALLS, rows=2))


@pytest.mark.parametrize("name", ["sampling", "trajectory"])
def test_a_target_behind_the_ball_is_reached_round_it(name: str) -> None:
    # No one sub-goal takes the robot from (-1.5, 0) round the ball to (0.64, 0) on two clear straight legs,
    # so each decision sends it a step round. A robot that moves 0.15 m a decision straight at its sub-goal
    # (1.5 m/s, 0.1 s) gets there within 150 decisions and never comes within 0.59 m of the ball.
    planner = _planner(name)
    rows = {"rows": np.array([0])} if name == "trajectory" else {}
    if rows:
        planner.forget(1)
    robot, closest = np.array([-1.5, 0.0]), np.inf
    for _ in range(150):
        subgoal = _subgoal(planner, planner(_obs(tuple(robot), (0.3, 0.0)), rules=STOP, **rows))[0, :2]
        assert np.hypot(*subgoal) >= 0.59
        step = subgoal - robot
        moved = robot + step * min(1.0, 0.15 / max(np.hypot(*step), 1e-12))
        closest, robot = min(closest, _leg_gap(robot, moved)), moved
    assert robot == pytest.approx([0.59 + ZONE_MARGIN, 0.0], abs=1e-6)
    assert closest >= 0.59 - 1e-3


def _stadium_gap(start, end, a: complex, b: complex) -> float:
    """The least distance of the straight leg start -> end from the segment a -> b, at 1 mm steps."""
    p, q = complex(*start), complex(*end)
    points = p + (q - p) * np.linspace(0.0, 1.0, max(int(abs(q - p) / 1e-3), 1) + 1)
    t = np.clip(((points - a) * np.conj(b - a)).real / abs(b - a) ** 2, 0.0, 1.0)
    return float(np.abs(points - (a + t * (b - a))).min())


def test_sampling_reaches_a_target_across_a_ball_placement_corridor_round_its_open_end() -> None:
    # The stadium 0.59 m round the ball's way from (0, -1.2) to (0, 1.6) lies across the field between the
    # robot and its target; only its lower end, the farther, leaves room to pass before the wall. Every
    # sub-goal's second leg crosses the corridor, so none is clear: the planner must prefer those that cross
    # it nearer the open end, not stand on its own position (every crossing is 0 m from the ball's way) nor
    # head for the closed end, the nearer.
    a, b = -1.2j, 1.6j
    placement = _rules(WALLS, EMPTY, EMPTY, (z.CAPSULE, (0.0, -1.2, 0.0, 1.6), 0.59))
    planner = _planner("sampling")
    robot, target, closest = np.array([-1.5, 0.8]), (1.5, 0.8), np.inf
    for _ in range(200):
        subgoal = _subgoal(planner, planner(_obs(tuple(robot), target), rules=placement))[0, :2]
        step = subgoal - robot
        moved = robot + step * min(1.0, 0.15 / max(np.hypot(*step), 1e-12))
        closest, robot = min(closest, _stadium_gap(robot, moved, a, b)), moved
    assert robot == pytest.approx(target, abs=1e-6)
    assert closest >= 0.59 - 1e-3


def test_sampling_under_the_rules_is_row_wise() -> None:
    # Each row is decided from its own observation and rules: a subset of rows gets the same actions.
    rng = np.random.default_rng(2)
    obs = np.concatenate([_obs(rng.uniform(-2, 2, 2), rng.uniform(-1, 1, 2)) for _ in range(5)])
    rules = _rules(WALLS, EMPTY, EMPTY, BALL, speed=1.5, rows=5)
    planner = _planner("sampling")
    every = planner(obs, rules=rules)
    some = RowRules(
        z.Zones(rules.zones.kind[[3, 0]], rules.zones.shape[[3, 0]], rules.zones.clearance[[3, 0]]),
        rules.speed[[3, 0]],
    )
    assert planner(obs[[3, 0]], rules=some).tobytes() == every[[3, 0]].tobytes()


def test_a_path_clear_of_the_zones_still_answers_to_the_still_obstacles() -> None:
    # 1 to 3 (2 m), a still robot hit at 2 s (threshold 0.5) 1.5 m short of the end (0.75): rejected, zones
    # checked and never entered or not.
    hits = Collisions(np.array([2.0]), np.array([1.5 + 0j]), np.array([np.inf]), np.zeros(1, complex))
    checked = dataclasses.replace(hits, zone_time=np.array([np.inf]), zone_pos=np.zeros(1, complex))
    for each in (hits, checked):
        assert not accepted(each, 1.0 + 0j, 3.0 + 0j, 0.0, 1.0, TrajectoryParams())[0][0]


def _one_candidate(robot, candidate: complex, drawn: tuple[complex, ...] = ()) -> complex:
    """``plan`` in STOP for the robot at rest at ``robot`` going to (0.3, 0), made (0.64, 0), behind the
    ball, with ``candidate`` (relative to the robot-target line) its only sub-destination, or the first
    before ``drawn``."""
    planner = make_planner("trajectory", env_config(task="proposed"), num_sub_destinations=len(drawn))
    planner.draw = lambda n: np.array([drawn] * n, complex).reshape(n, len(drawn))
    scene = read_scene(_obs(robot, (0.3, 0.0)), FIELD.max_pos, 2.5)
    return complex(planner.plan(scene, np.array([candidate]), STOP)[0][0])


def test_every_path_into_a_zone_heads_for_the_one_clear_until_its_switch() -> None:
    # From (-1.5, 0.2) the line to (0.64, 0) is 2.14 - 0.2j; the candidate 0.5 + 0.5j is (1.17 + 0.97j) off
    # the robot: (-0.33, 1.17), 1.22 m from the ball, reached clear of it. From there and from every switch
    # before it the straight way on passes within 0.59 m of the ball (from (-0.33, 1.17): 0.49 m), so no
    # path is accepted; the sub-path is clear until its switch, and the robot heads for it.
    assert _one_candidate((-1.5, 0.2), 0.5 + 0.5j) == pytest.approx(-0.33 + 1.17j, abs=1e-6)


def test_a_sub_destination_inside_a_zone_is_no_candidate_and_the_robot_stops() -> None:
    # The candidate 0.5 + 0j is halfway along the line: (-0.43, 0.1), 0.44 m from the ball, inside its zone.
    # With no other path, the robot (outside every zone) stops where it is: its own nearest legal point.
    assert _one_candidate((-1.5, 0.2), 0.5 + 0j) == pytest.approx(-1.5 + 0.2j, abs=1e-6)


def test_a_sub_destination_inside_a_zone_leaves_the_others_candidates() -> None:
    # Both candidates of the two tests above: the one inside the ball's zone is dropped, the other kept.
    assert _one_candidate((-1.5, 0.2), 0.5 + 0.5j, (0.5 + 0j,)) == pytest.approx(-0.33 + 1.17j, abs=1e-6)
