"""The controller's loop: receive vision, tick every control period, send commands, stop safely.

A period's tick waits for the first camera frame at or after its due time (so the command is computed
from the newest detections, and the time from that frame's arrival to the command's send is the loop's
own latency), but never more than ``WAIT`` past it: without vision the ticks go on, and the controller
stops the robots it no longer sees. Every datagram that is not vision from the configured source is
dropped and counted by reason; none of them reaches the controller. While datagrams are being dropped, or
the simulator answers with errors, the loop says so through ``report`` (the module's logger by default),
at most one line a ``REPORT_EVERY`` on each, not only in the counts at exit: a wrong ``--vision-source``
or a second team's SSL-Vision on the port shows at once. On exit (``stop`` set, e.g. by SIGINT or SIGTERM,
or ``duration`` over) every controlled robot is sent a zero command.

The referee (``referee``, the game controller's messages, ``hier_ssl.deploy.game.RefereeInput``): its
socket is read beside vision's, each packet checked and counted there (drops as ``referee ...``), and the
state in force (the last accepted message's, or STOP's limits after a second of silence) is handed to the
controller before each tick, which plans and caps its commands by its rules from that tick on (HALT:
zero commands).

The loop's thread runs under the real-time scheduler (SCHED_FIFO at ``priority``) where the OS allows it:
a tick computes for about a millisecond, and on cores shared with other processes (the field server, a
training) the time-sharing scheduler let them run first, which was the whole latency tail (6 robots,
load 2-3 on two cores: p99 22-40 ms under time-sharing, 2.2 ms under SCHED_FIFO; no garbage collection
fell in a slow tick). The loop sleeps in ``select`` between ticks, so it takes a core only for its ticks.

Lockstep (a field server that steps its world once per command, ``hier-ssl field --lockstep``): the field's
clock is the frames' capture time, and it stands still until the commands come. The loop then ticks once
per world time instead of once per 25 ms of its own clock: as soon as every camera it has seen sent a
frame of a newer capture time (or ``GATHER`` after the first of them), predicting to that time, not to its
own clock: the world did not move on while the frame travelled. A tick on its own clock would count a
period the world did not step (the decisions' cadence, the modelled velocities would run ahead of it), so
it comes only once no new frame has come for the controller's ``max_age`` + ``WAIT`` (60 ms), when every
robot is out of sight and gets its stop (within 100 ms, as in the free-running mode).
"""

from __future__ import annotations

import logging
import os
import selectors
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from math import inf

from hier_ssl.deploy.controller import Controller
from hier_ssl.deploy.game import RefereeInput
from hier_ssl.deploy.guard import ClockGuard, FieldGuard, frame_times_valid
from hier_ssl.deploy.net import CommandSender, ControlServer, receive
from hier_ssl.deploy.wire import DetectionFrame, FieldGeometry, PacketError, parse_response, parse_vision

log = logging.getLogger(__name__)

PERIOD = 0.025  # s, the control period the managers were trained with
WAIT = 0.010  # s a tick waits past its due time for a camera frame
WARMUP_TICKS = 40  # the first second's latencies are not kept: TorchScript's first runs are slower
STOP_COPIES = 2  # the stop goes out twice: one lost datagram must not leave a robot driving
PRIORITY = 10  # SCHED_FIFO priority: above every time-shared process, below interrupt threads (50)
GATHER = 0.02  # s lockstep waits at most for the other cameras' frames of a world time (they go out together)
REPORT_EVERY = 1.0  # s between two lines on one topic (drops, the simulator's errors): a flood must not
# become a flood of lines


def _raise_priority(priority: int) -> tuple[str, Callable[[], None]]:
    """Put the calling thread under SCHED_FIFO at ``priority`` (1-99; 0 leaves it time-shared) where the
    OS allows it: what it got ("fifo 10", "time-shared (...)") and a function that restores it."""
    if priority == 0:
        return "time-shared (asked)", lambda: None
    if not hasattr(os, "sched_setscheduler"):
        return "time-shared (no real-time scheduler on this OS)", lambda: None
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        return "time-shared (not permitted: needs CAP_SYS_NICE or an rtprio limit)", lambda: None
    return f"fifo {priority}", lambda: os.sched_setscheduler(0, policy, param)


@dataclass
class LoopStats:
    """What the loop saw: camera frames and geometry packets accepted, datagrams dropped by reason,
    ticks, commands that move a robot, the latencies (s) from a frame's arrival to the command sent on it
    and the controller's compute time (s) of each tick that decided (both after ``WARMUP_TICKS``), the
    field size from geometry, the simulator's errors, the scheduling the
    loop's thread ran under (``_raise_priority``)."""

    frames: int = 0
    geometry: int = 0
    dropped: Counter = field(default_factory=Counter)
    ticks: int = 0
    moving_commands: int = 0
    latencies: list[float] = field(default_factory=list)
    decisions: list[float] = field(default_factory=list)
    field_size: FieldGeometry | None = None
    simulator_errors: Counter = field(default_factory=Counter)  # by message: bounded, unlike a list of each
    scheduling: str = ""


@dataclass
class Throttle:
    """When the last line on one topic was said: the next may come ``REPORT_EVERY`` s after it."""

    said: float = -inf

    def due(self, now: float) -> bool:
        return now - self.said >= REPORT_EVERY


@dataclass
class WorldTime:
    """Lockstep: the newest capture time seen (``time``), the cameras that sent a frame of it (``seen``) out
    of all cameras seen (``cameras``), the arrival of its first and newest frames, and the capture time of
    the last tick (``ticked``)."""

    time: float = -inf
    cameras: set[int] = field(default_factory=set)
    seen: set[int] = field(default_factory=set)
    first: float = 0.0
    newest: float = 0.0
    ticked: float = -inf

    def add(self, frame: DetectionFrame, arrival: float) -> None:
        self.cameras.add(frame.camera)
        if frame.t_capture > self.time:
            self.time, self.seen, self.first = frame.t_capture, set(), arrival
        if frame.t_capture == self.time:
            self.seen.add(frame.camera)
            self.newest = arrival

    def pending(self) -> bool:
        """Whether frames of a world time not ticked on yet have come."""
        return self.time > self.ticked

    def ready(self, now: float) -> bool:
        """Whether to tick on the newest world time at monotonic ``now``: every camera's frame of it came,
        or ``GATHER`` passed since the first."""
        return self.pending() and (self.seen >= self.cameras or now - self.first >= GATHER)


class DeployLoop:
    """``controller`` fed from ``vision`` (datagrams from ``source`` only), commands out through
    ``sender``, targets in through ``control`` (optional); its thread runs at SCHED_FIFO ``priority``
    (0: time-shared) while ``run`` runs; ``lockstep`` for a field server that waits for the commands
    (module docstring). ``report`` takes a line on the datagrams dropped since the last one while some are,
    and on the simulator's errors (None: the module's logger, as warnings)."""

    def __init__(
        self,
        controller: Controller,
        vision: socket.socket,
        source: str,
        sender: CommandSender,
        control: ControlServer | None = None,
        clock: Callable[[], float] = time.monotonic,
        priority: int = PRIORITY,
        lockstep: bool = False,
        referee: RefereeInput | None = None,
        report: Callable[[str], None] | None = None,
    ) -> None:
        if not 0 <= priority <= 99:
            raise ValueError(f"priority {priority}: expected 0 (time-shared) or a SCHED_FIFO priority 1..99")
        self.priority = priority
        self.controller, self.vision, self.source = controller, vision, source
        self.sender, self.control, self.clock = sender, control, clock
        self.stats = LoopStats()
        self.report = report or log.warning
        self._reported: Counter = Counter()  # the drops already reported
        self._drops, self._errors = Throttle(clock()), Throttle()  # a drop's line covers the time since
        self.world = WorldTime() if lockstep else None
        self.vision_clock = ClockGuard()  # frames stamped at times no camera could send are dropped ("time")
        self.field_guard = FieldGuard(controller.view.field)
        self.selector = selectors.DefaultSelector()
        self.selector.register(vision, selectors.EVENT_READ, "vision")
        self.selector.register(sender.sock, selectors.EVENT_READ, "response")
        if control is not None:
            self.selector.register(control.listener, selectors.EVENT_READ, "listener")
        self.referee = referee  # the game controller: its state holds from the next tick
        if referee is not None:
            self.selector.register(referee.sock, selectors.EVENT_READ, "referee")

    def run(self, stop: threading.Event, duration: float | None = None) -> LoopStats:
        """Run until ``stop`` is set or ``duration`` seconds pass; then stop every robot."""
        self.stats.scheduling, restore = _raise_priority(self.priority)
        start = self.clock()
        due = start + PERIOD
        try:
            while not stop.is_set() and (duration is None or self.clock() - start < duration):
                wake = due + WAIT
                if self.world is not None and self.world.pending():
                    wake = min(wake, self.world.first + GATHER)
                arrival = None
                for key, _ in self.selector.select(max(0.0, wake - self.clock())):
                    arrival = self._handle(key) or arrival
                now = self.clock()
                self._report_drops(now)
                if self.world is not None and self.world.ready(now):
                    # The world waits for this tick: predict to the frames' time, not to this clock's.
                    self.world.ticked, arrival = self.world.time, self.world.newest
                    self._tick(arrival, arrival)
                    due = self.clock() + self.controller.max_age
                elif now >= due + WAIT or (self.world is None and now >= due and arrival is not None):
                    self._tick(now, arrival)
                    due = due + PERIOD if due + PERIOD > now else now + PERIOD
        finally:
            for _ in range(STOP_COPIES):
                self._send(self.controller.stop())
            self.selector.close()
            restore()
        return self.stats

    def _report_drops(self, now: float) -> None:
        """One line to ``report`` on what was dropped since the last line, if anything was and
        ``REPORT_EVERY`` has passed since it."""
        if not self._drops.due(now):
            return
        new = self.stats.dropped - self._reported
        if not new:
            return
        reasons = ", ".join(f"{reason} {count}" for reason, count in sorted(new.items()))
        self.report(f"dropped {new.total()} datagrams in {now - self._drops.said:.1f} s ({reasons})")
        self._reported, self._drops.said = self.stats.dropped.copy(), now

    def _tick(self, now: float, arrival: float | None) -> None:
        """Send the controller's commands of monotonic time ``now``; keep the latency from ``arrival``."""
        if self.referee is not None:
            self.controller.referee = self.referee.current(self.clock())
        start = self.clock()
        commands = self.controller.tick(now)
        if self.controller.since_decision == 1 and self.stats.ticks >= WARMUP_TICKS:  # it decided
            self.stats.decisions.append(self.clock() - start)
        self._send(commands)
        if arrival is not None and self.stats.ticks >= WARMUP_TICKS:
            self.stats.latencies.append(self.clock() - arrival)
        self.stats.ticks += 1

    def close(self) -> None:
        """Close the loop's sockets (after ``run``)."""
        self.vision.close()
        self.sender.close()
        if self.control is not None:
            self.control.shutdown()
        if self.referee is not None:
            self.referee.close()

    def _handle(self, key: selectors.SelectorKey) -> float | None:
        """Serve one ready socket; the arrival time of the newest camera frame it brought, if any."""
        if key.data == "vision":
            return self._read_vision()
        if key.data == "referee":
            self.referee.read(self.clock(), self.stats.dropped)
        elif key.data == "response":
            self._read_responses()
        elif key.data == "listener":
            client = self.control.accept()
            if client is not None:
                self.selector.register(client, selectors.EVENT_READ, "client")
        elif not self.control.read(key.fileobj):
            self.selector.unregister(key.fileobj)
        return None

    def _read_vision(self) -> float | None:
        newest = None
        while (packet := receive(self.vision)) is not None:
            data, sender = packet
            arrival = self.clock()
            if sender[0] != self.source:
                self.stats.dropped["source"] += 1
                continue
            try:
                parsed = parse_vision(data)
            except PacketError as err:
                self.stats.dropped[err.reason] += 1
                continue
            if isinstance(parsed, DetectionFrame):
                if not (
                    frame_times_valid(parsed.t_capture, parsed.t_sent)
                    and self.vision_clock.accept(parsed.t_sent, arrival, time.time())
                ):
                    self.stats.dropped["time"] += 1
                    continue
                self.controller.on_frame(parsed, arrival)
                if self.world is not None:
                    self.world.add(parsed, arrival)
                self.stats.frames += 1
                newest = arrival
            elif not self.field_guard.accept(parsed):  # another field than the manager's (FieldGuard)
                self.stats.dropped["field"] += 1
            else:
                self.stats.field_size = parsed
                self.stats.geometry += 1
        return newest

    def _read_responses(self) -> None:
        while (packet := receive(self.sender.sock)) is not None:
            try:
                errors = parse_response(packet[0])
            except PacketError as err:
                self.stats.dropped[f"response {err.reason}"] += 1
                continue
            self.stats.simulator_errors.update(errors)
            # A simulator repeats its error in each response (60 a second): said at most once a second.
            now = self.clock()
            if errors and self._errors.due(now):
                self._errors.said = now
                self.report(f"simulator: {errors[0]} ({self.stats.simulator_errors.total()} so far)")

    def _send(self, commands: list) -> None:
        try:
            self.sender.send(commands, time.time())
        except OSError as err:  # e.g. nobody listening on loopback yet: the next period sends again
            self.stats.dropped[f"send {type(err).__name__}"] += 1
            return
        self.stats.moving_commands += sum(any(c[1:]) for c in commands)


__all__ = ["GATHER", "PERIOD", "PRIORITY", "REPORT_EVERY", "WAIT", "DeployLoop", "LoopStats", "WorldTime"]
