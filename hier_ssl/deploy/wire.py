"""The wire: SSL-Vision packets and robot commands to and from bytes, through the ``protobuf`` runtime.

Decoding checks what arrives once, here: a packet that does not parse, lacks a required field, is larger
than ``MAX_PACKET`` bytes or holds a value no camera could report raises ``PacketError`` naming why, and
the caller drops and counts it. Everything past this module is in hier_ssl's units: metres, radians,
seconds, field frame (origin at the centre, x along the length); commands in the robot's own frame
(x forward, y to the left).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from google.protobuf.message import DecodeError

from hier_ssl.deploy.proto import grsim_pb2, ssl_simulation_pb2, ssl_vision_pb2

# Larger than any vision packet of a full field (32 robots, 4 cameras' geometry is about 3 kB), smaller
# than a datagram can be: what is bigger is not SSL-Vision.
MAX_PACKET = 16384
TEAMS = ("blue", "yellow")
MAX_ROBOT_ID = 15  # the league's robot ids
# No SSL field is larger: a detection beyond 20 m of the centre is corrupt.
MAX_COORD_MM = 20000.0


class PacketError(ValueError):
    """A packet that is dropped: its ``reason`` is the counter it goes to."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True)
class Detection:
    """One robot seen by one camera: ``team`` "blue" or "yellow", ``robot`` id, x, y (m), ``angle`` (rad,
    None when the camera gave no orientation)."""

    team: str
    robot: int
    x: float
    y: float
    angle: float | None


@dataclass(frozen=True)
class DetectionFrame:
    """One camera frame: capture and send times (s, the vision machine's clock), camera, robots, and the
    ball the camera is surest of (x, y m; None when it saw none)."""

    t_capture: float
    t_sent: float
    camera: int
    robots: tuple[Detection, ...]
    ball: tuple[float, float] | None = None


@dataclass(frozen=True)
class FieldGeometry:
    """A geometry packet's field in metres, by SSL-Vision's names (those of ``hier_ssl.world.field.Field``,
    whose docstring says what each is); the defense area's sizes are None where the packet lacks them."""

    field_length: float
    field_width: float
    goal_width: float
    goal_depth: float
    boundary_width: float
    penalty_area_depth: float | None = None
    penalty_area_width: float | None = None


# Sizes a geometry packet must agree on with the field a manager was trained on. The goal and the boundary
# are left out: the manager's observation holds neither (the goal is the rules' concern, the walls the
# controller's reach), and venues' boundaries differ from the rules' 0.3 m.
CHECKED_SIZES = ("field_length", "field_width", "penalty_area_depth", "penalty_area_width")
# m: the wire's sizes are whole millimetres, and a venue's configured field may be off the rules' by a few
# centimetres; the presets differ from one another by metres.
FIELD_TOLERANCE = 0.05


def check_field(seen: FieldGeometry, trained: Any) -> None:
    """ValueError naming both fields' sizes (m) unless ``seen`` agrees with ``trained`` (a ``Field``) on
    ``CHECKED_SIZES`` within ``FIELD_TOLERANCE``; a size the packet lacks is not compared."""
    wrong = [
        name
        for name in CHECKED_SIZES
        if getattr(seen, name) is not None
        and abs(getattr(seen, name) - getattr(trained, name)) > FIELD_TOLERANCE
    ]
    if wrong:

        def sizes(fld: Any) -> str:
            return ", ".join(f"{name} {getattr(fld, name)}" for name in CHECKED_SIZES)

        raise ValueError(
            f"the geometry packet's field ({sizes(seen)} m) is not the field the manager was trained on "
            f"({trained.name}: {sizes(trained)} m; tolerance {FIELD_TOLERANCE} m): {', '.join(wrong)} differ"
        )


def parse_message(message: type, data: bytes, what: str) -> Any:
    """``data`` as a ``message``, checked: size, parse, required fields; ``PacketError`` naming why not."""
    if len(data) > MAX_PACKET:
        raise PacketError("oversized", f"{what} of {len(data)} bytes > {MAX_PACKET}")
    packet = message()
    try:
        packet.ParseFromString(data)
    except (DecodeError, RuntimeError, ValueError) as err:  # RuntimeError: recursion in nested junk
        raise PacketError("malformed", f"{what} does not parse ({err})") from None
    if not packet.IsInitialized():  # the parser leaves required fields of nested messages unchecked
        missing = ", ".join(packet.FindInitializationErrors()[:3])
        raise PacketError("malformed", f"{what} lacks required fields ({missing})")
    return packet


def _finite(name: str, *values: float) -> None:
    if not all(math.isfinite(v) for v in values):
        raise PacketError("invalid", f"{name} is not finite")


def _robot(team: str, robot: ssl_vision_pb2.SSL_DetectionRobot) -> Detection:
    if not robot.HasField("robot_id") or robot.robot_id > MAX_ROBOT_ID:
        raise PacketError(
            "invalid", f"{team} robot id {robot.robot_id if robot.HasField('robot_id') else None}"
        )
    _finite("robot position", robot.x, robot.y)
    if abs(robot.x) > MAX_COORD_MM or abs(robot.y) > MAX_COORD_MM:
        raise PacketError("invalid", f"{team} robot {robot.robot_id} at ({robot.x}, {robot.y}) mm")
    angle = robot.orientation if robot.HasField("orientation") else None
    if angle is not None:
        _finite("robot orientation", angle)
    return Detection(team, robot.robot_id, robot.x / 1000.0, robot.y / 1000.0, angle)


def _ball(balls: Any) -> tuple[float, float] | None:
    """The most confident of a frame's balls (m), or None; ``PacketError`` for one no camera could see."""
    best = None
    for ball in balls:
        _finite("ball", ball.x, ball.y, ball.confidence)
        if abs(ball.x) > MAX_COORD_MM or abs(ball.y) > MAX_COORD_MM:
            raise PacketError("invalid", f"ball at ({ball.x}, {ball.y}) mm")
        if best is None or ball.confidence > best.confidence:
            best = ball
    return None if best is None else (best.x / 1000.0, best.y / 1000.0)


def parse_vision(data: bytes) -> DetectionFrame | FieldGeometry:
    """An ``SSL_WrapperPacket`` as its detection frame (or, for a geometry-only packet, its field);
    ``PacketError`` for anything else."""
    packet = parse_message(ssl_vision_pb2.SSL_WrapperPacket, data, "vision packet")
    if packet.HasField("detection"):
        frame = packet.detection
        _finite("frame time", frame.t_capture, frame.t_sent)
        robots = tuple(
            _robot(team, robot)
            for team, robots in (("blue", frame.robots_blue), ("yellow", frame.robots_yellow))
            for robot in robots
        )
        return DetectionFrame(frame.t_capture, frame.t_sent, frame.camera_id, robots, _ball(frame.balls))
    if packet.HasField("geometry"):
        size = packet.geometry.field

        def metres(name: str) -> float | None:
            return getattr(size, name) / 1000.0 if size.HasField(name) else None

        return FieldGeometry(**{name: metres(name) for name in FieldGeometry.__dataclass_fields__})
    raise PacketError("empty", "vision packet holds neither detection nor geometry")


def encode_detection(frame_number: int, frame: DetectionFrame) -> bytes:
    """An ``SSL_WrapperPacket`` with ``frame`` (metres in, millimetres on the wire)."""
    packet = ssl_vision_pb2.SSL_WrapperPacket()
    out = packet.detection
    out.frame_number, out.camera_id = frame_number, frame.camera
    out.t_capture, out.t_sent = frame.t_capture, frame.t_sent
    for seen in frame.robots:
        robot = (out.robots_blue if seen.team == "blue" else out.robots_yellow).add()
        robot.confidence, robot.robot_id = 1.0, seen.robot
        robot.x, robot.y = seen.x * 1000.0, seen.y * 1000.0
        robot.pixel_x = robot.pixel_y = 0.0
        if seen.angle is not None:
            robot.orientation = seen.angle
    if frame.ball is not None:
        ball = out.balls.add()
        ball.confidence, ball.x, ball.y = 1.0, frame.ball[0] * 1000.0, frame.ball[1] * 1000.0
        ball.pixel_x = ball.pixel_y = 0.0
    return packet.SerializeToString()


def encode_geometry(fld: Any) -> bytes:
    """An ``SSL_WrapperPacket`` with the geometry of ``fld`` (a ``Field`` or ``FieldGeometry``; m in, mm on
    the wire); a defense area size that is None is left out."""
    packet = ssl_vision_pb2.SSL_WrapperPacket()
    out = packet.geometry.field
    for name in FieldGeometry.__dataclass_fields__:
        if getattr(fld, name) is not None:
            setattr(out, name, round(getattr(fld, name) * 1000))
    return packet.SerializeToString()


Command = tuple[int, float, float, float]
"""One robot's command: id, forward and left velocity (m/s, robot frame), angular velocity (rad/s)."""


def encode_grsim(commands: list[Command], yellow: bool, timestamp: float) -> bytes:
    """A ``grSim_Packet`` driving ``commands``' robots of one team by their local velocity."""
    packet = grsim_pb2.grSim_Packet()
    out = packet.commands
    out.timestamp, out.isteamyellow = timestamp, yellow
    for robot, forward, left, angular in commands:
        cmd = out.robot_commands.add()
        cmd.id, cmd.veltangent, cmd.velnormal, cmd.velangular = robot, forward, left, angular
        cmd.kickspeedx = cmd.kickspeedz = 0.0
        cmd.spinner = cmd.wheelsspeed = False
    return packet.SerializeToString()


def encode_simulation(commands: list[Command]) -> bytes:
    """A ``RobotControl`` with a local-velocity move command for each robot (the team is the port's)."""
    packet = ssl_simulation_pb2.RobotControl()
    for robot, forward, left, angular in commands:
        cmd = packet.robot_commands.add()
        cmd.id = robot
        move = cmd.move_command.local_velocity
        move.forward, move.left, move.angular = forward, left, angular
    return packet.SerializeToString()


def _checked_command(robot: int, forward: float, left: float, angular: float) -> Command:
    _finite(f"robot {robot}'s command", forward, left, angular)
    return robot, forward, left, angular


def parse_grsim(data: bytes) -> tuple[bool, list[Command]]:
    """(is the team yellow, its robots' commands) of a ``grSim_Packet``; ``PacketError`` otherwise."""
    packet = parse_message(grsim_pb2.grSim_Packet, data, "grSim packet")
    if not packet.HasField("commands"):
        raise PacketError("empty", "grSim packet without commands")
    out = packet.commands
    if any(cmd.wheelsspeed for cmd in out.robot_commands):
        raise PacketError("unsupported", "grSim wheel speeds (only local velocities are simulated)")
    commands = [_checked_command(c.id, c.veltangent, c.velnormal, c.velangular) for c in out.robot_commands]
    return out.isteamyellow, commands


def parse_simulation(data: bytes) -> tuple[list[Command], list[int]]:
    """A ``RobotControl``'s local-velocity commands, and the ids of robots whose command moves them
    another way (which the sender is told about); ``PacketError`` when it does not parse."""
    packet = parse_message(ssl_simulation_pb2.RobotControl, data, "robot control")
    commands, other = [], []
    for cmd in packet.robot_commands:
        if cmd.move_command.WhichOneof("command") == "local_velocity":
            move = cmd.move_command.local_velocity
            commands.append(_checked_command(cmd.id, move.forward, move.left, move.angular))
        else:
            other.append(cmd.id)
    return commands, other


def encode_response(errors: list[tuple[str, str]]) -> bytes:
    """A ``RobotControlResponse`` listing (code, message) errors."""
    packet = ssl_simulation_pb2.RobotControlResponse()
    for code, message in errors:
        error = packet.errors.add()
        error.code, error.message = code, message
    return packet.SerializeToString()


def parse_response(data: bytes) -> list[str]:
    """The error messages of a simulator's ``RobotControlResponse``; ``PacketError`` when it does not
    parse."""
    packet = parse_message(ssl_simulation_pb2.RobotControlResponse, data, "robot control response")
    return [f"{error.code}: {_error_message(error)}" for error in packet.errors]


def _error_message(error: ssl_simulation_pb2.SimulatorError) -> str:
    """The message of either shape of ``SimulatorError`` (the .proto's note): field 3's, else field 2's
    string; a simulator's text is shown, so bytes that are not UTF-8 are replaced rather than dropped."""
    if error.HasField("message"):
        return error.message
    return error.message_or_capability.decode("utf-8", errors="replace")


__all__ = [
    "MAX_PACKET",
    "TEAMS",
    "Command",
    "Detection",
    "DetectionFrame",
    "CHECKED_SIZES",
    "FIELD_TOLERANCE",
    "FieldGeometry",
    "PacketError",
    "check_field",
    "encode_detection",
    "encode_geometry",
    "encode_grsim",
    "encode_response",
    "encode_simulation",
    "parse_message",
    "parse_grsim",
    "parse_response",
    "parse_simulation",
    "parse_vision",
]
