"""Input no camera or game controller could send, dropped before it reaches the controller.

The parsers (``wire``, ``referee``) check each packet alone; what needs the receiver's clock or the packets
before it is checked here. Both senders stamp their packets with their own clock: SSL-Vision and the game
controller with the UNIX clock of their machine (not synchronised with ours, possibly off by seconds), the
lockstep field server with its world time (which runs faster than the wall clock while the controller
answers quickly, and stands still while it waits). Neither can be compared with our clock directly, so
``ClockGuard`` compares the *offset* between a packet's time and its arrival on our monotonic clock: for a
sender whose clock runs with ours it is constant up to the network's jitter (milliseconds), for the lockstep
server it moves by at most a world step (25 ms) per packet. A packet whose offset jumps by more than
``WINDOW`` from the last accepted one is dropped; a well-formed frame stamped 1e300 s or 1e6 s in the past
(the fuzzing found both) jumps by far more.

Why from the last accepted packet, not a learned average: the lockstep server's offset drifts by design,
and a sender's clock may be stepped (NTP): the window follows it. Why ``WINDOW`` is 0.5 s: far above the
network's jitter and a lockstep world step, far below what corrupt times are off by, and no longer than a
robot may go unseen before it is stopped anyway (``Tracker``'s ``forget`` is 1 s). A sender that restarts
with another clock (the vision PC rebooted, the field server restarted) sends packets that all jump from the
old offset but agree with one another: after ``RELEARN`` such packets in a row the guard takes the new clock
(a fuzzer's random times do not agree with one another).

The first packet has nothing to be compared with. It is accepted when its time lies within ``PLAUSIBLE`` of
this machine's UNIX clock (senders keep UNIX time, the lockstep server's world time starts at it; a day
covers a vision PC without NTP or with a wrong time zone); otherwise the guard accepts nothing until
``RELEARN`` packets in a row agree, so one corrupt first frame cannot set the clock.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from hier_ssl.deploy.wire import FieldGeometry, check_field

WINDOW = 0.5  # s an offset may move between accepted packets (module docstring)
PLAUSIBLE = 86400.0  # s a first packet's time may be off this machine's UNIX clock (module docstring)
RELEARN = 5  # packets in a row that agree on a new offset before it is taken (about 80 ms of one camera)
COUNTER_SPAN = 1 << 32  # the referee's command counter is a uint32


@dataclass
class Streak:
    """How many values in a row agree (``same``) with the one before them, and the last of them: the
    guards take a new clock, field or count once enough dropped packets in a row agree on it."""

    same: Callable[[Any, Any], bool] = operator.eq
    last: Any = None
    count: int = 0

    def add(self, value: Any) -> int:
        """Count ``value`` in (a streak of one where it does not agree with the last); the streak's length."""
        self.count = self.count + 1 if self.count and self.same(value, self.last) else 1
        self.last = value
        return self.count

    def clear(self) -> None:
        self.last, self.count = None, 0


@dataclass
class ClockGuard:
    """Whether a packet's time fits the sender's clock as learned from the packets accepted before it."""

    window: float = WINDOW
    relearn: int = RELEARN
    offset: float | None = None  # the last accepted packet's time minus its arrival
    streak: Streak = field(init=False)  # the offsets the dropped packets in a row agree on

    def __post_init__(self) -> None:
        self.streak = Streak(lambda a, b: abs(a - b) <= self.window)

    @property
    def candidate(self) -> float | None:
        """The offset the dropped packets in a row agree on."""
        return self.streak.last

    @property
    def agreeing(self) -> int:
        return self.streak.count

    def accept(self, sent: float, arrival: float, wall: float | None = None) -> bool:
        """Whether a packet stamped ``sent`` (the sender's clock, s) that arrived at ``arrival`` (monotonic
        s) is accepted; accepting it moves the learned offset to it. ``wall``: this machine's UNIX time at
        the arrival, for the first packet (None: the first waits for ``relearn`` agreeing ones)."""
        offset = sent - arrival
        if not math.isfinite(offset):
            return False
        if self.offset is None and wall is not None and abs(sent - wall) <= PLAUSIBLE:
            self.offset = offset
            return True
        fits = self.offset is not None and abs(offset - self.offset) <= self.window
        if fits or self.streak.add(offset) >= self.relearn:
            self.offset = offset
            self.streak.clear()
            return True
        return False


@dataclass
class FieldGuard:
    """Whether a geometry packet's field is the ``trained`` one (a ``Field``; ``check_field``). One that is
    not is dropped; ``relearn`` in a row that agree on the same other field raise ``check_field``'s error,
    which ends the deploy: the cameras see another field than the manager plans on. Why not the first: a
    corrupt packet that still parses (the fuzzing makes them) must not end a deploy, and two corruptions
    in a row do not agree on one field."""

    trained: Any
    relearn: int = 3  # SSL-Vision sends its geometry every few seconds: the error comes within seconds
    streak: Streak = field(default_factory=Streak)  # the other fields seen in a row

    def accept(self, seen: FieldGeometry) -> bool:
        try:
            check_field(seen, self.trained)
        except ValueError:
            if self.streak.add(seen) >= self.relearn:
                raise
            return False
        self.streak.clear()
        return True


def frame_times_valid(t_capture: float, t_sent: float, window: float = WINDOW) -> bool:
    """Whether a camera frame was sent no earlier than it was captured (a millisecond of rounding allowed)
    and no later than ``window`` after: SSL-Vision processes a frame in milliseconds."""
    return -0.001 <= t_sent - t_capture <= window


def counter_went_back(counter: int, last: int | None) -> bool:
    """Whether the referee's command ``counter`` is behind the ``last`` accepted one, mod 2^32: a step of
    2^31 or more forward is read as a step back (the counter counts commands, a few a minute, and wraps
    only after 2^32 of them)."""
    if last is None:
        return False
    return (counter - last) % COUNTER_SPAN >= COUNTER_SPAN // 2


__all__ = [
    "COUNTER_SPAN",
    "PLAUSIBLE",
    "RELEARN",
    "WINDOW",
    "ClockGuard",
    "FieldGuard",
    "Streak",
    "counter_went_back",
    "frame_times_valid",
]
