"""The controller loop over 127.0.0.1: fuzzed and foreign packets never move a robot, lost vision stops
it within 100 ms, and the control socket takes well-formed targets only."""

from __future__ import annotations

import json
import os
import socket
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from hier_ssl.deploy import wire
from hier_ssl.deploy.assemble import DeploySettings, build_loop
from hier_ssl.deploy.loop import GATHER, PRIORITY, REPORT_EVERY, DeployLoop, WorldTime
from hier_ssl.deploy.net import MAX_LINE
from hier_ssl.world.field import get_field

FUZZED = 10_000


class Robots:
    """The commands' receiving end: a UDP socket on 127.0.0.1 collecting (time, commands) of grSim."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.received: list[tuple[float, list]] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._collect)
        self.thread.start()

    def _collect(self) -> None:
        while not self.stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            self.received.append((time.monotonic(), wire.parse_grsim(data)[1]))

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.sock.close()

    def moving(self) -> list[tuple[float, list]]:
        return [(t, c) for t, c in self.received if any(any(cmd[1:]) for cmd in c)]


@pytest.fixture
def robots() -> Iterator[Robots]:
    receiver = Robots()
    yield receiver
    receiver.close()


def _loop(
    robots: Robots, source: str = "127.0.0.1", priority: int = PRIORITY, lockstep: bool = False
) -> DeployLoop:
    settings = DeploySettings(
        "direct",
        "127.0.0.1:0",
        f"grsim:127.0.0.1:{robots.port}",
        "blue",
        [0],
        {0: [1.0, 0.5, 0.0]},
        source=source,
        control_port=0,
        task="proposed",
        priority=priority,
        lockstep=lockstep,
    )
    return build_loop(settings)


class Running:
    """The loop in a thread, and a vision socket on 127.0.0.1 to feed it."""

    def __init__(self, loop: DeployLoop) -> None:
        self.loop, self.stop = loop, threading.Event()
        self.thread = threading.Thread(target=loop.run, args=(self.stop,))
        self.thread.start()
        self.vision = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.vision.bind(("127.0.0.1", 0))
        self.to = ("127.0.0.1", loop.vision.getsockname()[1])

    def send(self, data: bytes) -> None:
        self.vision.sendto(data, self.to)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.vision.close()
        self.loop.close()


def _frame(t: float, team: str = "blue", robot: int = 0) -> bytes:
    seen = (wire.Detection(team, robot, 0.0, 0.0, 0.0),)
    # frame_number is a uint32: a UNIX time counted in 60 Hz frames overflows it
    return wire.encode_detection(int(t * 60) % 2**32, wire.DetectionFrame(t, t, 0, seen))


def _fuzz(rng: np.random.Generator) -> Iterator[bytes]:
    """Random bytes, truncated and corrupted valid packets (one byte changed: of other robots only, so
    no change can name the controlled one), oversized ones, and valid ones of other teams' robots."""
    bases = [_frame(1.0 + k, "yellow", 5 + k % 5) for k in range(20)]
    bases.append(wire.encode_geometry(get_field("hardware_challenge")))
    for k in range(FUZZED):
        base = bases[k % len(bases)]
        kind = k % 5
        if kind == 0:
            yield rng.bytes(int(rng.integers(0, 300)))
        elif kind == 1:
            yield base[: int(rng.integers(0, len(base)))]
        elif kind in (2, 3):
            data = bytearray(base)
            data[int(rng.integers(len(data)))] = int(rng.integers(256))
            yield bytes(data)
        elif k % 100 == 4:
            yield rng.bytes(wire.MAX_PACKET + 1 + int(rng.integers(1000)))
        else:
            yield base


def test_ten_thousand_fuzzed_packets_neither_crash_the_loop_nor_move_a_robot(robots: Robots) -> None:
    running = Running(_loop(robots))
    try:
        for k, data in enumerate(_fuzz(np.random.default_rng(0))):
            running.send(data)
            if k % 200 == 199:
                time.sleep(0.003)  # the loop reads as fast as this sends, a burst at a time
        time.sleep(0.2)
        assert running.thread.is_alive()
    finally:
        running.close()
    stats = running.loop.stats
    assert stats.frames + stats.geometry + sum(stats.dropped.values()) == FUZZED  # every one accounted for
    assert stats.dropped["malformed"] > 4000 and stats.dropped["oversized"] == 100
    assert stats.moving_commands == 0 and not robots.moving()
    assert robots.received  # the loop kept sending its stops


def test_packets_from_another_source_are_dropped_and_move_nothing(robots: Robots) -> None:
    running = Running(_loop(robots, source="10.0.0.7"))  # only compared, never contacted
    try:
        for k in range(30):
            running.send(_frame(k / 60))
            time.sleep(1 / 60)
    finally:
        running.close()
    assert running.loop.stats.dropped["source"] == 30 and running.loop.stats.frames == 0
    assert not robots.moving()


def test_drops_are_reported_while_they_happen_at_most_once_a_second(robots: Robots) -> None:
    loop, lines = _loop(robots, source="10.0.0.7"), []
    loop.report = lines.append
    running = Running(loop)
    try:
        for k in range(150):  # 2.5 s of frames at 60 Hz, every one from the wrong source
            running.send(_frame(k / 60))
            time.sleep(1 / 60)
    finally:
        running.close()
    assert 2 <= len(lines) <= 3, lines
    counts = []
    for line in lines:
        words = line.split()
        assert words[0] == "dropped" and words[2:4] == ["datagrams", "in"] and float(words[4]) >= REPORT_EVERY
        assert line.endswith(f"(source {words[1]})")
        counts.append(int(words[1]))
    assert sum(counts) <= loop.stats.dropped["source"] == 150 and min(counts) > 30


def test_a_robot_out_of_sight_is_stopped_within_100_ms(robots: Robots) -> None:
    running = Running(_loop(robots))
    try:
        start = time.monotonic()
        while time.monotonic() - start < 0.5:
            running.send(_frame(time.time()))
            time.sleep(1 / 60)
        lost = time.monotonic()
        time.sleep(0.3)
    finally:
        running.close()
    assert robots.moving(), "the robot never drove"
    after = [(t, c) for t, c in robots.received if t > lost]
    first_stop = next(t for t, c in after if not any(c[0][1:]))
    assert first_stop - lost < 0.1
    assert all(not any(c[0][1:]) for t, c in after if t >= first_stop)


def _ask(client: socket.socket, line: bytes) -> dict:
    client.sendall(line + b"\n")
    return json.loads(client.makefile().readline())


def test_the_control_socket_listens_on_loopback_and_takes_only_target_messages(robots: Robots) -> None:
    running = Running(_loop(robots))
    control = running.loop.control
    try:
        assert control.listener.getsockname()[0] == "127.0.0.1"
        with socket.create_connection(("127.0.0.1", control.port), timeout=2) as client:
            assert _ask(client, b'{"robot": 0, "target": [-1.0, 0.25, 1.5]}') == {"ok": True}
            for bad in (
                b"not json",
                b"[0, [1, 2, 3]]",
                b'{"robot": 0}',
                b'{"robot": 0, "target": [1, 2, 3], "extra": 1}',
                b'{"robot": 7, "target": [1, 2, 3]}',
                b'{"robot": 0, "target": [1e9, 0, 0]}',
                b"\xff\xfe",
            ):
                assert "error" in _ask(client, bad), bad
        np.testing.assert_allclose(running.loop.controller.view.target[0, 0, 0:3], [-1.0, 0.25, 1.5])
        with socket.create_connection(("127.0.0.1", control.port), timeout=2) as client:
            client.sendall(b"x" * (2 * MAX_LINE))
            answer = client.makefile().readline()
            assert "longer than" in answer
            assert client.recv(10) == b""  # closed by the loop
    finally:
        running.close()
    assert (control.accepted, control.refused) == (1, 8)


@pytest.mark.parametrize("priority", [PRIORITY, 0])
def test_the_loop_ticks_under_the_real_time_scheduler_where_permitted_and_restores_it(
    robots: Robots, priority: int
) -> None:
    loop = _loop(robots, priority=priority)
    policies, tick = [], loop.controller.tick
    loop.controller.tick = lambda now: policies.append(os.sched_getscheduler(0)) or tick(now)
    try:
        stats = loop.run(threading.Event(), duration=0.2)
    finally:
        loop.close()
    assert len(policies) >= 4 and os.sched_getscheduler(0) == os.SCHED_OTHER
    if priority and stats.scheduling == f"fifo {priority}":
        assert set(policies) == {os.SCHED_FIFO}
    else:  # asked for time-sharing, or not permitted (no CAP_SYS_NICE): the loop runs on, time-shared
        assert stats.scheduling.startswith("time-shared (asked" if priority == 0 else "time-shared (not")
        assert set(policies) == {os.SCHED_OTHER}


def test_a_priority_out_of_range_is_refused_naming_it(robots: Robots) -> None:
    with pytest.raises(ValueError, match="priority 100"):
        _loop(robots, priority=100)


def test_lockstep_ticks_once_per_world_time_when_every_camera_sent_its_frame() -> None:
    world = WorldTime()
    assert not world.ready(0.0)
    world.add(wire.DetectionFrame(1.0, 1.0, 0, ()), 10.0)
    world.add(wire.DetectionFrame(1.0, 1.0, 1, ()), 10.001)
    assert world.ready(10.001) and world.newest == 10.001
    world.ticked = 1.0
    world.add(wire.DetectionFrame(1.0, 1.0, 1, ()), 10.002)  # a second frame of the world time ticked on
    assert not world.ready(10.002)
    world.add(wire.DetectionFrame(1.025, 1.025, 0, ()), 10.01)
    assert not world.ready(10.01)  # camera 1's frame of 1.025 has not come yet
    assert not world.ready(10.01 + GATHER / 2) and world.ready(10.011 + GATHER)  # nor for longer
    world.add(wire.DetectionFrame(1.0, 1.0, 1, ()), 10.011)  # an older world time: not the newest
    assert world.seen == {0} and world.newest == 10.01


def test_in_lockstep_the_loop_ticks_once_per_world_step_and_stops_a_robot_out_of_sight(
    robots: Robots,
) -> None:
    # A world that takes 40 ms of wall-clock time per 25 ms step: one command per step, none on the loop's
    # own clock while frames come; once they stop, the stop within 100 ms.
    running = Running(_loop(robots, lockstep=True))
    try:
        steps, epoch = 15, time.time()  # world time starts at UNIX time, as the field server's does
        for k in range(steps):
            sent = time.monotonic()
            running.send(_frame(epoch + k * 0.025))
            time.sleep(0.04)
        time.sleep(0.3)
    finally:
        running.close()
    moving = robots.moving()
    assert len(moving) == steps and sent < moving[-1][0] < sent + 0.02  # the last step's command
    after = [(t, c) for t, c in robots.received if t > moving[-1][0]]
    assert all(not any(c[0][1:]) for t, c in after) and after[0][0] - sent < 0.1


def test_the_simulators_errors_are_counted_each_and_logged_at_most_once_a_second(
    robots: Robots, caplog: pytest.LogCaptureFixture
) -> None:
    loop = _loop(robots)
    now = [100.0]
    loop.clock = lambda: now[0]
    error = wire.encode_response([("ROBOT_NOT_FOUND", "no robot 7")])
    simulator = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        with caplog.at_level("WARNING", logger="hier_ssl.deploy.loop"):
            for t in (100.0, 100.5, 100.99, 101.0, 101.5):
                now[0] = t
                simulator.sendto(error, loop.sender.sock.getsockname())
                time.sleep(0.01)  # loopback delivers it by then
                loop._read_responses()
    finally:
        simulator.close()
        loop.close()
    assert loop.stats.simulator_errors == {"ROBOT_NOT_FOUND: no robot 7": 5}
    assert [r.getMessage() for r in caplog.records] == [
        "simulator: ROBOT_NOT_FOUND: no robot 7 (1 so far)",
        "simulator: ROBOT_NOT_FOUND: no robot 7 (4 so far)",
    ]


def test_cameras_on_another_field_than_the_managers_end_the_run_with_the_field_error(robots: Robots) -> None:
    loop = _loop(robots)  # "proposed": trained on the hardware-challenge field, 6 x 4 m
    vision = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        vision.sendto(wire.encode_geometry(get_field("hardware_challenge")), loop.vision.getsockname())
        for _ in range(3):
            vision.sendto(wire.encode_geometry(get_field("division_b")), loop.vision.getsockname())
        with pytest.raises(
            ValueError, match=r"field_length 9\.0, .*\(hardware_challenge: field_length 6\.0, "
        ):
            loop.run(threading.Event(), duration=5.0)
    finally:
        vision.close()
        loop.close()
    assert loop.stats.geometry == 1 and loop.stats.dropped["field"] == 2
    time.sleep(0.05)
    assert robots.received and not robots.moving()  # the run's end stopped the robot
