"""The protocol modules: regenerated from the project's .proto files they are what is checked in, and the
messages put their fields at the public protocols' numbers and types (bytes built here by hand)."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from protobuf_bytes import double, float32, tag, uint, varint
from protobuf_bytes import message as embed

from hier_ssl.deploy import wire
from hier_ssl.deploy.proto import grsim_pb2, ssl_simulation_pb2, ssl_vision_pb2
from hier_ssl.world.field import get_field

ROOT = Path(__file__).parents[2]
PROTO = ROOT / "hier_ssl" / "deploy" / "proto"
# The generator writes its own version into each module; what it generates from the .proto files is the rest.
_VERSION = re.compile(
    r"# Protobuf Python Version: .*\n|_runtime_version\.ValidateProtobufRuntimeVersion\([^)]*\)\n"
)


@pytest.mark.parametrize("name", ["ssl_vision", "grsim", "ssl_simulation", "ssl_gc_referee_message"])
def test_generated_modules_are_what_protoc_makes_of_the_proto_files(tmp_path: Path, name: str) -> None:
    pytest.importorskip("grpc_tools")
    shutil.copytree(PROTO, tmp_path / "hier_ssl" / "deploy" / "proto")
    source = f"hier_ssl/deploy/proto/{name}.proto"
    command = [sys.executable, "-m", "grpc_tools.protoc", "-I.", "--python_out=.", source]
    (tmp_path / "hier_ssl" / "deploy" / "proto" / f"{name}_pb2.py").unlink()
    subprocess.run(command, cwd=tmp_path, check=True)
    fresh = (tmp_path / source).with_name(f"{name}_pb2.py").read_text()
    checked_in = (PROTO / f"{name}_pb2.py").read_text()
    assert _VERSION.sub("", fresh) == _VERSION.sub("", checked_in)


def test_a_detection_packet_has_the_ssl_vision_field_numbers() -> None:
    robot = float32(1, 1.0) + tag(2, 0) + varint(3) + float32(3, 1500.0) + float32(4, -250.0)
    robot += float32(5, 0.5) + float32(6, 0.0) + float32(7, 0.0)
    frame = tag(1, 0) + varint(7) + double(2, 10.0) + double(3, 10.02) + tag(4, 0) + varint(1)
    frame += embed(7, robot)  # robots_blue
    packet = embed(1, frame)
    parsed = wire.parse_vision(packet)
    assert parsed == wire.DetectionFrame(10.0, 10.02, 1, (wire.Detection("blue", 3, 1.5, -0.25, 0.5),))
    ours = wire.encode_detection(7, parsed)
    assert ssl_vision_pb2.SSL_WrapperPacket.FromString(ours) == ssl_vision_pb2.SSL_WrapperPacket.FromString(
        packet
    )


def test_a_geometry_packet_gives_the_field_by_ssl_visions_names() -> None:
    size = b"".join(uint(n, v) for n, v in ((1, 9000), (2, 6000), (3, 1000), (4, 180), (5, 300)))
    # SSL-Vision before 2019: no defense area; later ones add lines and arcs (6, 7, skipped) and 8, 9.
    assert wire.parse_vision(embed(2, embed(1, size))) == wire.FieldGeometry(9.0, 6.0, 1.0, 0.18, 0.3)
    line = embed(6, embed(1, b"TopTouchLine") + embed(2, float32(1, 0.0) + float32(2, 0.0)))
    full = size + line + uint(8, 1000) + uint(9, 2000)
    b = get_field("division_b")
    geometry = wire.parse_vision(embed(2, embed(1, full)))
    assert geometry == wire.FieldGeometry(9.0, 6.0, 1.0, 0.18, 0.3, 1.0, 2.0)
    names = wire.FieldGeometry.__dataclass_fields__
    assert geometry == wire.FieldGeometry(**{n: getattr(b, n) for n in names})  # the names are Field's
    assert wire.parse_vision(wire.encode_geometry(b)) == geometry


def test_a_field_within_5_cm_of_the_managers_passes_and_one_beyond_fails_naming_both_in_metres() -> None:
    b = get_field("division_b")
    # 4 cm off on every checked size, and a goal and boundary unlike the rules' (not checked): passes.
    wire.check_field(wire.FieldGeometry(9.04, 5.96, 1.3, 0.3, 0.7, 1.04, 1.96), b)
    wire.check_field(wire.FieldGeometry(9.0, 6.0, 9.0, 0.18, 0.3), b)  # no defense area sent: not compared
    with pytest.raises(ValueError) as err:
        wire.check_field(wire.FieldGeometry(9.0, 6.0, 1.0, 0.18, 0.3, 1.0, 2.06), b)
    assert str(err.value) == (
        "the geometry packet's field (field_length 9.0, field_width 6.0, penalty_area_depth 1.0, "
        "penalty_area_width 2.06 m) is not the field the manager was trained on (division_b: field_length "
        "9.0, field_width 6.0, penalty_area_depth 1.0, penalty_area_width 2.0 m; tolerance 0.05 m): "
        "penalty_area_width differ"
    )
    a = wire.parse_vision(wire.encode_geometry(get_field("division_a")))
    seen = r"^the geometry packet's field \(field_length 12\.0, field_width 9\.0, "
    with pytest.raises(ValueError, match=seen + r".*: field_length, field_width, penalty_area_depth, pen"):
        wire.check_field(a, b)


def test_grsim_commands_have_the_grsim_field_numbers() -> None:
    data = wire.encode_grsim([(2, 1.0, -0.5, 0.25)], yellow=True, timestamp=3.0)
    robot = tag(1, 0) + varint(2) + float32(2, 0.0) + float32(3, 0.0) + float32(4, 1.0) + float32(5, -0.5)
    robot += float32(6, 0.25) + tag(7, 0) + varint(0) + tag(8, 0) + varint(0)
    commands = double(1, 3.0) + tag(2, 0) + varint(1) + embed(3, robot)
    assert grsim_pb2.grSim_Packet.FromString(embed(1, commands)) == grsim_pb2.grSim_Packet.FromString(data)
    assert wire.parse_grsim(data) == (True, [(2, 1.0, -0.5, 0.25)])


def test_robot_control_has_the_simulation_protocol_field_numbers() -> None:
    data = wire.encode_simulation([(4, 0.5, 0.25, -1.0)])
    local = float32(1, 0.5) + float32(2, 0.25) + float32(3, -1.0)
    command = tag(1, 0) + varint(4) + embed(2, embed(2, local))
    expected = ssl_simulation_pb2.RobotControl.FromString(embed(1, command))
    assert ssl_simulation_pb2.RobotControl.FromString(data) == expected
    assert wire.parse_simulation(data) == ([(4, 0.5, 0.25, -1.0)], [])
    wheels = (
        tag(1, 0)
        + varint(5)
        + embed(2, embed(1, float32(1, 1.0) + float32(2, 1.0) + float32(3, 1.0) + float32(4, 1.0)))
    )
    assert wire.parse_simulation(embed(1, wheels)) == ([], [5])


def test_a_response_of_the_first_protocol_version_parses_despite_its_feedbacks_uint32_id() -> None:
    # The first version: SimulatorError's message a string at field 2, RobotFeedback's id a uint32 at 1.
    error = embed(1, embed(1, b"E1") + embed(2, b"first version"))
    feedback = embed(2, uint(1, 3) + uint(2, 1))
    assert wire.parse_response(error + feedback) == ["E1: first version"]


def test_a_response_of_the_later_protocol_version_parses_with_its_capability_and_robot_id() -> None:
    # Later versions: the unsupported capability (an enum) at field 2, the message at 3, the id a RobotId.
    error = embed(1, embed(1, b"E2") + uint(2, 2) + embed(3, b"later version"))
    feedback = embed(2, embed(1, uint(1, 3) + uint(2, 2)) + uint(2, 1))
    assert wire.parse_response(error + feedback) == ["E2: later version"]
    assert wire.parse_response(feedback + feedback) == []


def test_a_response_carries_the_simulators_errors() -> None:
    error = embed(1, tag(1, 2) + varint(4) + b"CODE" + tag(3, 2) + varint(3) + b"bad")
    assert wire.parse_response(error) == ["CODE: bad"]
    assert wire.parse_response(wire.encode_response([("X", "y")])) == ["X: y"]


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"\xff" * 10, "malformed"),
        (wire.encode_geometry(get_field("division_b"))[:-3], "malformed"),
        (b"", "empty"),
        (b"\x00" * (wire.MAX_PACKET + 1), "oversized"),
        (embed(1, tag(1, 0) + varint(1)), "malformed"),  # a frame without its required times
    ],
)
def test_bad_vision_packets_raise_a_packet_error_with_its_reason(data: bytes, reason: str) -> None:
    with pytest.raises(wire.PacketError) as err:
        wire.parse_vision(data)
    assert err.value.reason == reason


def test_values_no_camera_reports_are_invalid() -> None:
    far = wire.DetectionFrame(1.0, 1.0, 0, (wire.Detection("blue", 1, 25.0, 0.0, 0.0),))
    with pytest.raises(wire.PacketError, match="invalid"):
        wire.parse_vision(wire.encode_detection(0, far))
    nan = wire.DetectionFrame(float("nan"), 1.0, 0, ())
    with pytest.raises(wire.PacketError, match="not finite"):
        wire.parse_vision(wire.encode_detection(0, nan))
    with pytest.raises(wire.PacketError, match="robot id"):
        wire.parse_vision(
            wire.encode_detection(0, wire.DetectionFrame(1.0, 1.0, 0, (wire.Detection("blue", 16, 0, 0, 0),)))
        )


def _dropped(parse, data: bytes) -> str:
    """The text of the PacketError ``parse`` raises on ``data``: its reason (the counter), a colon, why."""
    with pytest.raises(wire.PacketError) as err:
        parse(data)
    assert str(err.value).startswith(f"{err.value.reason}: ")
    return str(err.value)


def _detection(*robots: wire.Detection, t_capture: float = 1.0, t_sent: float = 1.0) -> bytes:
    return wire.encode_detection(0, wire.DetectionFrame(t_capture, t_sent, 0, robots))


def _padded(packet: bytes, size: int) -> bytes:
    """``packet`` with an unknown field (number 9, length-delimited) that makes it ``size`` bytes."""
    body = size - len(packet) - 3  # its tag is one byte and its length two (128 to 16383 bytes)
    return packet + tag(9, 2) + varint(body) + b"\x00" * body


def test_a_packet_of_exactly_the_maximum_size_is_read_and_one_byte_more_is_dropped() -> None:
    frame = wire.DetectionFrame(1.0, 1.0, 0, (wire.Detection("blue", 0, 1.0, 2.0, 0.5),))
    packet = _padded(wire.encode_detection(0, frame), wire.MAX_PACKET)
    assert len(packet) == wire.MAX_PACKET and wire.parse_vision(packet) == frame
    over = _padded(wire.encode_detection(0, frame), wire.MAX_PACKET + 1)
    assert _dropped(wire.parse_vision, over) == "oversized: vision packet of 16385 bytes > 16384"


@pytest.mark.parametrize(
    ("parse", "what"),
    [
        (wire.parse_vision, "vision packet"),
        (wire.parse_grsim, "grSim packet"),
        (wire.parse_simulation, "robot control"),
        (wire.parse_response, "robot control response"),
    ],
)
def test_bytes_that_do_not_parse_are_malformed_and_named(parse, what: str) -> None:
    assert _dropped(parse, b"\xff" * 10).startswith(f"malformed: {what} does not parse (Error parsing")


def test_missing_required_fields_are_named_up_to_three() -> None:
    # An empty detection frame lacks all four of its required fields; the first three are named.
    missing = "detection.frame_number, detection.t_capture, detection.t_sent"
    assert (
        _dropped(wire.parse_vision, embed(1, b""))
        == f"malformed: vision packet lacks required fields ({missing})"
    )


def test_a_packet_with_neither_detection_nor_geometry_is_empty() -> None:
    assert _dropped(wire.parse_vision, b"") == "empty: vision packet holds neither detection nor geometry"


@pytest.mark.parametrize(("t_capture", "t_sent"), [(math.nan, 1.0), (1.0, math.inf)])
def test_a_frame_time_that_is_not_finite_is_invalid(t_capture: float, t_sent: float) -> None:
    data = _detection(t_capture=t_capture, t_sent=t_sent)
    assert _dropped(wire.parse_vision, data) == "invalid: frame time is not finite"


@pytest.mark.parametrize(("x", "y"), [(math.nan, 0.0), (0.0, math.nan)])
def test_a_robot_position_that_is_not_finite_is_invalid(x: float, y: float) -> None:
    data = _detection(wire.Detection("blue", 1, x, y, 0.0))
    assert _dropped(wire.parse_vision, data) == "invalid: robot position is not finite"


def test_a_robot_orientation_that_is_not_finite_is_invalid() -> None:
    data = _detection(wire.Detection("blue", 1, 0.0, 0.0, math.nan))
    assert _dropped(wire.parse_vision, data) == "invalid: robot orientation is not finite"


def test_a_detection_without_orientation_has_no_angle() -> None:
    frame = wire.DetectionFrame(1.0, 1.0, 0, (wire.Detection("blue", 1, 0.5, -0.5, None),))
    assert wire.parse_vision(wire.encode_detection(0, frame)) == frame


def test_a_yellow_robot_round_trips_as_yellow() -> None:
    frame = wire.DetectionFrame(1.0, 1.0, 2, (wire.Detection("yellow", 4, -1.0, 2.5, -3.0),))
    assert wire.parse_vision(wire.encode_detection(0, frame)) == frame


def test_robot_id_15_and_20_m_from_the_centre_are_the_largest_read() -> None:
    edge = (wire.Detection("blue", 15, 20.0, -20.0, 0.0), wire.Detection("yellow", 15, -20.0, 20.0, 0.0))
    assert wire.parse_vision(_detection(*edge)).robots == edge
    for x, y in ((20.001, 0.0), (0.0, -20.001)):
        message = _dropped(wire.parse_vision, _detection(wire.Detection("blue", 1, x, y, 0.0)))
        assert message == f"invalid: blue robot 1 at ({x * 1000:.1f}, {y * 1000:.1f}) mm"
    assert _dropped(wire.parse_vision, _detection(wire.Detection("yellow", 16, 0, 0, 0))) == (
        "invalid: yellow robot id 16"
    )


def test_a_robot_without_an_id_is_invalid() -> None:
    robot = float32(1, 1.0) + float32(3, 0.0) + float32(4, 0.0) + float32(6, 0.0) + float32(7, 0.0)
    frame = tag(1, 0) + varint(0) + double(2, 1.0) + double(3, 1.0) + tag(4, 0) + varint(0)
    data = embed(1, frame + embed(7, robot))
    assert _dropped(wire.parse_vision, data) == "invalid: blue robot id None"


def test_the_geometry_packet_carries_the_goal_and_boundary_in_millimetres() -> None:
    packet = ssl_vision_pb2.SSL_WrapperPacket.FromString(
        wire.encode_geometry(wire.FieldGeometry(9.0, 6.0, 1.0, 0.6, 0.7, 1.0, 2.0))
    )
    field = packet.geometry.field
    assert (field.goal_width, field.goal_depth, field.boundary_width) == (1000, 600, 700)
    assert (field.penalty_area_depth, field.penalty_area_width) == (1000, 2000)
    without = ssl_vision_pb2.SSL_WrapperPacket.FromString(
        wire.encode_geometry(wire.FieldGeometry(9.0, 6.0, 1.0, 0.18, 0.3))
    )
    assert not without.geometry.field.HasField("penalty_area_depth")


@pytest.mark.parametrize("bad", [0, 1, 2])
def test_a_command_component_that_is_not_finite_is_invalid(bad: int) -> None:
    values = [1.0, -0.5, 0.25]
    values[bad] = math.nan
    grsim = wire.encode_grsim([(2, *values)], yellow=False, timestamp=0.0)
    assert _dropped(wire.parse_grsim, grsim) == "invalid: robot 2's command is not finite"
    simulation = wire.encode_simulation([(2, *values)])
    assert _dropped(wire.parse_simulation, simulation) == "invalid: robot 2's command is not finite"


def test_a_grsim_packet_without_commands_is_empty() -> None:
    replacement = embed(2, b"")  # a grSim_Packet holding only an (empty) replacement
    assert _dropped(wire.parse_grsim, replacement) == "empty: grSim packet without commands"


def test_grsim_wheel_speeds_are_unsupported() -> None:
    robot = tag(1, 0) + varint(2) + float32(2, 0.0) + float32(3, 0.0) + float32(4, 0.0) + float32(5, 0.0)
    robot += float32(6, 0.0) + tag(7, 0) + varint(0) + tag(8, 0) + varint(1)  # wheelsspeed = true
    data = embed(1, double(1, 0.0) + tag(2, 0) + varint(0) + embed(3, robot))
    message = "unsupported: grSim wheel speeds (only local velocities are simulated)"
    assert _dropped(wire.parse_grsim, data) == message


def _ball(confidence: float, x: float, y: float) -> bytes:
    # SSL_DetectionBall: confidence 1, x 3, y 4, pixel_x 6, pixel_y 7 (the required fields)
    return float32(1, confidence) + float32(3, x) + float32(4, y) + float32(6, 0.0) + float32(7, 0.0)


def _frame_with(*balls: bytes) -> bytes:
    frame = uint(1, 1) + double(2, 10.0) + double(3, 10.0) + uint(4, 0)
    return embed(1, frame + b"".join(embed(5, ball) for ball in balls))


def test_the_most_confident_ball_is_kept_in_metres_the_first_of_equals() -> None:
    frame = _frame_with(_ball(0.5, 1000.0, -500.0), _ball(0.75, -1500.0, 250.0), _ball(0.75, 0.0, 0.0))
    assert wire.parse_vision(frame).ball == (-1.5, 0.25)
    assert wire.parse_vision(_frame_with()).ball is None


def test_a_ball_on_the_20_m_edge_is_kept_and_one_beyond_it_dropped() -> None:
    assert wire.parse_vision(_frame_with(_ball(1.0, 20000.0, -20000.0))).ball == (20.0, -20.0)
    for x, y in ((20001.0, 0.0), (0.0, -20001.0)):
        assert _dropped(wire.parse_vision, _frame_with(_ball(1.0, x, y))) == f"invalid: ball at ({x}, {y}) mm"


@pytest.mark.parametrize("ball", [(math.nan, 0.0, 0.0), (1.0, math.nan, 0.0), (1.0, 0.0, math.nan)])
def test_a_ball_with_a_nan_is_dropped(ball: tuple[float, float, float]) -> None:
    assert _dropped(wire.parse_vision, _frame_with(_ball(*ball))) == "invalid: ball is not finite"


def test_an_encoded_frame_carries_its_ball_as_ssl_vision_does() -> None:
    frame = wire.DetectionFrame(10.0, 10.0, 0, (), ball=(-1.5, 0.25))
    expected = ssl_vision_pb2.SSL_WrapperPacket.FromString(_frame_with(_ball(1.0, -1500.0, 250.0)))
    assert ssl_vision_pb2.SSL_WrapperPacket.FromString(wire.encode_detection(1, frame)) == expected
    assert wire.parse_vision(wire.encode_detection(1, frame)).ball == (-1.5, 0.25)


def test_a_simulator_message_that_is_not_utf8_is_shown_replaced() -> None:
    error = embed(1, embed(1, b"E") + embed(2, b"bad \xff"))
    assert wire.parse_response(error) == ["E: bad \ufffd"]


def test_a_field_off_by_exactly_the_tolerance_agrees() -> None:
    # Sizes of 0 and exactly FIELD_TOLERANCE: the only pair whose float difference is the tolerance itself.
    trained = SimpleNamespace(
        name="edge", field_length=0.0, field_width=0.0, penalty_area_depth=0.0, penalty_area_width=0.0
    )
    wire.check_field(wire.FieldGeometry(wire.FIELD_TOLERANCE, 0.0, 1.0, 0.18, 0.3, 0.0, 0.0), trained)
    with pytest.raises(ValueError, match="field_width differ"):
        wire.check_field(wire.FieldGeometry(0.0, 2 * wire.FIELD_TOLERANCE, 1.0, 0.18, 0.3, 0.0, 0.0), trained)
