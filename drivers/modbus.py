"""Modbus RTU framing helpers (CRC-16/MODBUS, function 16 "write multiple registers").

Source: *Modbus over Serial Line Specification and Implementation Guide V1.02*
(modbus.org), section 2.5.1.2 and appendix B: CRC polynomial 0xA001 (reflected
0x8005), initial value 0xFFFF, appended low byte first.
"""

from __future__ import annotations

import struct

from drivers.errors import ProtocolError


def crc16_modbus(data: bytes) -> int:
    """CRC-16/MODBUS of ``data`` (integer; send as ``crc.to_bytes(2, "little")``)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def with_crc(frame: bytes) -> bytes:
    """Append the CRC (low byte first)."""
    return frame + crc16_modbus(frame).to_bytes(2, "little")


def check_crc(frame: bytes) -> bytes:
    """Return the frame without its CRC; raise :class:`ProtocolError` if the CRC is wrong."""
    if len(frame) < 3:
        raise ProtocolError(f"Modbus frame of {len(frame)} bytes is too short")
    body, crc = frame[:-2], int.from_bytes(frame[-2:], "little")
    if crc16_modbus(body) != crc:
        raise ProtocolError(f"Modbus CRC mismatch: got 0x{crc:04x}, "
                            f"computed 0x{crc16_modbus(body):04x}")
    return body


def encode_write_registers(slave: int, first: int, values: list[int]) -> bytes:
    """Function 16 request: write ``values`` (uint16) starting at register ``first``."""
    payload = b"".join(struct.pack(">H", v & 0xFFFF) for v in values)
    head = struct.pack(">BBHHB", slave, 0x10, first, len(values), len(payload))
    return with_crc(head + payload)


def decode_write_registers_request(frame: bytes) -> tuple[int, int, list[int]]:
    """Decode a function 16 request into ``(slave, first, values)`` (used by the fake)."""
    body = check_crc(frame)
    if len(body) < 7 or body[1] != 0x10:
        raise ProtocolError("not a function 16 request")
    slave, _fc, first, count, nbytes = struct.unpack(">BBHHB", body[:7])
    if nbytes != 2 * count or len(body) != 7 + nbytes:
        raise ProtocolError("function 16 request with inconsistent byte count")
    values = list(struct.unpack(f">{count}H", body[7:]))
    return slave, first, values


def encode_write_registers_reply(slave: int, first: int, count: int) -> bytes:
    """Function 16 reply echoing the first register and the count."""
    return with_crc(struct.pack(">BBHH", slave, 0x10, first, count))


def decode_write_registers_reply(frame: bytes, slave: int, first: int, count: int) -> None:
    """Check a function 16 reply; exception replies (function | 0x80) raise."""
    body = check_crc(frame)
    if len(body) >= 3 and body[1] == 0x90:
        raise ProtocolError(f"Modbus exception code {body[2]} from slave {body[0]}")
    if body != struct.pack(">BBHH", slave, 0x10, first, count):
        raise ProtocolError(f"unexpected Modbus reply {frame.hex(' ')}")


#: Modbus exception codes (Modbus Application Protocol V1.1b3, section 7).
ILLEGAL_FUNCTION, ILLEGAL_DATA_ADDRESS, ILLEGAL_DATA_VALUE = 1, 2, 3


def encode_read_registers(slave: int, function: int, first: int, count: int) -> bytes:
    """Function 3 (holding) or 4 (input registers) request: ``count`` registers from ``first``."""
    return with_crc(struct.pack(">BBHH", slave, function, first, count))


def encode_read_reply(slave: int, function: int, values: list[int]) -> bytes:
    """Reply to a function 3/4 read: byte count then the registers, big-endian (used by fakes)."""
    payload = b"".join(struct.pack(">H", v & 0xFFFF) for v in values)
    return with_crc(struct.pack(">BBB", slave, function, len(payload)) + payload)


def encode_exception(slave: int, function: int, code: int) -> bytes:
    """Exception reply: the function code with bit 7 set, then the exception code."""
    return with_crc(struct.pack(">BBB", slave, (function | 0x80) & 0xFF, code))


def request_length(buf: bytes | bytearray) -> int | None:
    """Length of the RTU request at the start of ``buf`` (functions 3, 4, 6, 16), or None
    when it cannot be known yet (too few bytes) or the function is not one of those."""
    if len(buf) < 2:
        return None
    if buf[1] in (3, 4, 6):
        return 8
    if buf[1] == 16:
        return 9 + buf[6] if len(buf) >= 7 else None
    return None
