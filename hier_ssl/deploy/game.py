"""The game controller's word in the deploy loop: Referee messages in, the rules the controller plans with.

``RefereeInput`` reads the referee socket (unicast, from one source address) and keeps the state in force.
What no game controller sends is dropped and counted by reason, beside the vision's drops: what does not
parse (``hier_ssl.deploy.referee``), a packet time that jumps (``ClockGuard``, as for the cameras), a
command counter that goes back (mod 2^32), a command that changes while the counter stays (the game
controller counts every command it issues, so a new command without a new count is a corrupt packet, not
a decision: one changed byte must not turn HALT into a start), a command the game does not play or a
placement off the field. A counter that goes back to the same count and command in ``RELEARN`` packets in
a row is a restarted game controller (or the real count after a corrupt one went ahead) and is followed.

Silence: with no message accepted for ``SILENCE`` (1 s, ten of the game controller's periodic messages),
or none yet, the controller holds at STOP's limits: the last command may be over, and STOP is the
strictest state in which robots still may move out of the way.

``game_rules`` turns the state into what the controller plans with: each controlled robot's zones
(``forbidden_zones``; the keeper from the message's team info; the ball where a camera saw it last,
``Tracker.ball``) and the speed limit (0 in HALT, 1.5 m/s in STOP). With no ball seen lately, a ball
placement's zone is a circle around the designated position and STOP's and the free kicks' zones around
the ball are left out.
"""

from __future__ import annotations

import socket
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import fields, replace
from math import inf

import numpy as np

from hier_ssl.deploy.guard import RELEARN, ClockGuard, Streak, counter_went_back
from hier_ssl.deploy.net import receive
from hier_ssl.deploy.referee import RefereeMessage, game_state, parse_referee
from hier_ssl.deploy.wire import PacketError
from hier_ssl.game.legal import RowRules, row_rules
from hier_ssl.game.referee import (
    STOP,
    TEAM_NAMES,
    Lineup,
    RefereeState,
    ball_in_play,
    is_free_kick,
    is_placement,
    lineup,
    referee_state,
)
from hier_ssl.game.zones import BALL, NONE, forbidden_zones, speed_limit
from hier_ssl.world.field import Field

SILENCE = 1.0  # s without an accepted referee message before the controller holds at STOP's limits


class RefereeInput:
    """Referee messages from ``source`` on ``sock`` (non-blocking UDP), for the game on ``field``."""

    def __init__(self, sock: socket.socket, source: str, field: Field) -> None:
        self.sock, self.source, self.field = sock, source, field
        self.clock = ClockGuard()
        self.message: RefereeMessage | None = None
        self.state: RefereeState | None = None
        self.heard = -inf  # monotonic s of the last accepted message
        self.accepted = 0
        self.going_back = Streak()  # packets in a row whose counter went back, saying one (counter, command)
        self._held: tuple[RefereeState | None, RefereeState] | None = None  # (the state it holds from, STOP)

    def read(self, now: float, dropped: Counter) -> None:
        """Take every waiting datagram, arrived by monotonic ``now``; drops go to ``dropped`` by reason."""
        while (packet := receive(self.sock)) is not None:
            reason = self.take(packet[0], packet[1][0], now, time.time())
            if reason is not None:
                dropped[f"referee {reason}"] += 1

    def take(self, data: bytes, sender: str, arrival: float, wall: float) -> str | None:
        """Take one datagram from IP ``sender`` that arrived at monotonic ``arrival`` (UNIX ``wall``); the
        reason it is dropped, or None when it is accepted."""
        if sender != self.source:
            return "source"
        try:
            message = parse_referee(data)
        except PacketError as err:
            return err.reason
        if not self.clock.accept(message.sent, arrival, wall):
            return "time"
        last = self.message
        if last is not None and counter_went_back(message.counter, last.counter):
            # A restarted game controller repeats its count and command; corrupt packets scatter.
            if self.going_back.add((message.counter, message.command)) < RELEARN:
                if message.command == last.command:
                    # The game controller repeats the command in force: it is not silent, whatever count
                    # went ahead of it (silence would hold the team at STOP's limits, moving it out of HALT).
                    self.heard = arrival
                return "counter"
        elif last is not None and message.counter == last.counter and message.command != last.command:
            return "command without counter"
        try:
            state = game_state(message, self.field)
        except ValueError:
            return "unplayable"
        self.message, self.state, self.heard = message, state, arrival
        self.going_back.clear()
        self.accepted += 1
        return None

    def current(self, now: float) -> RefereeState:
        """The state in force at monotonic ``now``: the last message's, or STOP (its keepers and sides kept)
        after ``SILENCE`` without one."""
        if self.state is not None and now - self.heard <= SILENCE:
            return self.state
        if (
            self._held is None or self._held[0] is not self.state
        ):  # one object while silent: the controller's rules are kept
            held = referee_state(STOP, self.field) if self.state is None else self.state
            self._held = (
                self.state,
                replace(held, command=np.full_like(held.command, STOP), in_play=np.zeros_like(held.in_play)),
            )
        return self._held[1]

    def close(self) -> None:
        self.sock.close()


def labelled_lineup(labels: Sequence[tuple[str, int]]) -> Lineup:
    """The rules' lineup of robots labelled (team name, vision id) as vision labels them, in their order."""
    team = np.array([TEAM_NAMES.index(name) for name, _ in labels], dtype=np.int64)
    return lineup(team, np.array([robot for _, robot in labels], dtype=np.int64))


def game_rules(
    referee: RefereeState, field: Field, players: Lineup, ball: tuple[float, float] | None = None
) -> RowRules:
    """The rules of the controlled robots ``players`` (``labelled_lineup``), one planner row each in their
    order, under ``referee`` (one field) with the ``ball`` where vision saw it (m; None: not known): zones
    and speed limit. Without a ball, a ball placement's zone is a circle around the designated position and
    the other commands' zones around the ball are left out: there is no position to put them at."""
    at = referee.placement if ball is None else np.asarray(ball, dtype=float)[None]
    zones = forbidden_zones(referee, at, field, players)
    if ball is None and not is_placement(referee.command).all():
        kind = zones.kind.copy()
        kind[..., BALL] = NONE
        zones = replace(zones, kind=kind)
    return row_rules(zones, speed_limit(referee))


def same_call(a: RefereeState | None, b: RefereeState | None) -> bool:
    """Whether two referee states say the same (None: no referee); a placement not given is NaN in both."""
    if a is None or b is None:
        return a is b
    return all(np.array_equal(getattr(a, f.name), getattr(b, f.name), equal_nan=True) for f in fields(a))


class InPlayWatch:
    """Rules 5.4 as a team's own software tells it, for one field: the game controller keeps sending a free
    kick after its ball is in play, so the state it sends gains ``in_play`` here (``ball_in_play``), once
    the ball is ``IN_PLAY_DISTANCE`` from where vision saw it when the kick was first heard, or the kick's
    time has passed since then. A ball not seen then: the time alone (the restrictions kept longer, never a
    foul). Called each period with the state received; returns it, or one object with ``in_play`` set."""

    def __init__(self, field: Field) -> None:
        self.division_a = field.name == "division_a"
        self._kick: tuple[RefereeState, float, np.ndarray] | None = None  # the kick as heard, when, its ball
        self._played: RefereeState | None = None

    def __call__(self, referee: RefereeState, now: float, ball: tuple[float, float] | None) -> RefereeState:
        if not is_free_kick(referee.command).all():
            self._kick = self._played = None
            return referee
        seen = None if ball is None else np.asarray(ball, dtype=float)[None]
        if self._kick is None or not same_call(self._kick[0], referee):  # a new kick (or a new call of it)
            self._kick, self._played = (referee, now, np.full((1, 2), np.nan) if seen is None else seen), None
        if self._played is None:
            _, start, at = self._kick
            since = np.array([now - start])
            if ball_in_play(referee.command, since, at if seen is None else seen, at, self.division_a).all():
                self._played = replace(referee, in_play=np.ones_like(referee.in_play))
        return referee if self._played is None else self._played


__all__ = ["SILENCE", "InPlayWatch", "RefereeInput", "game_rules", "labelled_lineup", "same_call"]
