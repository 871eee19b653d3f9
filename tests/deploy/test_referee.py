"""The referee message: the game controller's field numbers, and what is dropped with which reason."""

from __future__ import annotations

import pytest
from protobuf_bytes import float32, message, uint

from hier_ssl.deploy import referee
from hier_ssl.deploy.proto import ssl_gc_referee_message_pb2
from hier_ssl.deploy.wire import MAX_PACKET, PacketError
from hier_ssl.game import referee as rules
from hier_ssl.world.field import get_field


def _team(keeper: int) -> bytes:
    # name "", score, red cards, yellow cards, timeouts, timeout time, goalkeeper: the required fields.
    return message(1, b"") + b"".join(
        uint(n, v) for n, v in ((2, 0), (3, 0), (5, 0), (6, 4), (7, 300), (8, keeper))
    )


def _packet(command: int, *, yellow_keeper: int = 1, blue_keeper: int = 0, extra: bytes = b"") -> bytes:
    head = (
        uint(1, 1_700_000_000_250_000)
        + uint(2, 1)
        + uint(4, command)
        + uint(5, 42)
        + uint(6, 1_700_000_000_000_000)
    )
    return head + message(7, _team(yellow_keeper)) + message(8, _team(blue_keeper)) + extra


def test_a_stop_has_the_game_controllers_field_numbers() -> None:
    parsed = referee.parse_referee(
        _packet(1, yellow_keeper=3, blue_keeper=7, extra=uint(12, 9) + uint(10, 1))
    )
    assert parsed == referee.RefereeMessage(
        sent=1_700_000_000.25,
        command="STOP",
        counter=42,
        issued=1_700_000_000.0,
        stage="NORMAL_FIRST_HALF",
        keepers={"blue": 7, "yellow": 3},
        next_command="DIRECT_FREE_BLUE",
        blue_on_positive_half=True,
    )


def test_a_ball_placement_carries_its_position_in_metres() -> None:
    position = message(9, float32(1, -1500.0) + float32(2, 250.0))
    parsed = referee.parse_referee(_packet(17, extra=position))
    assert parsed.command == "BALL_PLACEMENT_BLUE"
    assert parsed.designated == (-1.5, 0.25)
    assert parsed.next_command is None and parsed.blue_on_positive_half is None


def test_a_message_round_trips_through_its_bytes() -> None:
    sent = referee.RefereeMessage(
        sent=12.5,
        command="BALL_PLACEMENT_YELLOW",
        counter=3,
        issued=12.0,
        stage="NORMAL_SECOND_HALF",
        keepers={"blue": 15, "yellow": 0},
        designated=(2.0, -1.25),
        next_command="FORCE_START",
        blue_on_positive_half=False,
    )
    data = referee.encode_referee(sent)
    assert referee.parse_referee(data) == sent
    # The game controller's own layout, built by hand, is the same message.
    theirs = ssl_gc_referee_message_pb2.Referee.FromString(data)
    assert theirs.yellow.goalkeeper == 0 and theirs.blue.goalkeeper == 15
    assert theirs.designated_position.x == 2000.0 and theirs.designated_position.y == -1250.0


def test_a_position_outside_a_placement_is_not_passed_on() -> None:
    # The protocol sends the position with ball placements only; a stray one means nothing to a STOP.
    assert (
        referee.parse_referee(_packet(1, extra=message(9, float32(1, 0.0) + float32(2, 0.0)))).designated
        is None
    )


@pytest.mark.parametrize(
    ("data", "reason", "names"),
    [
        (_packet(99), "malformed", "command"),  # a command this protocol does not define
        (_packet(1)[:-4], "malformed", "referee message"),
        (_packet(1, blue_keeper=16), "invalid", "blue keeper id 16"),
        (_packet(1, yellow_keeper=20), "invalid", "yellow keeper id 20"),
        (_packet(16), "invalid", "BALL_PLACEMENT_YELLOW without a designated position"),
        (_packet(16, extra=message(9, float32(1, float("nan")) + float32(2, 0.0))), "invalid", "nan"),
        (_packet(16, extra=message(9, float32(1, 0.0) + float32(2, -25000.0))), "invalid", "-25000"),
        (b"\x00" * (MAX_PACKET + 1), "oversized", f"{MAX_PACKET + 1} bytes"),
    ],
)
def test_what_no_game_controller_sends_is_dropped_with_its_reason(
    data: bytes, reason: str, names: str
) -> None:
    with pytest.raises(PacketError) as err:
        referee.parse_referee(data)
    assert err.value.reason == reason
    assert names in str(err.value)


def test_keeper_fifteen_and_a_position_on_the_edge_are_kept() -> None:
    edge = message(9, float32(1, 20000.0) + float32(2, -20000.0))
    parsed = referee.parse_referee(_packet(16, blue_keeper=15, extra=edge))
    assert parsed.keepers["blue"] == 15 and parsed.designated == (20.0, -20.0)


def test_a_message_is_the_rules_state_of_its_field() -> None:
    placement = referee.parse_referee(
        _packet(
            16,
            yellow_keeper=2,
            blue_keeper=5,
            extra=message(9, float32(1, 1000.0) + float32(2, -500.0)) + uint(10, 1),
        )
    )
    state = referee.game_state(placement, get_field("division_b"))
    assert state.command.tolist() == [rules.BALL_PLACEMENT_YELLOW]
    assert state.placement.tolist() == [[1.0, -0.5]]
    assert state.keeper.tolist() == [[2, 5]]  # yellow, blue: the rules' team order
    assert state.blue_on_positive_half.tolist() == [True]
    stop = referee.game_state(referee.parse_referee(_packet(1)), get_field("division_b"))
    assert stop.command.tolist() == [rules.STOP] and stop.blue_on_positive_half.tolist() == [False]


def test_a_command_the_game_does_not_play_or_a_placement_off_the_field_is_named() -> None:
    kickoff = referee.parse_referee(_packet(4))
    with pytest.raises(ValueError, match="PREPARE_KICKOFF_YELLOW"):
        referee.game_state(kickoff, get_field("division_b"))
    far = referee.parse_referee(_packet(17, extra=message(9, float32(1, 5000.0) + float32(2, 0.0))))
    with pytest.raises(ValueError, match=r"\(5, 0\) m"):
        referee.game_state(far, get_field("division_b"))


def test_an_oversized_packet_is_named_a_referee_message() -> None:
    with pytest.raises(PacketError) as err:
        referee.parse_referee(b"\x00" * (MAX_PACKET + 1))
    assert str(err.value) == f"oversized: referee message of {MAX_PACKET + 1} bytes > {MAX_PACKET}"


def test_the_teams_required_fields_go_out_empty() -> None:
    # The message carries no team names, scores, cards or timeouts: a HALT parsed from a packet with 4
    # timeouts and 300 us of timeout time left goes back out with "" and 0 for each, its keepers kept.
    theirs = ssl_gc_referee_message_pb2.Referee.FromString(
        referee.encode_referee(referee.parse_referee(_packet(0, yellow_keeper=5, blue_keeper=2)))
    )
    for team, keeper in ((theirs.blue, 2), (theirs.yellow, 5)):
        assert team.name == ""
        counts = (team.score, team.red_cards, team.yellow_cards, team.timeouts, team.timeout_time)
        assert counts == (0, 0, 0, 0, 0)
        assert team.goalkeeper == keeper
