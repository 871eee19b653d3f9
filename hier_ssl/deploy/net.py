"""Sockets: the vision receiver (source-checked, unicast or a real field's multicast group), the command
sender (grSim or the simulation protocol) and the loopback control socket (JSON lines of targets).

On a real field SSL-Vision multicasts to 224.5.23.2:10006 and a receiver joins the group on the interface
that faces the vision machine (``--vision-interface``). Everything on one machine, grSim and the field
server included, is unicast to 127.0.0.1.
"""

from __future__ import annotations

import ipaddress
import json
import socket
import struct
from collections.abc import Callable
from dataclasses import dataclass

from hier_ssl.deploy.wire import MAX_PACKET, TEAMS, Command, encode_grsim, encode_simulation

LOOPBACK = "127.0.0.1"
# The simulators' command ports: grSim's one port for both teams, the simulation protocol's per team.
GRSIM_PORT = 20011
SIMULATION_PORTS = {"blue": 10301, "yellow": 10302}
MAX_LINE = 4096  # bytes of one control message
RECEIVE_BUFFER = 1 << 20  # bytes


def parse_address(text: str, default_port: int | None = None, any_port: bool = False) -> tuple[str, int]:
    """``HOST:PORT`` (or ``HOST`` with a default port) as (host, port); ValueError naming the text. Port 0
    (a free one, for an address to bind) only with ``any_port``."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, "" if default_port is None else str(default_port)
    try:
        ipaddress.ip_address(host)
        number = int(port)
    except ValueError:
        raise ValueError(f"address {text!r}: expected IP:PORT, e.g. 127.0.0.1:10006") from None
    if not (0 if any_port else 1) <= number < 65536:
        raise ValueError(f"address {text!r}: port {number} is not in 1..65535")
    return host, number


def open_vision(host: str, port: int, interface: str | None = None) -> socket.socket:
    """A non-blocking UDP socket receiving vision at ``host:port``: bound there when unicast; for a
    multicast group, bound to the group and joined on ``interface`` (required: the address of this
    machine's interface to the vision network)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    # Room for bursts (four cameras' frames at once, a stalled period) rather than losing them.
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
    try:
        if ipaddress.ip_address(host).is_multicast:
            if interface is None:
                raise ValueError(f"vision {host}:{port} is a multicast group: name --vision-interface")
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((host, port))
            membership = struct.pack("4s4s", socket.inet_aton(host), socket.inet_aton(interface))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
        else:
            sock.bind((host, port))
    except BaseException:
        sock.close()
        raise
    sock.setblocking(False)
    return sock


def receive(sock: socket.socket) -> tuple[bytes, tuple[str, int]] | None:
    """One datagram (data, sender's (IP, port)) or None when none is waiting; a datagram over
    ``MAX_PACKET`` comes back one byte longer than the limit, so the decoder counts it as oversized."""
    try:
        data, sender = sock.recvfrom(MAX_PACKET + 1)
    except (BlockingIOError, ConnectionRefusedError):  # refused: an earlier send found no listener
        return None
    return data, sender


@dataclass
class CommandSender:
    """Commands of one ``team`` to ``kind`` ("grsim" or "simulation") at ``address``; the socket also
    receives the simulation protocol's responses."""

    kind: str
    address: tuple[str, int]
    team: str

    def __post_init__(self) -> None:
        if self.kind not in ("grsim", "simulation") or self.team not in TEAMS:
            raise ValueError(
                f"commands {self.kind!r} for team {self.team!r}: expected grsim|simulation, blue|yellow"
            )
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        if ipaddress.ip_address(self.address[0]).is_loopback:
            self.sock.bind((LOOPBACK, 0))  # a loopback peer is answered on loopback, nowhere else
        self.sock.setblocking(False)

    def send(self, commands: list[Command], timestamp: float) -> None:
        if self.kind == "grsim":
            data = encode_grsim(commands, self.team == "yellow", timestamp)
        else:
            data = encode_simulation(commands)
        self.sock.sendto(data, self.address)

    def close(self) -> None:
        self.sock.close()


def command_target(spec: str, team: str) -> tuple[str, tuple[str, int]]:
    """``grsim``, ``simulation`` or either with ``:HOST:PORT`` as (kind, address); without an address,
    the simulator's default port on 127.0.0.1."""
    kind, _, rest = spec.partition(":")
    if kind not in ("grsim", "simulation"):
        raise ValueError(f"commands {spec!r}: expected grsim|simulation[:HOST:PORT]")
    default = GRSIM_PORT if kind == "grsim" else SIMULATION_PORTS[team]
    return kind, parse_address(rest or LOOPBACK, default)


class ControlServer:
    """Targets over TCP on 127.0.0.1: one JSON object per line, ``{"robot": 0, "target": [x, y, theta]}``
    (or with vx, vy), answered ``{"ok": true}`` or ``{"error": "..."}``. ``apply(robot, target)`` raises
    ValueError for a target it refuses; a line that is not such an object is refused the same way, one
    longer than ``MAX_LINE`` bytes ends the connection."""

    def __init__(self, port: int, apply: Callable[[object, object], None]) -> None:
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((LOOPBACK, port))
        self.listener.listen(4)
        self.listener.setblocking(False)
        self.port = self.listener.getsockname()[1]
        self.apply = apply
        self.clients: dict[socket.socket, bytes] = {}
        self.accepted = self.refused = 0

    def accept(self) -> socket.socket | None:
        try:
            client, _ = self.listener.accept()
        except BlockingIOError:
            return None
        client.setblocking(False)
        self.clients[client] = b""
        return client

    def read(self, client: socket.socket) -> bool:
        """Handle what ``client`` sent; False once it is closed (by the peer or for a too long line)."""
        try:
            data = client.recv(MAX_LINE)
        except BlockingIOError:
            return True
        except ConnectionError:
            data = b""
        if not data:
            return self.close(client)
        buffer = self.clients[client] + data
        *lines, rest = buffer.split(b"\n")
        for line in lines:
            self._reply(client, self._handle(line))
        if len(rest) > MAX_LINE:
            self._reply(client, {"error": f"line longer than {MAX_LINE} bytes"})
            self.refused += 1
            return self.close(client)
        self.clients[client] = rest
        return True

    def _handle(self, line: bytes) -> dict[str, object]:
        try:
            message = json.loads(line.decode("utf-8"))
            if not isinstance(message, dict) or set(message) != {"robot", "target"}:
                raise ValueError(f"expected {{'robot': id, 'target': [x, y, theta]}}, got {line[:80]!r}")
            self.apply(message["robot"], message["target"])
        except (UnicodeDecodeError, ValueError) as err:  # JSONDecodeError is a ValueError
            self.refused += 1
            return {"error": str(err)}
        self.accepted += 1
        return {"ok": True}

    def _reply(self, client: socket.socket, answer: dict[str, object]) -> None:
        try:
            client.sendall(json.dumps(answer).encode() + b"\n")
        except OSError:  # the peer left: nothing to tell it
            pass

    def close(self, client: socket.socket) -> bool:
        self.clients.pop(client, None)
        client.close()
        return False

    def shutdown(self) -> None:
        for client in list(self.clients):
            self.close(client)
        self.listener.close()


__all__ = [
    "GRSIM_PORT",
    "LOOPBACK",
    "SIMULATION_PORTS",
    "CommandSender",
    "ControlServer",
    "command_target",
    "open_vision",
    "parse_address",
    "receive",
]
