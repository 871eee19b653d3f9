"""The referee a field server plays: game controller commands on a schedule of episode time.

A script is comma-separated entries ``TIME:COMMAND``, a ball placement with its position in metres
(vision frame) after ``@``: ``2.0:STOP,5.0:FORCE_START,8.0:BALL_PLACEMENT_YELLOW@1.0,-0.5,12:HALT``.
TIME is seconds of an episode's world time (control steps x 25 ms from its reset, so that free-running and
lockstep fields play a script alike) and the script starts again with each episode. Before its first entry
the game runs (FORCE_START). COMMAND is a command the rules play (``hier_ssl.game.referee.COMMANDS``).
``parse_script`` refuses a script with one error that names the entry at fault: a time that is no number
or goes back, an unknown command, a ball placement without a position or off the field's playing area, a
position given to another command.

``ScriptedReferee`` turns it into the rules' state at each time (both keepers robot 0, the game
controller's default; blue on the negative half), and ``GameController`` any such state (a script's, or a
game scenario's own) into ``Referee`` messages as the game controller sends them.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from hier_ssl.deploy.referee import BALL_PLACEMENT, RefereeMessage, encode_referee, game_state
from hier_ssl.game.referee import COMMANDS, TEAM_NAMES, RefereeState
from hier_ssl.world.field import Field

STAGE = "NORMAL_FIRST_HALF"
KEEPERS = {"blue": 0, "yellow": 0}  # the game controller's default keeper ids


@dataclass(frozen=True)
class Call:
    """One entry of a script: ``command`` (protocol name) from ``time`` s of an episode, with the ball
    ``placement`` (x, y m) of a ball placement."""

    time: float
    command: str
    placement: tuple[float, float] | None = None


START = Call(0.0, "FORCE_START")  # in force before a script's first entry: the game runs


def _entries(text: str) -> list[str]:
    """``text``'s entries: a part without a ``:`` is the y of the placement before it."""
    entries: list[str] = []
    for part in text.split(","):
        if ":" not in part and entries and "@" in entries[-1]:
            entries[-1] += "," + part
        else:
            entries.append(part)
    return entries


def _number(text: str, what: str) -> float:
    """``text`` as a finite number; a ValueError names ``what`` it was to be otherwise."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ValueError(f"{what} {text.strip()!r} is not a finite number")
    return value


def parse_xy(text: str, what: str) -> tuple[float, float]:
    """``X,Y`` (m) as two finite numbers; a ValueError names ``what`` it was to be otherwise."""
    x, comma, y = text.partition(",")
    if not comma:
        raise ValueError(f"{what} {text.strip()!r}: expected X,Y (m)")
    return _number(x, f"{what}: x"), _number(y, f"{what}: y")


def parse_script(text: str, field: Field) -> tuple[Call, ...]:
    """The calls of script ``text`` (module docstring) on ``field``; a ValueError names the entry at
    fault and why."""
    calls: list[Call] = []
    for entry in _entries(text):
        when, colon, said = entry.partition(":")
        if not colon:
            raise ValueError(f"referee script entry {entry!r}: expected TIME:COMMAND[@X,Y]")
        time = _number(when, f"referee script entry {entry!r}: time")
        if time < 0 or (calls and time <= calls[-1].time):
            after = f"after the previous entry's {calls[-1].time:g} s" if calls else "at least 0"
            raise ValueError(f"referee script entry {entry!r}: time {time:g} s goes back (expected {after})")
        command, at, where = (p.strip() for p in said.partition("@"))
        if command not in COMMANDS.values():
            raise ValueError(
                f"referee script entry {entry!r}: unknown command {command!r}; known: "
                f"{', '.join(COMMANDS.values())}"
            )
        placement = None
        if command in BALL_PLACEMENT:
            if not at:
                raise ValueError(f"referee script entry {entry!r}: {command} needs a position, {command}@X,Y")
            placement = parse_xy(where, f"referee script entry {entry!r}: the position")
        elif at:
            raise ValueError(f"referee script entry {entry!r}: only a ball placement takes a position")
        call = Call(time, command, placement)
        try:
            game_state(_message(call), field)
        except ValueError as err:
            raise ValueError(f"referee script entry {entry!r}: {err}") from None
        calls.append(call)
    return tuple(calls)


def _message(call: Call) -> RefereeMessage:
    """``call`` as a message (times and counter 0), read into the rules' state by ``game_state``."""
    return RefereeMessage(
        sent=0.0,
        command=call.command,
        counter=0,
        issued=0.0,
        stage=STAGE,
        keepers=KEEPERS,
        designated=call.placement,
    )


class ScriptedReferee:
    """The rules' state that ``calls`` (``parse_script``) have in force on ``field`` at an episode's time."""

    def __init__(self, calls: tuple[Call, ...], field: Field) -> None:
        self.calls = (START, *calls)
        self.times = [call.time for call in self.calls]
        self.states = [game_state(_message(call), field) for call in self.calls]

    def at(self, time: float) -> RefereeState:
        """The state in force at episode ``time`` s."""
        return self.states[bisect.bisect_right(self.times, time) - 1]


class GameController:
    """``Referee`` packets of the rules' states (one field) as the game controller sends them: the command
    counter counts each command issued (a changed command, or any after ``restart``), ``issued`` its time."""

    def __init__(self) -> None:
        self.command: int | None = None  # the command in force (None: the next one is issued afresh)
        self.counter, self.issued = 0, 0.0

    def restart(self) -> None:
        """A new episode: its first command is issued anew (the counter goes on)."""
        self.command = None

    def packet(self, state: RefereeState, wall: float) -> bytes:
        """``state``'s packet, sent at UNIX ``wall``; a ValueError for a team without a keeper, which the
        protocol's unsigned keeper id cannot say."""
        command = int(state.command[0])
        if command != self.command:
            self.command, self.counter, self.issued = command, self.counter + 1, wall
        keeper = state.keeper[0].tolist()
        if min(keeper) < 0:
            raise ValueError(f"keepers {keeper} (yellow, blue): a Referee message needs an id for each team")
        name = COMMANDS[command]
        return encode_referee(
            RefereeMessage(
                sent=wall,
                command=name,
                counter=self.counter,
                issued=self.issued,
                stage=STAGE,
                keepers=dict(zip(TEAM_NAMES, keeper, strict=True)),
                designated=tuple(state.placement[0].tolist()) if name in BALL_PLACEMENT else None,
                blue_on_positive_half=bool(state.blue_on_positive_half[0]),
            )
        )


__all__ = ["START", "Call", "GameController", "ScriptedReferee", "parse_script", "parse_xy"]
