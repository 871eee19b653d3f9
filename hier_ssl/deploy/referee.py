"""The game controller's ``Referee`` message to and from bytes, checked once here like the vision packets.

A message that does not parse, lacks a required field, carries a command or stage this protocol does not
define (a closed enum: the value lands among the unknown fields and the required field reads as missing),
names a keeper id no robot can have, or places the ball at a position no field has raises
``PacketError``; the receiver drops and counts it. Past this module: seconds, metres, command and stage by
their protocol names. Whether a message is stale or its counter went back needs the receiver's clock and
the previous message, so the receiver checks that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hier_ssl.deploy.proto import ssl_gc_referee_message_pb2
from hier_ssl.deploy.wire import MAX_COORD_MM, MAX_ROBOT_ID, TEAMS, PacketError, parse_message
from hier_ssl.game.referee import TEAM_NAMES, RefereeState, referee_state
from hier_ssl.world.field import Field

Referee = ssl_gc_referee_message_pb2.Referee
BALL_PLACEMENT = ("BALL_PLACEMENT_YELLOW", "BALL_PLACEMENT_BLUE")


@dataclass(frozen=True)
class RefereeMessage:
    """One referee packet: ``sent`` and ``issued`` (s, UNIX: the packet and its command), ``command`` and
    ``stage`` by name, ``counter`` (commands issued so far, mod 2^32), ``keepers`` the keeper's robot id by
    team ("blue", "yellow"), ``designated`` the ball placement position (m, vision frame; None unless the
    command is a ball placement), ``next_command`` (None when not announced), ``blue_on_positive_half``
    (None when not said)."""

    sent: float
    command: str
    counter: int
    issued: float
    stage: str
    keepers: dict[str, int]
    designated: tuple[float, float] | None = None
    next_command: str | None = None
    blue_on_positive_half: bool | None = None


def parse_referee(data: bytes) -> RefereeMessage:
    """A ``Referee`` packet as a ``RefereeMessage``; ``PacketError`` naming why it is dropped otherwise."""
    packet = parse_message(Referee, data, "referee message")
    command = Referee.Command.Name(packet.command)
    keepers = {team: getattr(packet, team).goalkeeper for team in TEAMS}
    for team, keeper in keepers.items():
        if keeper > MAX_ROBOT_ID:
            raise PacketError("invalid", f"{team} keeper id {keeper} > {MAX_ROBOT_ID}")
    designated = None
    if packet.HasField("designated_position"):
        x, y = packet.designated_position.x, packet.designated_position.y
        if not (math.isfinite(x) and math.isfinite(y)) or max(abs(x), abs(y)) > MAX_COORD_MM:
            raise PacketError("invalid", f"designated position ({x}, {y}) mm")
        designated = (x / 1000.0, y / 1000.0)
    if command in BALL_PLACEMENT and designated is None:
        raise PacketError("invalid", f"{command} without a designated position")
    return RefereeMessage(
        sent=packet.packet_timestamp / 1e6,
        command=command,
        counter=packet.command_counter,
        issued=packet.command_timestamp / 1e6,
        stage=Referee.Stage.Name(packet.stage),
        keepers=keepers,
        designated=designated if command in BALL_PLACEMENT else None,
        next_command=Referee.Command.Name(packet.next_command) if packet.HasField("next_command") else None,
        blue_on_positive_half=(
            packet.blue_team_on_positive_half if packet.HasField("blue_team_on_positive_half") else None
        ),
    )


def encode_referee(message: RefereeMessage) -> bytes:
    """``message`` as a ``Referee`` packet (s in, microseconds on the wire; m in, mm on the wire), with
    empty team names and no cards, timeouts or score: what a field server playing referee sends."""
    packet = Referee()
    packet.packet_timestamp = round(message.sent * 1e6)
    packet.stage = Referee.Stage.Value(message.stage)
    packet.command = Referee.Command.Value(message.command)
    packet.command_counter = message.counter
    packet.command_timestamp = round(message.issued * 1e6)
    for team in TEAMS:
        info = getattr(packet, team)
        info.name = ""
        info.score = info.red_cards = info.yellow_cards = info.timeouts = info.timeout_time = 0
        info.goalkeeper = message.keepers[team]
    if message.designated is not None:
        packet.designated_position.x = message.designated[0] * 1000.0
        packet.designated_position.y = message.designated[1] * 1000.0
    if message.next_command is not None:
        packet.next_command = Referee.Command.Value(message.next_command)
    if message.blue_on_positive_half is not None:
        packet.blue_team_on_positive_half = message.blue_on_positive_half
    return packet.SerializeToString()


def game_state(message: RefereeMessage, field: Field) -> RefereeState:
    """``message`` as the rules' state of one field (``hier_ssl.game``, whose commands are the protocol's
    numbers); a ValueError names a command the game does not play or a placement off ``field``."""
    return referee_state(
        Referee.Command.Value(message.command),
        field,
        placement=message.designated,
        keeper=tuple(message.keepers[team] for team in TEAM_NAMES),
        blue_on_positive_half=bool(message.blue_on_positive_half),
    )


__all__ = [
    "BALL_PLACEMENT",
    "RefereeMessage",
    "encode_referee",
    "game_state",
    "parse_referee",
]
