"""One control period: decisions every frame_skip periods, commands in the robot's frame, and the stop of
every robot not seen lately or without a target."""

from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.deploy.controller import MAX_AGE, Controller
from hier_ssl.deploy.game import InPlayWatch
from hier_ssl.deploy.tracker import Tracker
from hier_ssl.deploy.view import DeployView, manager_task
from hier_ssl.deploy.wire import Detection, DetectionFrame, check_field, encode_geometry, parse_vision
from hier_ssl.envs.registry import task_config
from hier_ssl.game.referee import DIRECT_FREE_BLUE, FORCE_START, referee_state
from hier_ssl.world.field import get_field
from hier_ssl.world.physics import World


def _controller(
    robots: tuple[int, ...] = (0,), manager: str = "direct", frame_skip: int = 4, feedback: str = "command"
) -> Controller:
    config = manager_task(manager, "proposed", frame_skip=frame_skip, worker="paper")
    view = DeployView(manager, len(robots), config)
    return Controller(view, Tracker(), "blue", list(robots), feedback=feedback)


def _see(controller: Controller, t: float, *robots: tuple[int, float, float, float]) -> None:
    seen = tuple(Detection("blue", r, x, y, a) for r, x, y, a in robots)
    controller.on_frame(DetectionFrame(t, t, 0, seen), arrival=t)


def test_a_seen_robot_with_a_target_drives_toward_it_in_its_own_frame() -> None:
    controller = _controller()
    controller.set_target(0, [1.0, 0.0, 0.0])
    _see(controller, 0.0, (0, 0.0, 0.0, np.pi / 2))  # facing +y: the target lies to its right
    [(robot, forward, left, _)] = controller.tick(0.01)
    assert robot == 0 and left < 0 and abs(forward) < abs(left)


def test_decisions_come_every_frame_skip_periods_and_on_a_new_target() -> None:
    controller = _controller(frame_skip=4)
    calls = []
    decide = controller.view.decide
    controller.view.decide = lambda s, live, rules: (calls.append(live.copy()), decide(s, live, rules))
    controller.set_target(0, [1.0, 0.0, 0.0])
    for k in range(9):
        _see(controller, k * 0.025, (0, 0.0, 0.0, 0.0))
        controller.tick(k * 0.025 + 0.001)
        if k == 5:
            controller.set_target(0, [-1.0, 0.0, 0.0])
    assert len(calls) == 3  # periods 0, 4 (frame skip) and 6 (the target changed after period 5)
    np.testing.assert_allclose(controller.view.subgoal[0, 0, 0:2], [-1.0, 0.0])


def test_unseen_stale_and_targetless_robots_get_zero_commands() -> None:
    controller = _controller(robots=(0, 1, 2))
    controller.set_target(0, [1.0, 1.0, 0.0])
    controller.set_target(1, [-1.0, 1.0, 0.0])  # robot 2 has no target
    _see(controller, 0.0, (0, 0.0, 0.0, 0.0), (1, 0.5, 0.0, 0.0), (2, -0.5, 0.0, 0.0))
    commands = {robot: rest for robot, *rest in controller.tick(0.01)}
    assert any(commands[0]) and any(commands[1]) and not any(commands[2])
    _see(controller, 0.03, (0, 0.0, 0.0, 0.0))  # robot 1 drops out of sight
    commands = {robot: rest for robot, *rest in controller.tick(MAX_AGE * 0.9)}
    assert any(commands[0]) and any(commands[1])  # robot 1 seen 45 ms ago: still fresh
    commands = {robot: rest for robot, *rest in controller.tick(MAX_AGE * 1.1)}
    assert any(commands[0]) and not any(commands[1])
    assert controller.tick(10.0) == [(0, 0.0, 0.0, 0.0), (1, 0.0, 0.0, 0.0), (2, 0.0, 0.0, 0.0)]
    assert controller.stop() == [(0, 0.0, 0.0, 0.0), (1, 0.0, 0.0, 0.0), (2, 0.0, 0.0, 0.0)]


@pytest.mark.parametrize(
    ("robot", "target", "message"),
    [
        (3, [0, 0, 0], "robot 3 is not a controlled robot"),
        (True, [0, 0, 0], "robot True is not a controlled robot"),
        ("0", [0, 0, 0], "robot '0' is not a controlled robot"),
        (0, [0, 0], r"expected \[x, y, theta\]"),
        (0, "1,2,3", r"expected \[x, y, theta\]"),
        (0, [0, float("nan"), 0], "finite numbers"),
        (0, [0, True, 0], "finite numbers"),
        (0, [9.0, 0, 0], r"at \[9.0, 0.0\] is outside the walls \(\+-\[3.21, 2.21\] m\)$"),
    ],
)
def test_bad_targets_are_refused_by_name(robot: object, target: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        _controller().set_target(robot, target)


@pytest.mark.parametrize(
    ("feedback", "speeds", "after"),
    [
        ("model", [0.1, 0.175, 0.25], 0.25),  # the robot gains 0.075 m/s a period (3 m/s^2), then brakes
        ("command", [0.1, 0.2, 0.3], 0.1),
    ],
)
def test_the_worker_steers_from_the_modelled_robot_or_the_last_command(
    feedback: str, speeds: list, after: float
) -> None:
    # The paper worker adds 0.1 m/s a period to the velocity it steers from; the robot is seen standing.
    controller = _controller(feedback=feedback)
    controller.set_target(0, [2.0, 0.0, 0.0])
    got = []
    for k in range(3):
        _see(controller, k * 0.025, (0, 0.0, 0.0, 0.0))
        got.append(controller.tick(k * 0.025 + 0.001)[0][1])
    np.testing.assert_allclose(got, speeds, atol=1e-9)
    assert controller.tick(1.0) == [(0, 0.0, 0.0, 0.0)]  # out of sight: stopped
    _see(controller, 1.01, (0, 0.0, 0.0, 0.0))
    assert controller.tick(1.011)[0][1] == pytest.approx(after)


def test_the_tracked_velocity_follows_the_commands_sent_as_far_as_vision_agrees() -> None:
    # The robot is seen standing while commanded to speed up (held by something): the tracker's velocity,
    # told the commands, moves off towards the model's but vision pulls it back.
    controller = _controller(feedback="tracked")
    controller.set_target(0, [2.0, 0.0, 0.0])
    got = []
    for k in range(3):
        _see(controller, k * 0.025, (0, 0.0, 0.0, 0.0))
        got.append(controller.tick(k * 0.025 + 0.001)[0][1])
    assert got[0] == pytest.approx(0.1)
    assert 0.1 < got[1] < 0.175 and got[1] < got[2] < 0.25  # the model's: 0.175, 0.25


def test_the_modelled_robot_answers_commands_as_the_world_does() -> None:
    world = World(1, 1)
    world.set_state(np.array([0]), np.zeros((1, 1, 2)), np.zeros((1, 1)))
    view = DeployView("direct", 1, manager_task("direct", "proposed"))
    vel, spin = np.zeros((1, 1, 2)), np.zeros((1, 1))
    # Accelerating while turning, braking, then past the acceleration limit in both axes.
    for command in [(1.0, 0.5, 3.0)] * 6 + [(0.0, 0.0, 0.0)] * 3 + [(2.4, -1.0, 0.0)] * 4:
        sent = np.array(command)[None, None]
        vel, spin = view.respond(vel, spin, sent, world.state.angle.copy())
        state = world.step(sent)
        np.testing.assert_allclose(vel, state.vel, atol=1e-6)
        np.testing.assert_allclose(spin, state.ang_vel, atol=1e-6)


def test_a_new_target_takes_the_modelled_velocity_from_the_tracker() -> None:
    controller = _controller(feedback="model")
    controller.set_target(0, [2.0, 0.0, 0.0])
    for k in range(3):  # the model believes the robot speeds up: 0.225 m/s
        _see(controller, k * 0.025, (0, 0.0, 0.0, 0.0))
        controller.tick(k * 0.025 + 0.001)
    controller.set_target(0, [2.0, 0.0, 0.0])  # e.g. a new episode: the robot was put down, standing
    _see(controller, 0.075, (0, -1.0, 0.0, 0.0))  # past the gate: its filter restarts, standing
    # The tracker's 0 m/s, 1 ms on at the last command's 3 m/s^2, plus the worker's 0.1 m/s.
    assert controller.tick(0.076)[0][1] == pytest.approx(0.1 + 3.0 * 0.001)


def test_robots_must_be_distinct() -> None:
    view = DeployView("direct", 2, manager_task("direct", "proposed"))
    with pytest.raises(ValueError, match="distinct ids"):
        Controller(view, Tracker(), "blue", [1, 1])
    with pytest.raises(ValueError, match="worker feedback 'odometry'"):
        Controller(view, Tracker(), "blue", [1, 2], feedback="odometry")


@pytest.mark.parametrize("name", ["division_b", "division_a"])
def test_a_manager_trained_on_a_division_field_plans_on_the_whole_of_it(name: str) -> None:
    config = task_config(manager_task("direct", "proposed", worker="paper"), field=name)
    controller = Controller(DeployView("direct", 1, config), Tracker(), "blue", [0])
    fld = get_field(name)
    # Its whole field and margin up to a robot radius from the walls, corners included: no smaller field's.
    hx, hy = fld.half_length + fld.boundary_width - 0.1, fld.half_width + fld.boundary_width - 0.1
    for corner in ([hx, hy, 0.0], [-hx, -hy, 0.0]):
        controller.set_target(0, corner)
    with pytest.raises(ValueError, match="outside the walls"):
        controller.set_target(0, [hx + 0.02, 0.0, 0.0])
    # The cameras' geometry of that field is the manager's own: accepted.
    check_field(parse_vision(encode_geometry(fld)), controller.view.field)


def test_the_controller_tells_a_free_kicks_ball_in_play_itself() -> None:
    # Rules 5.4: the game controller keeps sending the free kick; the ball 5 cm from where it was seen when
    # the kick was first heard, or 10 s after (Division B), the kick is played as the running game.
    field = get_field("division_b")
    watch = InPlayWatch(field)
    kick = referee_state(DIRECT_FREE_BLUE, field)
    assert watch(kick, 0.0, (1.0, 0.0)) is kick  # heard with the ball at (1, 0)
    assert not watch(referee_state(DIRECT_FREE_BLUE, field), 1.0, (1.04, 0.0)).in_play.any()  # a new message
    played = watch(kick, 1.1, (1.06, 0.0))
    assert played.in_play.tolist() == [True] and played.command.tolist() == [DIRECT_FREE_BLUE]
    assert watch(kick, 1.2, (1.0, 0.0)) is played  # in play stays in play, one object while it holds
    running = referee_state(FORCE_START, field)
    assert watch(running, 2.0, (1.0, 0.0)) is running
    # The next kick, its ball never seen: in play after 10 s of it, by the time alone.
    assert not watch(kick, 3.0, None).in_play.any() and not watch(kick, 12.9, None).in_play.any()
    assert watch(kick, 13.0, None).in_play.tolist() == [True]
    division_a = InPlayWatch(get_field("division_a"))  # 5 s there
    assert division_a(kick, 0.0, None) is kick and division_a(kick, 5.0, None).in_play.tolist() == [True]
