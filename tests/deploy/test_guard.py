"""Packet times no camera or game controller could send: the clock guard, the frame's own times, the
referee's counter."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from hier_ssl.deploy import wire
from hier_ssl.deploy.assemble import DeploySettings, build_loop
from hier_ssl.deploy.guard import (
    COUNTER_SPAN,
    PLAUSIBLE,
    RELEARN,
    WINDOW,
    ClockGuard,
    FieldGuard,
    counter_went_back,
    frame_times_valid,
)
from hier_ssl.world.field import get_field

UNIX = 1.76e9  # s, a UNIX time of these years
BOOT = 5000.0  # s, a monotonic clock's reading: no relation to UNIX time


def _learned(offset: float = UNIX - BOOT) -> ClockGuard:
    guard = ClockGuard()
    assert guard.accept(BOOT + offset, BOOT, wall=BOOT + offset)
    return guard


@pytest.mark.parametrize("sent", [1e300, -1e300, UNIX - 1e6, UNIX + 2 * WINDOW, UNIX - 2 * WINDOW])
def test_a_frame_whose_time_jumps_is_dropped_and_the_clock_kept(sent: float) -> None:
    guard = _learned(UNIX - BOOT)
    assert not guard.accept(sent, BOOT + 0.016)
    assert guard.accept(UNIX + 0.033, BOOT + 0.035)  # the next real frame: still the learned clock


def test_real_vision_with_its_own_clock_and_jitter_is_accepted() -> None:
    # A vision PC 3.7 s off this machine's UNIX clock, frames every 16.7 ms arriving with 0-4 ms of jitter.
    guard = ClockGuard()
    wall_offset = UNIX - BOOT
    for k in range(600):
        sent = UNIX + 3.7 + k / 60
        arrival = BOOT + k / 60 + 0.004 * ((k * 7) % 5) / 4
        assert guard.accept(sent, arrival, wall=arrival + wall_offset)


def test_lockstep_world_time_running_ahead_and_standing_still_is_accepted() -> None:
    # The field server's world time: 25 ms a step, stepped every 2 ms of wall time, then still for 0.3 s.
    guard, sent, arrival = ClockGuard(), UNIX, BOOT
    assert guard.accept(sent, arrival, wall=UNIX)
    for _ in range(400):  # the world runs 10 s ahead of the wall clock, 23 ms a packet
        sent, arrival = sent + 0.025, arrival + 0.002
        assert guard.accept(sent, arrival)
    assert guard.accept(sent + 0.025, arrival + 0.3)


def test_a_sender_restarted_with_another_clock_is_learned_after_agreeing_packets() -> None:
    guard = _learned()
    restarted = [guard.accept(100.0 + k / 60, BOOT + 1 + k / 60) for k in range(RELEARN + 2)]
    assert restarted == [False] * (RELEARN - 1) + [True] * 3


def test_scattered_corrupt_times_never_set_the_clock() -> None:
    guard = _learned()
    for k in range(100):  # each far from the last: they never agree with one another
        assert not guard.accept(1e6 * (k + 1) * (-1) ** k, BOOT + k / 60)
    assert guard.accept(UNIX + 2.0, BOOT + 2.0)


def test_the_first_packet_is_taken_only_near_the_unix_clock() -> None:
    far = ClockGuard()
    assert not far.accept(UNIX - 2 * PLAUSIBLE, BOOT, wall=UNIX)  # 1e6 s in the past is not a first frame
    # A sender whose clock is far off (the tests' monotonic clock) is learned from agreeing packets.
    monotonic = ClockGuard()
    accepted = [monotonic.accept(BOOT + k / 60, BOOT + k / 60, wall=UNIX + k / 60) for k in range(RELEARN)]
    assert accepted == [False] * (RELEARN - 1) + [True]
    assert not ClockGuard().accept(float("nan"), BOOT, wall=UNIX)
    assert ClockGuard().accept(time.time(), time.monotonic(), wall=time.time())


def test_a_frame_sent_before_it_was_captured_or_long_after_is_invalid() -> None:
    assert frame_times_valid(UNIX, UNIX) and frame_times_valid(UNIX, UNIX + 0.02)
    assert not frame_times_valid(1e300, UNIX) and not frame_times_valid(UNIX, UNIX - 0.01)
    assert not frame_times_valid(UNIX - 1e6, UNIX)


def test_the_referee_counter_going_back_is_told_mod_2_32() -> None:
    assert not counter_went_back(7, None)
    assert not counter_went_back(7, 7) and not counter_went_back(8, 7)
    assert counter_went_back(6, 7)
    assert not counter_went_back(0, COUNTER_SPAN - 1)  # wrapped forward
    assert counter_went_back(COUNTER_SPAN - 1, 0)  # one back across the wrap
    assert counter_went_back(7 + COUNTER_SPAN // 2, 7)  # half the span ahead is read as behind


def _frame(t_capture: float, t_sent: float) -> bytes:
    seen = (wire.Detection("blue", 0, 0.0, 0.0, 0.0),)
    return wire.encode_detection(0, wire.DetectionFrame(t_capture, t_sent, 0, seen))


def test_the_loop_drops_frames_of_impossible_times_and_they_move_no_robot() -> None:
    # Robot 0 has a target: any frame of it that reached the controller would make it drive.
    commands = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    commands.bind(("127.0.0.1", 0))
    loop = build_loop(
        DeploySettings(
            "direct",
            "127.0.0.1:0",
            f"grsim:127.0.0.1:{commands.getsockname()[1]}",
            "blue",
            [0],
            {0: [1.0, 0.5, 0.0]},
            task="proposed",
            priority=0,
        )
    )
    vision = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vision.bind(("127.0.0.1", 0))
    to = ("127.0.0.1", loop.vision.getsockname()[1])
    thread = threading.Thread(target=loop.run, args=(threading.Event(), 1.0))
    thread.start()
    try:
        now = time.time()
        corrupt = [(1e300, 1e300), (-1e300, -1e300), (now - 1e6, now - 1e6), (1e300, now), (now, now + 5.0)]
        for k in range(40):  # the fuzzing's finds, again and again, as a camera's frames would come
            vision.sendto(_frame(*corrupt[k % len(corrupt)]), to)
            time.sleep(0.01)
        assert loop.stats.moving_commands == 0 and loop.stats.frames == 0
        vision.sendto(_frame(time.time(), time.time()), to)  # a frame of now: the robot drives
        time.sleep(0.1)
    finally:
        thread.join()
        loop.close()
        vision.close()
        commands.close()
    assert loop.stats.dropped["time"] == 40 and loop.stats.frames == 1
    assert loop.stats.moving_commands > 0


def test_each_window_holds_its_edge() -> None:
    # Binary-exact times, so each comparison meets its bound exactly: the bounds are "at most".
    first = ClockGuard()
    assert first.accept(sent=PLAUSIBLE, arrival=0.0, wall=0.0)  # a first packet a day off is still taken
    guard = ClockGuard()
    assert guard.accept(sent=1000.0, arrival=0.0, wall=1000.0)
    assert guard.accept(sent=1000.5, arrival=0.0)  # the offset moved by exactly WINDOW
    assert (guard.offset, guard.candidate, guard.agreeing) == (1000.5, None, 0)
    assert frame_times_valid(t_capture=0.5, t_sent=1.0)  # sent exactly WINDOW after capture
    assert frame_times_valid(t_capture=0.001, t_sent=0.0)  # the millisecond of rounding, exactly


def test_packets_a_window_apart_agree_on_a_new_clock() -> None:
    guard = ClockGuard(relearn=2)
    assert guard.accept(sent=1000.0, arrival=0.0, wall=1000.0)
    assert not guard.accept(sent=5000.0, arrival=0.0)  # far off the learned clock: dropped, a candidate
    assert guard.accept(sent=5000.5, arrival=0.0)  # exactly a window from the candidate: the second to agree
    assert (guard.offset, guard.candidate, guard.agreeing) == (5000.5, None, 0)


def test_the_counter_half_way_round_is_the_first_step_back() -> None:
    assert not counter_went_back(2**31 - 1, 0)
    assert counter_went_back(2**31, 0)


def _geometry(name: str) -> wire.FieldGeometry:
    return wire.parse_vision(wire.encode_geometry(get_field(name)))


def test_the_field_guard_drops_another_field_and_raises_once_three_in_a_row_agree_on_it() -> None:
    guard = FieldGuard(get_field("division_b"))
    b, a, hw = _geometry("division_b"), _geometry("division_a"), _geometry("hardware_challenge")
    assert guard.accept(b)
    # Corrupt packets that parse do not agree on one field: dropped, never an error.
    assert [guard.accept(g) for g in (a, hw, a, b, a, a, b)] == [
        False,
        False,
        False,
        True,
        False,
        False,
        True,
    ]
    assert not guard.accept(a) and not guard.accept(a)
    with pytest.raises(
        ValueError, match=r"^the geometry packet's field \(field_length 12\.0, .*\(division_b: "
    ):
        guard.accept(a)
