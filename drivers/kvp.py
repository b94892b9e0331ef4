"""KUKAVARPROXY message codec (TCP port 7000 on the KUKA controller).

Message layout as implemented by KUKAVARPROXY (ImtsSoft, github
``ImtsSoftware/KUKAVARPROXY``) and documented by its clients (e.g. the
``openshowvar`` projects): all integers big-endian.

request::

    uint16 message id | uint16 content length | uint8 function (0 read, 1 write)
    | uint16 name length | name | [uint16 value length | value]   (write only)

reply::

    uint16 message id | uint16 content length | uint8 function
    | uint16 value length | value | 3 status bytes (00 01 01 = success)

Values are KRL text, e.g. ``{E6AXIS: A1 0.0, A2 -90.0, ...}`` for ``$AXIS_ACT``
(degrees) or ``TRUE``.
"""

from __future__ import annotations

import re
import struct

import numpy as np

from drivers.errors import DeviceFault, ProtocolError

READ, WRITE = 0, 1
OK_TAIL = b"\x00\x01\x01"
_AXIS = re.compile(r"\bA([1-6])\s+([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


def encode_request(msg_id: int, name: str, value: str | None = None) -> bytes:
    """Encode a read (``value is None``) or write request."""
    bname = name.encode("ascii")
    content = struct.pack(">BH", READ if value is None else WRITE, len(bname)) + bname
    if value is not None:
        bval = value.encode("ascii")
        content += struct.pack(">H", len(bval)) + bval
    return struct.pack(">HH", msg_id & 0xFFFF, len(content)) + content


def decode_request(data: bytes) -> tuple[int, int, str, str | None]:
    """Decode a whole request into ``(msg_id, function, name, value)`` (used by the fake)."""
    if len(data) < 7:
        raise ProtocolError("KVP request too short")
    msg_id, length, func, nlen = struct.unpack(">HHBH", data[:7])
    if length != len(data) - 4 or 7 + nlen > len(data):
        raise ProtocolError("KVP request length fields inconsistent")
    name = data[7:7 + nlen].decode("ascii", "replace")
    value = None
    if func == WRITE:
        rest = data[7 + nlen:]
        if len(rest) < 2:
            raise ProtocolError("KVP write without a value")
        (vlen,) = struct.unpack(">H", rest[:2])
        value = rest[2:2 + vlen].decode("ascii", "replace")
    elif func != READ:
        raise ProtocolError(f"KVP function {func} is neither read nor write")
    return msg_id, func, name, value


def encode_reply(msg_id: int, func: int, value: str, ok: bool = True) -> bytes:
    """Encode a reply carrying ``value`` and the status tail (used by the fake)."""
    bval = value.encode("ascii")
    content = struct.pack(">BH", func, len(bval)) + bval + (OK_TAIL if ok else b"\x00\x00\x00")
    return struct.pack(">HH", msg_id & 0xFFFF, len(content)) + content


def decode_reply(header: bytes, content: bytes, expect_id: int) -> str:
    """Decode a reply (4-byte header + content) and return its value text.

    Raises
    ------
    ProtocolError
        Wrong message id, inconsistent lengths.
    DeviceFault
        The controller reports failure (unknown variable, write refused).
    """
    if len(header) != 4:
        raise ProtocolError("KVP reply header must be 4 bytes")
    msg_id, length = struct.unpack(">HH", header)
    if length != len(content) or length < 6:
        raise ProtocolError(f"KVP reply length {length} does not match {len(content)} bytes")
    if msg_id != expect_id & 0xFFFF:
        raise ProtocolError(f"KVP reply id {msg_id} does not answer request {expect_id}")
    func, vlen = struct.unpack(">BH", content[:3])
    if 3 + vlen + 3 != len(content):
        raise ProtocolError("KVP reply value length inconsistent")
    if content[-3:] != OK_TAIL:
        raise DeviceFault(f"controller refused the request (status {content[-3:].hex()})")
    return content[3:3 + vlen].decode("ascii", "replace")


def parse_axis(text: str) -> np.ndarray:
    """Joint angles A1..A6 (deg) from a KRL AXIS/E6AXIS value; returns rad."""
    found = {int(k): float(v) for k, v in _AXIS.findall(text)}
    if sorted(found) != [1, 2, 3, 4, 5, 6]:
        raise ProtocolError(f"not an AXIS value with A1..A6: {text[:80]!r}")
    return np.deg2rad([found[i] for i in range(1, 7)])


def format_axis(q: np.ndarray) -> str:
    """KRL E6AXIS aggregate of joint angles ``q`` (rad) in degrees."""
    deg = np.rad2deg(np.asarray(q, float))
    return "{E6AXIS: " + ", ".join(f"A{i + 1} {v:.5f}" for i, v in enumerate(deg)) + "}"
