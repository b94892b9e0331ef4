"""KUKAVARPROXY message codec (TCP port 7000 on the KUKA controller).

Message layout as implemented by KUKAVARPROXY (ImtsSoft, github
``ImtsSoftware/KUKAVARPROXY``) and documented by its clients (e.g. the
``openshowvar`` projects): all integers big-endian.

request::

    uint16 message id | uint16 content length | uint8 function (0 read, 1 write)
    | uint16 name length | name | [uint16 value length | value]   (write only)

reply::

    uint16 message id | uint16 content length | uint8 function
    | uint16 value length | value | uint16 1 | uint8 success flag

The 3-byte tail is a one-byte field with its length: ``00 01 01`` on success,
``00 01 00`` on failure (KUKAVARPROXY's ``basMain.readMsg``); the content length
counts the tail. A refused write echoes the value with the failure flag. A read of a
name the controller does not know is answered by the proxy with an *empty* value
(its ``ShowVar`` swallows the cross-comm error); :func:`decode_reply` with
``read=True`` refuses that as an unknown variable. Functions other than 0 and 1
(2, 3: the proxy's PLC array formats) are not used here; the proxy answers an unknown
function with a header of content length 0. ``PING`` is answered ``PONG`` by the proxy
itself.

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
FAIL_TAIL = b"\x00\x01\x00"
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
    content = struct.pack(">BH", func, len(bval)) + bval + (OK_TAIL if ok else FAIL_TAIL)
    return struct.pack(">HH", msg_id & 0xFFFF, len(content)) + content


def decode_reply(header: bytes, content: bytes, expect_id: int, name: str = "",
                 read: bool = False) -> str:
    """Decode a reply (4-byte header + content) and return its value text.

    ``name`` is the variable asked for (for messages); with ``read`` an empty value
    (the proxy's answer to an unknown variable) is refused.

    Raises
    ------
    ProtocolError
        Wrong message id, inconsistent lengths.
    DeviceFault
        The controller reports failure (write refused), or a read returns no value.
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
    if content[-3:-1] != b"\x00\x01":
        raise ProtocolError(f"KVP reply status field malformed ({content[-3:].hex(' ')})")
    what = f" for {name}" if name else ""
    if content[-1] != 1:
        raise DeviceFault(f"controller refused the request{what} "
                          f"(status {content[-3:].hex(' ')})")
    if read and vlen == 0:
        raise DeviceFault(f"controller returned no value{what}: unknown variable "
                          "(not declared, or not GLOBAL in a PUBLIC .dat)?")
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
