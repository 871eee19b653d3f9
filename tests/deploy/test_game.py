"""The controller under the game controller: which referee packets are taken, the rules planned with (the
keeper from the team info, STOP held when the referee is silent), and the loop over 127.0.0.1: HALT stops on
the next tick, STOP slows every robot within a second, garbage on the referee port moves nothing."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from hier_ssl.deploy import wire
from hier_ssl.deploy.assemble import DeploySettings, build_loop
from hier_ssl.deploy.cameras import Cameras
from hier_ssl.deploy.controller import Controller
from hier_ssl.deploy.field import FieldServer
from hier_ssl.deploy.game import SILENCE, RefereeInput
from hier_ssl.deploy.guard import RELEARN
from hier_ssl.deploy.loop import DeployLoop
from hier_ssl.deploy.referee import RefereeMessage, encode_referee
from hier_ssl.deploy.tracker import Tracker
from hier_ssl.deploy.view import DeployView, manager_task
from hier_ssl.envs import task_config
from hier_ssl.game.legal import SPEED_MARGIN
from hier_ssl.game.referee import FORCE_START, HALT, STOP, referee_state
from hier_ssl.game.zones import STOP_SPEED, defense_box
from hier_ssl.world.field import get_field

UNIX = 1.76e9


def _message(command: str, counter: int, sent: float, blue_keeper: int = 0, **extra: object) -> bytes:
    return encode_referee(
        RefereeMessage(
            sent=sent,
            command=command,
            counter=counter,
            issued=sent,
            stage="NORMAL_FIRST_HALF",
            keepers={"blue": blue_keeper, "yellow": 0},
            **extra,
        )
    )


@pytest.fixture
def referee_input() -> Iterator[RefereeInput]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    taken = RefereeInput(sock, "127.0.0.1", get_field(task_config("proposed").field))
    yield taken
    taken.close()


def test_referee_packets_no_game_controller_sends_are_dropped_by_reason(referee_input: RefereeInput) -> None:
    take = referee_input.take
    assert take(_message("HALT", 7, UNIX), "127.0.0.1", 10.0, UNIX) is None
    assert take(_message("HALT", 7, UNIX), "10.0.0.9", 10.1, UNIX + 0.1) == "source"
    assert take(b"\x08\x01garbage", "127.0.0.1", 10.1, UNIX + 0.1) == "malformed"
    assert take(_message("HALT", 6, UNIX + 0.1), "127.0.0.1", 10.1, UNIX + 0.1) == "counter"
    assert take(_message("HALT", 7 + 2**31, UNIX + 0.1), "127.0.0.1", 10.1, UNIX + 0.1) == "counter"
    # One changed byte must not turn a HALT into a start: a new command comes with a new count.
    assert (
        take(_message("FORCE_START", 7, UNIX + 0.1), "127.0.0.1", 10.1, UNIX + 0.1)
        == "command without counter"
    )
    assert take(_message("HALT", 8, UNIX + 1e6), "127.0.0.1", 10.2, UNIX + 0.2) == "time"
    assert take(_message("HALT", 8, 0.0), "127.0.0.1", 10.2, UNIX + 0.2) == "time"
    assert take(_message("FORCE_START", 8, UNIX + 0.2), "127.0.0.1", 10.2, UNIX + 0.2) is None
    assert referee_input.current(10.3).command.tolist() == [3]  # FORCE_START
    assert referee_input.accepted == 2


def test_the_referee_counter_wraps_past_2_32_forward(referee_input: RefereeInput) -> None:
    take = referee_input.take
    assert take(_message("STOP", 2**32 - 1, UNIX), "127.0.0.1", 10.0, UNIX) is None
    assert take(_message("HALT", 0, UNIX + 0.1), "127.0.0.1", 10.1, UNIX + 0.1) is None
    assert take(_message("STOP", 2**32 - 1, UNIX + 0.2), "127.0.0.1", 10.2, UNIX + 0.2) == "counter"


def test_a_restarted_game_controller_is_followed_after_agreeing_packets(referee_input: RefereeInput) -> None:
    take = referee_input.take
    assert take(_message("FORCE_START", 500, UNIX), "127.0.0.1", 10.0, UNIX) is None
    taken = [take(_message("HALT", 1, UNIX + k / 10), "127.0.0.1", 10 + k / 10, UNIX) for k in range(RELEARN)]
    assert taken == ["counter"] * (RELEARN - 1) + [None]
    assert referee_input.current(10.5).command.tolist() == [HALT]


def test_a_silent_referee_holds_the_team_at_stop_with_its_keeper(referee_input: RefereeInput) -> None:
    assert referee_input.current(0.0).command.tolist() == [STOP]  # nothing heard yet
    assert (
        referee_input.take(_message("FORCE_START", 1, UNIX, blue_keeper=4), "127.0.0.1", 10.0, UNIX) is None
    )
    assert referee_input.current(10.0 + SILENCE).command.tolist() == [3]
    held = referee_input.current(10.0 + SILENCE + 0.01)
    assert held.command.tolist() == [STOP] and held.keeper.tolist() == [[0, 4]]
    assert referee_input.current(10.0 + SILENCE + 0.5) is held  # one state: the rules are not rebuilt


def _see(controller: Controller, t: float, *robots: tuple[int, float, float]) -> None:
    seen = tuple(wire.Detection("blue", r, x, y, 0.0) for r, x, y in robots)
    controller.on_frame(wire.DetectionFrame(t, t, 0, seen), arrival=t)


def test_the_keeper_named_by_the_referee_may_enter_its_defense_area_and_a_new_keeper_replaces_it(
    referee_input: RefereeInput,
) -> None:
    config = manager_task("direct", "proposed", frame_skip=4, worker="paper")
    controller = Controller(DeployView("direct", 2, config), Tracker(), "blue", [0, 1], feedback="command")
    field = controller.view.field
    box = defense_box(field, np.array(-1.0))  # blue defends negative x (no blue_team_on_positive_half)
    inside = [(box[0] + box[2]) / 2, 0.0]
    controller.set_target(0, [*inside, 0.0])
    controller.set_target(1, [0.0, 1.0, 0.0])
    for k, keeper in enumerate((0, 1)):
        assert (
            referee_input.take(_message("STOP", k, UNIX + k, blue_keeper=keeper), "127.0.0.1", k, UNIX + k)
            is None
        )
        controller.referee = referee_input.current(float(k))
        _see(controller, k + 0.01, (0, -1.0, 0.0), (1, 1.0, 0.0))
        controller.tick(k + 0.02)
        subgoal = controller.view.subgoal[0, 0, 0:2]
        in_box = box[0] <= subgoal[0] <= box[2] and box[1] <= subgoal[1] <= box[3]
        assert in_box == (keeper == 0), (keeper, subgoal)


def test_a_referee_repeating_itself_leaves_the_decisions_every_frame_skip_and_a_new_command_decides() -> None:
    # A field server sends its state every period, each message a new object: the decisions keep their
    # period, as in the direct loop, and only a new call brings one forward.
    config = manager_task("direct", "proposed", frame_skip=4, worker="paper")
    controller = Controller(DeployView("direct", 1, config), Tracker(), "blue", [0], feedback="command")
    field = controller.view.field
    controller.set_target(0, [2.0, 0.0, 0.0])
    decided = []
    for k in range(10):
        controller.referee = referee_state(STOP if k >= 6 else FORCE_START, field)
        _see(controller, k * 0.025, (0, -2.0, 0.0))
        controller.tick(k * 0.025 + 0.001)
        decided.append(controller.since_decision == 1)
    assert np.flatnonzero(decided).tolist() == [0, 4, 6]


def test_halt_sends_zero_commands_and_stop_caps_the_commanded_speed() -> None:
    config = manager_task("direct", "proposed", frame_skip=4, worker="paper")
    controller = Controller(DeployView("direct", 1, config), Tracker(), "blue", [0], feedback="command")
    field = controller.view.field
    controller.set_target(0, [2.0, 0.0, 0.0])
    for k in range(40):  # a second of driving: the worker speeds up from the command it sent
        _see(controller, k * 0.025, (0, -2.0, 0.0))
        [(_, forward, left, _)] = controller.tick(k * 0.025 + 0.001)
    assert np.hypot(forward, left) > STOP_SPEED  # far from its target, it asks for more than STOP allows
    controller.referee = referee_state(STOP, field)
    _see(controller, 1.0, (0, -2.0, 0.0))
    [(_, forward, left, _)] = controller.tick(1.001)
    assert np.hypot(forward, left) <= SPEED_MARGIN * STOP_SPEED + 1e-9
    controller.referee = referee_state(HALT, field)
    assert controller.tick(1.002) == [(0, 0.0, 0.0, 0.0)]


class Game:
    """The deploy loop (direct planner, blue robot 0, ``--referee`` on 127.0.0.1), the lockstep field
    server and a game controller sending ``command`` every 50 ms, each in its thread."""

    def __init__(self) -> None:
        settings = DeploySettings(
            "direct", "127.0.0.1:0", "grsim:127.0.0.1:9", "blue", [0], {}, control_port=0, task="proposed"
        )
        settings.lockstep, settings.referee, settings.priority = True, "127.0.0.1:0", 0
        self.loop: DeployLoop = build_loop(settings)
        cameras = Cameras(rate=60.0, pos_noise=0.0, angle_noise=0.0)
        port = self.loop.vision.getsockname()[1]
        self.server = FieldServer(
            task_config("proposed"),
            port,
            "blue",
            cameras,
            control_port=self.loop.control.port,
            seed=3,
            lockstep=True,
        )
        self.loop.sender.address = ("127.0.0.1", self.server.grsim_port)
        self.ticks: list[tuple[float, str | None, list]] = []  # (time, message in force, commands)
        self.speeds: list[tuple[float, float]] = []  # (time, robot 0's speed) after each world step
        tick, step = self.loop.controller.tick, self.server.core.control_step

        def recorded_tick(now: float) -> list:
            commands = tick(now)
            message = self.loop.referee.message
            self.ticks.append((time.monotonic(), None if message is None else message.command, commands))
            self.held.append((time.monotonic(), int(self.loop.controller.referee.command[0]), commands))
            return commands

        def recorded_step(*args: object, **kwargs: object) -> tuple:
            out = step(*args, **kwargs)
            self.speeds.append((time.monotonic(), float(np.hypot(*self.server.core.world.state.vel[0, 0]))))
            return out

        self.loop.controller.tick, self.server.core.control_step = recorded_tick, recorded_step
        self.command, self.counter, self.stop = "FORCE_START", 0, threading.Event()
        self.silent = threading.Event()  # set: the game controller sends nothing
        self.held: list[tuple[float, int, list]] = []  # (time, the command the controller plays, commands)
        self.gc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.gc.bind(("127.0.0.1", 0))
        self.to = ("127.0.0.1", self.loop.referee.sock.getsockname()[1])
        self.threads = [
            threading.Thread(target=self.loop.run, args=(self.stop, 20.0)),
            threading.Thread(target=self.server.run, args=(None, self.stop)),
            threading.Thread(target=self._referee),
        ]

    def _referee(self) -> None:
        while not self.stop.wait(0.05):
            if not self.silent.is_set():
                self.gc.sendto(_message(self.command, self.counter, time.time()), self.to)

    def say(self, command: str) -> float:
        self.command, self.counter = command, self.counter + 1
        self.gc.sendto(_message(command, self.counter, time.time()), self.to)
        return time.monotonic()

    def __enter__(self) -> Game:
        for thread in self.threads:
            thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.stop.set()
        for thread in self.threads:
            thread.join()
        self.server.close()
        self.loop.close()
        self.gc.close()


def _wait(condition: object, timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while not condition() and time.monotonic() < end:
        time.sleep(0.005)
    assert condition(), "timed out"


def test_halt_sends_zero_commands_from_the_next_tick_on_loopback() -> None:
    with Game() as game:
        _wait(lambda: any(any(c[0][1:]) and m == "FORCE_START" for _, m, c in game.ticks))
        game.say("HALT")
        _wait(lambda: sum(m == "HALT" for _, m, _c in game.ticks) >= 20)
    halted = [c for _, m, c in game.ticks if m == "HALT"]
    assert halted and all(c == [(0, 0.0, 0.0, 0.0)] for c in halted)  # every tick once HALT was taken
    assert not game.loop.stats.dropped


def test_stop_mid_run_slows_every_robot_below_the_stop_speed_within_a_second_on_loopback() -> None:
    with Game() as game:
        _wait(lambda: game.speeds and game.speeds[-1][1] > STOP_SPEED + 0.3)  # driving faster than STOP's
        said = game.say("STOP")
        _wait(lambda: len([t for t, _ in game.speeds if t > said]) >= 60)  # 1.5 s of world time
    after = [speed for t, speed in game.speeds if t > said]
    # World steps of 25 ms: 40 of them are a second of game time, however fast the lockstep world ran.
    assert max(after[40:]) < STOP_SPEED
    assert any(m == "STOP" for _, m, _c in game.ticks)


def _fuzz(rng: np.random.Generator, valid: bytes, command_at: int, count: int) -> Iterator[bytes]:
    """Random bytes, one byte of ``valid`` changed anywhere, its command byte (at ``command_at``) set to
    any command's number (the change that could start the robots), ``valid`` truncated."""
    for k in range(count):
        kind, data = k % 4, bytearray(valid)
        if kind == 0:
            yield rng.bytes(int(rng.integers(0, 200)))
        elif kind in (1, 2):
            data[command_at if kind == 2 else int(rng.integers(len(data)))] = int(
                rng.integers(256 if kind == 1 else 20)
            )
            yield bytes(data)
        else:
            yield valid[: int(rng.integers(0, len(valid)))]


def test_garbage_on_the_referee_port_crashes_nothing_and_moves_no_robot() -> None:
    # HALT is in force and robot 0, in sight, has a target: only a packet read as a start could move it.
    settings = DeploySettings(
        "direct", "127.0.0.1:0", "grsim:127.0.0.1:9", "blue", [0], {0: [1.0, 0.5, 0.0]}, task="proposed"
    )
    settings.referee, settings.priority = "127.0.0.1:0", 0
    loop = build_loop(settings)
    vision, gc = (socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2))
    for sock in (vision, gc):
        sock.bind(("127.0.0.1", 0))
    to_vision = ("127.0.0.1", loop.vision.getsockname()[1])
    to_referee = ("127.0.0.1", loop.referee.sock.getsockname()[1])
    stop = threading.Event()
    thread = threading.Thread(target=loop.run, args=(stop, 20.0))
    thread.start()
    sent, rng = 0, np.random.default_rng(5)
    try:
        gc.sendto(_message("HALT", 1, time.time()), to_referee)
        sent += 1
        _wait(lambda: loop.referee.accepted == 1)
        start = time.monotonic()
        now = time.time()
        halt, stop_ = _message("HALT", 1, now), _message("STOP", 1, now)
        command_at = next(i for i, (a, b) in enumerate(zip(halt, stop_, strict=True)) if a != b)
        for k, data in enumerate(_fuzz(rng, halt, command_at, 3000)):
            gc.sendto(data, to_referee)
            sent += 1
            if k % 50 == 0:  # the game controller's own HALT, and a camera frame of the robot
                gc.sendto(_message("HALT", 1, time.time()), to_referee)
                sent += 1
                frame = wire.DetectionFrame(
                    time.time(), time.time(), 0, (wire.Detection("blue", 0, 0.0, 0.0, 0.0),)
                )
                vision.sendto(wire.encode_detection(k, frame), to_vision)
            if k % 50 == 25:  # the loop ticks after fuzzed packets, not only after the game controller's
                time.sleep(0.03)
        time.sleep(0.2)
        assert thread.is_alive() and time.monotonic() - start < 15
    finally:
        stop.set()
        thread.join()
        loop.close()
        vision.close()
        gc.close()
    stats, drops = (
        loop.stats,
        Counter({k: v for k, v in loop.stats.dropped.items() if k.startswith("referee")}),
    )
    assert loop.referee.accepted + sum(drops.values()) == sent  # every packet accounted for
    assert drops["referee malformed"] > 1000 and stats.frames > 0
    assert stats.moving_commands == 0
    assert loop.referee.message.command == "HALT" and drops["referee command without counter"] > 50


def test_vision_brings_the_most_confident_ball_and_refuses_one_no_camera_could_see() -> None:
    frame = wire.DetectionFrame(UNIX, UNIX, 1, (), ball=(1.25, -0.5))
    assert wire.parse_vision(wire.encode_detection(3, frame)) == frame
    packet = wire.ssl_vision_pb2.SSL_WrapperPacket()
    packet.detection.frame_number, packet.detection.camera_id = 1, 0
    packet.detection.t_capture = packet.detection.t_sent = UNIX
    for confidence, x in ((0.2, 100.0), (0.9, -300.0), (0.5, 700.0)):
        ball = packet.detection.balls.add()
        ball.confidence, ball.x, ball.y, ball.pixel_x, ball.pixel_y = confidence, x, 0.0, 0.0, 0.0
    assert wire.parse_vision(packet.SerializeToString()).ball == (-0.3, 0.0)
    packet.detection.balls[0].x = 1e9
    with pytest.raises(wire.PacketError, match="ball"):
        wire.parse_vision(packet.SerializeToString())


def test_under_stop_a_target_by_the_ball_seen_is_moved_off_it_and_a_ball_unseen_moves_nothing() -> None:
    config = manager_task("direct", "proposed", frame_skip=4, worker="paper")
    controller = Controller(DeployView("direct", 1, config), Tracker(), "blue", [0], feedback="command")
    controller.set_target(0, [0.3, 0.0, 0.0])
    controller.referee = referee_state(STOP, controller.view.field)
    seen = (wire.Detection("blue", 0, -1.0, 0.0, 0.0),)
    controller.on_frame(wire.DetectionFrame(0.0, 0.0, 0, seen), arrival=0.0)
    controller.tick(0.01)
    np.testing.assert_allclose(controller.view.subgoal[0, 0, 0:2], [0.3, 0.0])  # no ball seen: no zone
    controller.on_frame(wire.DetectionFrame(0.02, 0.02, 0, seen, ball=(0.4, 0.0)), arrival=0.02)
    controller.set_target(0, [0.3, 0.0, 0.0])
    controller.tick(0.03)
    gap = np.hypot(*(controller.view.subgoal[0, 0, 0:2] - [0.4, 0.0]))
    assert gap >= 0.5 + 0.09  # rules 5.1.1: 0.5 m from the ball, measured from the robot's edge


def test_the_deploy_command_takes_a_referee_address_and_counts_its_drops() -> None:
    root = Path(__file__).parents[2]
    robots = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    robots.bind(("127.0.0.1", 0))
    options = "deploy direct --vision 127.0.0.1:0 --team blue --robots 0 --task proposed --duration 1.0"
    command = [sys.executable, "-m", "hier_ssl.cli", *options.split(), "--referee", "127.0.0.1:0"]
    command += ["--commands", f"grsim:127.0.0.1:{robots.getsockname()[1]}"]
    env = {**os.environ, "PYTHONPATH": str(root)}
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, cwd=root, env=env)
    gc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gc.bind(("127.0.0.1", 0))
    try:
        ports = json.loads(process.stdout.readline())
        to = ("127.0.0.1", ports["referee_port"])
        gc.sendto(_message("HALT", 1, time.time()), to)
        gc.sendto(_message("HALT", 0, time.time()), to)  # the counter went back
        gc.sendto(b"not a referee message", to)
        assert process.wait(timeout=30) == 0
    finally:
        if process.poll() is None:
            process.kill()
        gc.close()
        robots.close()
    summary = json.loads(process.stdout.readline())
    assert summary["dropped"] == {"referee counter": 1, "referee malformed": 1}


@pytest.mark.parametrize("form", ["run", "torchscript"])
def test_a_learned_managers_sub_goal_is_kept_off_the_ball_and_under_the_stop_speed(
    tmp_path: Path, form: str
) -> None:
    from hier_ssl.deploy.bench import untrained_export

    exported = untrained_export(tmp_path, "obstacle")
    manager = str(exported.parent if form == "run" else exported)
    config = manager_task(manager)
    inside = 0
    for k, x in enumerate(np.linspace(-1.5, 1.5, 7)):
        subgoals = []
        for referee in (None, referee_state(STOP, get_field(config.field))):
            controller = Controller(DeployView(manager, 1, config), Tracker(), "blue", [0])
            controller.set_target(0, [-x, 0.8, 0.0])
            controller.referee = referee
            seen = (wire.Detection("blue", 0, x, 0.0, 0.3 * k),)
            controller.on_frame(wire.DetectionFrame(0.0, 0.0, 0, seen, ball=(x + 0.1, 0.0)), arrival=0.0)
            controller.tick(0.01)
            subgoals.append(controller.view.subgoal[0, 0].copy())
        free, ruled = subgoals
        inside += np.hypot(free[0] - x - 0.1, free[1]) < 0.59
        assert np.hypot(ruled[0] - x - 0.1, ruled[1]) >= 0.59  # 0.5 m from the ball plus the robot's radius
        assert np.hypot(*ruled[3:5]) <= STOP_SPEED + 1e-9
    assert inside  # without the rules, the untrained manager put sub-goals by the ball


def test_a_referee_silent_for_a_second_holds_the_robots_at_stop_on_loopback() -> None:
    with Game() as game:
        _wait(lambda: any(any(c[0][1:]) and m == "FORCE_START" for _, m, c in game.ticks))
        game.silent.set()
        muted = time.monotonic()
        _wait(lambda: time.monotonic() > muted + SILENCE + 0.5)
    held = [(command, c) for t, command, c in game.held if t > muted + SILENCE + 0.05]
    assert held and all(command == STOP for command, _ in held)
    speeds = [np.hypot(*c[0][1:3]) for _, c in held]
    assert max(speeds) <= 0.9 * STOP_SPEED + 1e-9 and max(speeds) > 0  # slowed, not halted


@pytest.mark.parametrize(("command", "kept_off"), [("DIRECT_FREE_YELLOW", True), ("DIRECT_FREE_BLUE", False)])
def test_a_free_kick_keeps_only_the_other_team_off_the_ball(
    referee_input: RefereeInput, command: str, kept_off: bool
) -> None:
    config = manager_task("direct", "proposed", frame_skip=4, worker="paper")
    controller = Controller(DeployView("direct", 1, config), Tracker(), "blue", [0], feedback="command")
    controller.set_target(0, [0.3, 0.0, 0.0])
    assert referee_input.take(_message(command, 1, UNIX), "127.0.0.1", 0.0, UNIX) is None
    controller.referee = referee_input.current(0.0)
    seen = (wire.Detection("blue", 0, -1.0, 0.0, 0.0),)
    controller.on_frame(wire.DetectionFrame(0.0, 0.0, 0, seen, ball=(0.4, 0.0)), arrival=0.0)
    controller.tick(0.01)
    gap = np.hypot(*(controller.view.subgoal[0, 0, 0:2] - [0.4, 0.0]))
    assert (gap >= 0.59) == kept_off  # rules 5.3.3: the defending team keeps 0.5 m from the ball
