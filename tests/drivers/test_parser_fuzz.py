"""Parsers of network bytes, fuzzed: any input gives a value or the driver's own error.

Bounded runs (``max_examples``) keep the suite fast; ``--run-slow`` runs longer ones.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers import ati_netcan, ati_netft, emscon, geocom, kvp, modbus, robotiq_ft300, rtde
from drivers.address import parse_address
from drivers.errors import DriverError, ProtocolError

FAST = settings(max_examples=200, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])


def _own_errors_only(fn, *args):
    try:
        return fn(*args)
    except DriverError:
        return None


@FAST
@given(st.binary(max_size=200))
def test_rdt_records(data):
    out = _own_errors_only(ati_netft.decode_records, data)
    if out is not None:
        assert len(out) * 36 == len(data)


@FAST
@given(st.binary(max_size=40))
def test_ft300_frames(data):
    out = _own_errors_only(robotiq_ft300.decode_stream_frame, data)
    if out is not None:
        assert out.shape == (6,) and np.all(np.abs(out[:3]) <= 327.68)


@FAST
@given(st.binary(min_size=16, max_size=16))
def test_ft300_corrupted_valid_frame_never_passes_with_wrong_values(noise):
    good = robotiq_ft300.encode_stream_frame([1, 2, 3, 0.1, 0.2, 0.3])
    bad = bytes(a ^ b for a, b in zip(good, noise, strict=True))
    out = _own_errors_only(robotiq_ft300.decode_stream_frame, bad)
    if out is not None and bad[2:14] != good[2:14]:
        # CRC-16 catches every error burst up to 16 bits; longer ones only by chance
        changed = [i for i in range(16) if bad[i] != good[i]]
        assert changed[-1] - changed[0] >= 2


@FAST
@given(st.binary(max_size=300))
def test_modbus_frames(data):
    _own_errors_only(modbus.decode_write_registers_request, data)


@FAST
@given(st.binary(max_size=10), st.binary(max_size=10))
def test_netcan_sg_frames(a, b):
    _own_errors_only(ati_netcan.decode_sg_frames, a, b)


@FAST
@given(st.binary(max_size=4), st.binary(max_size=200), st.integers(0, 0xFFFF))
def test_kvp_replies(head, content, msg_id):
    text = _own_errors_only(kvp.decode_reply, head, content, msg_id)
    if text is not None:
        _own_errors_only(kvp.parse_axis, text)


@settings(max_examples=60, deadline=None)
@given(st.text(alphabet="A123456E:{}, .-+e0789x", max_size=120))
def test_kvp_axis_text(text):
    q = _own_errors_only(kvp.parse_axis, text)
    if q is not None:
        assert q.shape == (6,)


@FAST
@given(st.binary(max_size=120))
def test_geocom_replies(line):
    _own_errors_only(geocom.decode_reply, line)


@FAST
@given(st.binary(max_size=200), st.sampled_from(["int32", "int64"]))
def test_emscon_packets(data, header):
    h = emscon.HEADERS[header]
    _own_errors_only(emscon.decode_header, data[: h.size], header)
    _own_errors_only(emscon.decode_single, data)
    _own_errors_only(emscon.decode_probe, data)


@FAST
@given(st.binary(min_size=emscon.PROBE_BODY.size, max_size=emscon.PROBE_BODY.size))
def test_emscon_probe_bodies_of_the_right_length(data):
    r = _own_errors_only(emscon.decode_probe, data)
    if r is not None:
        assert abs(np.linalg.norm(r["quat"]) - 1) <= 1e-3


@FAST
@given(st.binary(max_size=200))
def test_rtde_headers_and_setup(data):
    _own_errors_only(rtde.decode_header, data[:3])
    _own_errors_only(rtde.decode_setup_outputs, data)


@FAST
@given(st.binary(max_size=300))
def test_netft_calibration_page(data):
    _own_errors_only(ati_netft.parse_calibration_xml, data)


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=60))
def test_addresses(text):
    _own_errors_only(parse_address, text)


@pytest.mark.slow
@settings(max_examples=20000, deadline=None)
@given(st.binary(max_size=400))
def test_all_parsers_long_run(data):
    for fn in (ati_netft.decode_records, robotiq_ft300.decode_stream_frame,
               geocom.decode_reply, emscon.decode_single, emscon.decode_probe,
               modbus.decode_write_registers_request, ati_netft.parse_calibration_xml):
        _own_errors_only(fn, data)
    _own_errors_only(kvp.decode_reply, data[:4], data[4:], 1)


def test_fuzz_helper_lets_foreign_errors_through():
    def boom(_):
        raise struct.error("not ours")

    with pytest.raises(struct.error):
        _own_errors_only(boom, b"")
    assert _own_errors_only(lambda _: (_ for _ in ()).throw(ProtocolError("ours")), b"") is None


class _BytesPort:
    """Stands in for a serial port: serves a fixed byte string, then fails as an unplugged
    port does (the driver's ConnectionFailed ends the read loop on the data, not on a clock:
    a short timeout could expire mid-stream on a loaded machine)."""

    def __init__(self, data: bytes) -> None:
        self.data = bytearray(data)
        self.in_waiting = 0

    def read(self, n: int) -> bytes:
        if not self.data:
            raise OSError("end of the test's bytes")
        out = bytes(self.data[:n])
        del self.data[:n]
        return out


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=24),
                          st.tuples(st.integers(-32767, 32766), st.integers(-32767, 32766))),
                max_size=12))
def test_ft300_stream_reassembly_returns_only_sent_frames(pieces):
    """Valid frames mixed with junk: every value returned was sent, and none is lost."""
    sent, stream = [], b""
    for piece in pieces:
        if isinstance(piece, tuple):
            values = np.array([piece[0] / 100, piece[1] / 100, 0, piece[0] / 1000, 0, 0])
            frame = robotiq_ft300.encode_stream_frame(values)
            sent.append(robotiq_ft300.decode_stream_frame(frame))
            stream += frame
        else:
            stream += piece
    drv = robotiq_ft300.FT300Sensor("/dev/null", timeout=60.0)
    drv._ser = _BytesPort(stream)
    drv.max_bad_frames = 10**6
    returned = []
    while True:
        try:
            got = drv._read_sample()
        except DriverError:
            break
        assert any(np.array_equal(got, s) for s in sent) or _is_valid_frame_in(stream, got)
        returned.append(got)
    assert len(returned) >= len(sent)  # resynchronisation recovers every intact frame


def _is_valid_frame_in(stream: bytes, values: np.ndarray) -> bool:
    """True if junk bytes happened to contain a frame with a correct CRC for ``values``."""
    return robotiq_ft300.encode_stream_frame(values) in stream
