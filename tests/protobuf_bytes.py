"""Protocol buffer bytes built by hand from field numbers and wire types, so a test can hold a message's
layout against the public protocol's numbers rather than against our own generated code."""

from __future__ import annotations

import struct


def varint(value: int) -> bytes:
    out = b""
    while True:
        low, value = value & 0x7F, value >> 7
        out += bytes([low | (0x80 if value else 0)])
        if not value:
            return out


def tag(number: int, wire_type: int) -> bytes:
    return varint(number << 3 | wire_type)


def uint(number: int, value: int) -> bytes:
    return tag(number, 0) + varint(value)


def float32(number: int, value: float) -> bytes:
    return tag(number, 5) + struct.pack("<f", value)


def double(number: int, value: float) -> bytes:
    return tag(number, 1) + struct.pack("<d", value)


def message(number: int, body: bytes) -> bytes:
    """A length-delimited field: an embedded message, a string or bytes."""
    return tag(number, 2) + varint(len(body)) + body
