"""Byte-level transcripts of every protocol encoder/decoder (expected bytes written out by hand)."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from drivers import ati_netcan, ati_netft, emscon, geocom, kvp, modbus, robotiq_ft300, rtde
from drivers.errors import DeviceFault, ProtocolError


def test_rdt_request_bytes():
    assert ati_netft.encode_request(0x0002, 0) == bytes.fromhex("1234 0002 00000000")
    assert ati_netft.encode_request(0x0042, 1) == bytes.fromhex("1234 0042 00000001")
    assert ati_netft.decode_request(bytes.fromhex("1234 0000 00000000")) == (0, 0)
    with pytest.raises(ProtocolError, match="0x1234"):
        ati_netft.decode_request(bytes.fromhex("4321 0002 00000000"))


def test_rdt_record_decoding_and_scaling():
    raw = bytes.fromhex("00000005 0000000a 00000000 000f4240 fff0bdc0 00000000"
                        "00000064 ffffff9c 00000001")
    (rec,) = ati_netft.decode_records(raw)
    assert (rec.rdt_sequence, rec.ft_sequence, rec.status) == (5, 10, 0)
    assert rec.counts == (1_000_000, -1_000_000, 0, 100, -100, 1)
    cal = ati_netft.NetFTCalibration(1e6, 1e3, "N", "N-mm")
    np.testing.assert_allclose(np.array(rec.counts) * cal.scale(),
                               [1.0, -1.0, 0, 1e-4, -1e-4, 1e-6])
    assert len(ati_netft.decode_records(raw * 3)) == 3
    with pytest.raises(ProtocolError, match="multiple of 36"):
        ati_netft.decode_records(raw[:-1])


def test_netft_calibration_xml():
    xml = b"<netft><cfgcpf>1000000</cfgcpf><cfgcpt>1000</cfgcpt><scfgfu>lbf</scfgfu>" \
          b"<scfgtu>lbf-in</scfgtu></netft>"
    cal = ati_netft.parse_calibration_xml(xml)
    np.testing.assert_allclose(cal.scale(), [4.4482216152605e-6] * 3 + [0.112984829e-3] * 3,
                               rtol=1e-9)
    for bad in (b"<netft>", b"<netft><cfgcpf>1</cfgcpf></netft>",
                b"<netft><cfgcpf>x</cfgcpf><cfgcpt>1</cfgcpt></netft>",
                b"<netft><cfgcpf>1</cfgcpf><cfgcpt>1</cfgcpt><scfgfu>stone</scfgfu></netft>"):
        with pytest.raises(ProtocolError):
            ati_netft.parse_calibration_xml(bad)


def test_modbus_crc_matches_the_robotiq_manual_example():
    # FT 300 manual: start the stream with 09 10 01 9A 00 01 02 02 00 CD CA
    start = modbus.encode_write_registers(robotiq_ft300.SLAVE_ID, robotiq_ft300.STREAM_REGISTER,
                                          [robotiq_ft300.STREAM_START])
    assert start == bytes.fromhex("09 10 01 9A 00 01 02 02 00 CD CA")
    assert modbus.crc16_modbus(b"123456789") == 0x4B37  # CRC-16/MODBUS check value
    assert modbus.decode_write_registers_request(start) == (9, 410, [0x0200])
    reply = modbus.encode_write_registers_reply(9, 410, 1)
    assert reply[:6] == bytes.fromhex("09 10 01 9A 00 01")
    modbus.decode_write_registers_reply(reply, 9, 410, 1)
    with pytest.raises(ProtocolError, match="exception code 2"):
        modbus.decode_write_registers_reply(modbus.with_crc(bytes([9, 0x90, 2])), 9, 410, 1)
    with pytest.raises(ProtocolError, match="CRC"):
        modbus.check_crc(start[:-1] + b"\x00")


def test_ft300_stream_frame():
    body = bytes.fromhex("20 4e") + struct.pack("<6h", 1234, -50, 0, 1500, -1, 32000)
    frame = body + modbus.crc16_modbus(body).to_bytes(2, "little")
    np.testing.assert_allclose(robotiq_ft300.decode_stream_frame(frame),
                               [12.34, -0.5, 0, 1.5, -0.001, 32.0])
    assert robotiq_ft300.encode_stream_frame([12.34, -0.5, 0, 1.5, -0.001, 32.0]) == frame
    with pytest.raises(ProtocolError, match="CRC"):
        robotiq_ft300.decode_stream_frame(frame[:-1] + bytes([frame[-1] ^ 1]))
    with pytest.raises(ProtocolError, match="20 4e"):
        robotiq_ft300.decode_stream_frame(b"\x00" + frame[1:])


def test_netcan_ids_and_frames():
    assert ati_netcan.can_id(0x7F, 0x0) == 0x7F0
    assert ati_netcan.can_id(0x01, 0x7) == 0x017
    first = bytes.fromhex("0000 0001 fffe 7fff")
    second = bytes.fromhex("0002 fffd 0000")
    status, sg = ati_netcan.decode_sg_frames(first, second)
    assert status == 0
    np.testing.assert_array_equal(sg, [1, 2, -2, -3, 32767, 0])
    assert ati_netcan.encode_sg_frames(0, sg) == (first, second)
    with pytest.raises(ProtocolError):
        ati_netcan.decode_sg_frames(first[:4], second)


def test_kvp_read_and_write_requests():
    assert kvp.encode_request(7, "$AXIS_ACT") == bytes.fromhex("0007 000c 00 0009") + \
        b"$AXIS_ACT"
    req = kvp.encode_request(8, "STIFF_GO", "TRUE")
    assert req == bytes.fromhex("0008 0011 01 0008") + b"STIFF_GO" + bytes.fromhex("0004") + \
        b"TRUE"
    assert kvp.decode_request(req) == (8, 1, "STIFF_GO", "TRUE")
    value = "{E6AXIS: A1 10.0, A2 -90.5, A3 90, A4 0.0, A5 45.0, A6 -1e-3, E1 0.0}"
    reply = kvp.encode_reply(7, 0, value)
    assert reply[-3:] == b"\x00\x01\x01"
    text = kvp.decode_reply(reply[:4], reply[4:], 7)
    np.testing.assert_allclose(np.rad2deg(kvp.parse_axis(text)), [10, -90.5, 90, 0, 45, -1e-3])
    with pytest.raises(ProtocolError, match="does not answer"):
        kvp.decode_reply(reply[:4], reply[4:], 8)
    bad = kvp.encode_reply(7, 0, "", ok=False)
    with pytest.raises(DeviceFault):
        kvp.decode_reply(bad[:4], bad[4:], 7)


def test_geocom_lines():
    assert geocom.encode_request(2082, 5000, 1) == b"%R1Q,2082:5000,1\r\n"
    assert geocom.encode_request(2008, 1, 1, trid=3) == b"%R1Q,2008,3:1,1\r\n"
    assert geocom.decode_request(b"%R1Q,2008,3:1,1\r\n") == (2008, ["1", "1"], 3)
    assert geocom.reply_trid(b"%R1P,0,3:0\r\n") == 3
    assert geocom.decode_reply(b"%R1P,0,0:0,1.5,-2.25,0.125,17\r\n") == \
        (0, ["1.5", "-2.25", "0.125", "17"])
    assert geocom.decode_reply(b"%R1P,0,0:1285\r\n") == (1285, [])
    with pytest.raises(ProtocolError, match="communication error"):
        geocom.decode_reply(b"%R1P,1,0:\r\n")
    with pytest.raises(ProtocolError, match="malformed"):
        geocom.decode_reply(b"%R1Q,2082:\r\n")


@pytest.mark.parametrize(("header", "head_bytes"), [("int32", "0c000000 00000000"),
                                                     ("int64", "1000000000000000 00000000")])
def test_emscon_command_packet_in_both_header_layouts(header, head_bytes):
    pkt = emscon.encode_packet(emscon.DT_COMMAND, struct.pack("<i", 49), header)
    assert pkt == bytes.fromhex(head_bytes + "31000000")
    size, ptype = emscon.decode_header(pkt[: emscon.HEADERS[header].size], header)
    assert (size, ptype) == (len(pkt), 0)


def test_emscon_data_type_numbers():
    # ES_DataType in ES_C_API_Def.h (TPI V3.6)
    assert (emscon.DT_COMMAND, emscon.DT_ERROR, emscon.DT_SINGLE) == (0, 1, 2)
    assert emscon.DT_PROBE_STATIONARY == 4  # ES_DT_StationaryProbeMeasResult
    assert (emscon.DT_REFLECTOR_POS, emscon.DT_STATUS_CHANGE, emscon.DT_SINGLE2) == (7, 8, 9)
    assert emscon.DT_PROBE_POS == 11  # ES_DT_ProbePosResult: position indication only
    assert emscon.C_START_MEASUREMENT == 49


def test_emscon_stationary_probe_result_bytes():
    # ProbeStationaryResultT, pack(4): sizeof 376; byte offsets from offsetof()
    pkt = bytearray(376)
    pkt[:48] = bytes.fromhex("78010000 04000000"  # lPacketSize 376, ES_DT_StationaryProbeMeasResult
                             "00000000 06000000 00000000"  # status OK, ES_MM_6DStationary, try
                             "01000000 01000000 03000000"  # trigger pressed, Status6D, probe id
                             "02000000 00000000 05000000 01000000")  # field, tip OK, adapter
    for offset, values in ((48, (1200.5, -300.25, 45.0)),  # dPosition1-3
                           (72, (0.01, 0.02, 0.03, 0.04)),  # dStdDevPosition1-3, total
                           (184, (0.5, 0.5, -0.5, 0.5)),  # dQuaternion0-3
                           (216, (0.1, 0.2, 0.3)),  # dRotationAngleX-Z
                           (240, (1e-5, 2e-5, 3e-5)),  # dStdDevRotationAngleX-Z
                           (352, (21.5, 1001.25, 40.0))):  # temperature, pressure, humidity
        struct.pack_into(f"<{len(values)}d", pkt, offset, *values)
    size, ptype = emscon.decode_header(bytes(pkt[:8]))
    assert (size, ptype) == (376, emscon.DT_PROBE_STATIONARY)
    r = emscon.decode_probe(bytes(pkt[8:]))
    assert (r["status"], r["mode"], r["try"], r["trigger"], r["rotation_status"]) == (0, 6, 0, 1, 1)
    assert (r["probe_id"], r["field"], r["tip_status"]) == (3, 2, 0)
    assert (r["tip_adapter_id"], r["tip_adapter_interface"]) == (5, 1)
    np.testing.assert_array_equal(r["xyz"], [1200.5, -300.25, 45.0])
    np.testing.assert_array_equal(r["std"], [0.01, 0.02, 0.03])
    assert r["std_total"] == 0.04
    np.testing.assert_array_equal(r["quat"], [0.5, 0.5, -0.5, 0.5])
    np.testing.assert_array_equal(r["angles"], [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(r["std_angles"], [1e-5, 2e-5, 3e-5])
    assert (r["temperature"], r["pressure"], r["humidity"]) == (21.5, 1001.25, 40.0)
    # the encoder used by the fake writes the same layout
    body = emscon.encode_probe(0, r["xyz"], r["quat"], std=r["std"], angles=r["angles"])
    assert len(body) == 368
    assert body[:40] == bytes.fromhex("00000000 06000000 00000000 00000000 01000000"
                                      "00000000 00000000 00000000 00000000 00000000")
    assert body[48 - 8:72 - 8] == bytes(pkt[48:72])
    assert body[184 - 8:216 - 8] == bytes(pkt[184:216])
    # the 11-type probe position packet is shorter and is not a measurement result
    assert emscon.PROBE_POS_BODY.size + 8 == 108
    with pytest.raises(ProtocolError, match="368 bytes"):
        emscon.decode_probe(emscon.encode_probe_position(np.zeros(3), np.array([1.0, 0, 0, 0])))


def test_emscon_results_round_trip():
    body = emscon.encode_single(0, np.array([1000.0, -250.5, 3.25]), np.array([0.01] * 3))
    assert len(body) == 12 + 17 * 8
    r = emscon.decode_single(body)
    np.testing.assert_allclose(r["xyz"], [1000.0, -250.5, 3.25])
    q = np.array([np.cos(0.2), 0, np.sin(0.2), 0])
    p = emscon.decode_probe(emscon.encode_probe(0, np.array([1.0, 2.0, 3.0]), q))
    np.testing.assert_allclose(p["quat"], q)
    with pytest.raises(ProtocolError, match="unit quaternion"):
        emscon.decode_probe(emscon.encode_probe(0, np.zeros(3), np.array([2.0, 0, 0, 0])))
    with pytest.raises(ProtocolError, match="out of range"):
        emscon.decode_header(struct.pack("<ii", 4, 0))


def test_rtde_packages():
    assert rtde.encode(rtde.REQUEST_PROTOCOL_VERSION, b"\x00\x02") == bytes.fromhex("0005 56 0002")
    assert rtde.decode_header(bytes.fromhex("0004 53")) == (1, rtde.START)
    payload = struct.pack(">d", 125.0) + b"timestamp,actual_q,"
    assert rtde.decode_setup_outputs(payload) == (125.0, ["timestamp", "actual_q"])
    assert [rtde.output_type(n) for n in ("actual_q", "timestamp", "robot_mode", "x",
                                          "output_int_register_12")] == \
        ["VECTOR6D", "DOUBLE", "INT32", "NOT_FOUND", "INT32"]
    packed = rtde.pack_values(["DOUBLE", "VECTOR6D", "INT32"], [1.5, [0, 1, 2, 3, 4, 5], -7])
    assert len(packed) == 8 + 48 + 4 and packed[-4:] == struct.pack(">i", -7)


# --- the fakes answer request bytes with the bytes the real devices give -------------
# Each transcript is request bytes -> response bytes, written out by hand from the
# device documentation named in the test, sent over the fake's own transport (TCP
# socket or serial pty) by a plain client that is not this project's driver.

def _kvp_exchange(sock, request: bytes) -> bytes:
    sock.sendall(request)
    head = _recv(sock, 4)
    return head + _recv(sock, struct.unpack(">H", head[2:])[0])


def _recv(sock, n: int) -> bytes:
    buf = b""
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        assert chunk, "peer closed"
        buf += chunk
    return buf


@pytest.fixture
def home_world():
    from drivers.sim.settings import LabSettings
    from drivers.sim.world import World

    return World(LabSettings(home=tuple(np.radians([0.0, -90.0, 90.0, 0.0, 0.0, 0.0])),
                             seed=3, time_scale=200.0, force_noise=0.0, torque_noise=0.0))


def test_kvp_fake_transcripts(home_world):
    """KUKAVARPROXY (ImtsSrl sources, basMain.readMsg): reply = id, length of the rest,
    function, value length, value, 00 01 then 01 (success) or 00 (failure)."""
    import socket

    from drivers.sim.fake_kvp import FakeKukaVarProxy

    fake = FakeKukaVarProxy(home_world)
    fake.start()
    try:
        with socket.create_connection((fake.host, fake.port), timeout=5) as s:
            # read $OV_PRO (message id 48) -> "100"
            assert _kvp_exchange(s, bytes.fromhex("0030 000a 00 0007") + b"$OV_PRO") == \
                bytes.fromhex("0030 0009 00 0003") + b"100" + bytes.fromhex("000101")
            # write $OV_PRO = 50 -> echoed with success; read back
            assert _kvp_exchange(s, bytes.fromhex("0031 000e 01 0007") + b"$OV_PRO" +
                                 bytes.fromhex("0002") + b"50") == \
                bytes.fromhex("0031 0008 01 0002") + b"50" + bytes.fromhex("000101")
            assert _kvp_exchange(s, bytes.fromhex("0032 000a 00 0007") + b"$OV_PRO")[7:-3] \
                == b"50"
            # the operating mode is an enumeration value, KRL syntax with '#'
            assert _kvp_exchange(s, bytes.fromhex("0033 000b 00 0008") + b"$MODE_OP") == \
                bytes.fromhex("0033 000a 00 0004") + b"#AUT" + bytes.fromhex("000101")
            # an unknown name: the proxy answers an empty value
            assert _kvp_exchange(s, bytes.fromhex("0034 0009 00 0006") + b"$NOPE!") == \
                bytes.fromhex("0034 0006 00 0000 000101")
            # a refused write ($AXIS_ACT is read-only): value echoed, failure flag
            value = b"{E6AXIS: A1 0}"
            assert _kvp_exchange(s, bytes.fromhex("0035 001c 01 0009") + b"$AXIS_ACT" +
                                 bytes.fromhex("000e") + value) == \
                bytes.fromhex("0035 0014 01 000e") + value + bytes.fromhex("000100")
            # PING -> PONG (the proxy's keep-alive)
            assert _kvp_exchange(s, bytes.fromhex("0036 0007 00 0004") + b"PING") == \
                bytes.fromhex("0036 000a 00 0004") + b"PONG" + bytes.fromhex("000101")
            # an unknown function code: a header with content length 0
            assert _kvp_exchange(s, bytes.fromhex("0037 0007 07 0004") + b"PING") == \
                bytes.fromhex("0037 0000")
            # at the pendant home: E6AXIS with the external axes, E6POS in mm/deg with
            # KUKA's status 6 (A3 >= phi, A5 <= 0) and turn 2 (A2 < 0)
            axis = _kvp_exchange(s, kvp.encode_request(9, "$AXIS_ACT"))[7:-3].decode()
            assert axis == ("{E6AXIS: A1 0.0, A2 -90.0, A3 90.0, A4 0.0, A5 0.0, A6 0.0, "
                            "E1 0.0, E2 0.0, E3 0.0, E4 0.0, E5 0.0, E6 0.0}")
            pos = _kvp_exchange(s, kvp.encode_request(10, "$POS_ACT"))[7:-3].decode()
            assert pos == ("{E6POS: X 1765.0, Y 0.0, Z 1109.0, A 0.0, B 90.0, C 0.0, S 6, "
                           "T 2, E1 0.0, E2 0.0, E3 0.0, E4 0.0, E5 0.0, E6 0.0}")
            tool = _kvp_exchange(s, kvp.encode_request(11, "$TOOL"))[7:-3].decode()
            assert tool == "{FRAME: X 0.0, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0}"
    finally:
        fake.stop()


def test_kvp_fake_pos_act_follows_the_pose():
    """$POS_ACT of a moved robot with a tool equals the model's FK (mm, KUKA ZYX angles)."""
    import socket

    from scipy.spatial.transform import Rotation

    from drivers.sim.fake_kvp import FakeKukaVarProxy
    from drivers.sim.settings import LabSettings
    from drivers.sim.world import World

    q = np.radians([20.0, -70.0, 100.0, 30.0, -40.0, 60.0])
    world = World(LabSettings(home=tuple(q), tool_xyz=(0.01, 0.02, 0.15),
                              tool_rpy=(0.1, 0.0, 0.2)))
    fake = FakeKukaVarProxy(world)
    fake.start()
    try:
        with socket.create_connection((fake.host, fake.port), timeout=5) as s:
            text = _kvp_exchange(s, kvp.encode_request(1, "$POS_ACT"))[7:-3].decode()
    finally:
        fake.stop()
    fields = dict(part.split() for part in text[len("{E6POS: "):-1].split(", "))
    T = world.nominal_tool_pose()
    np.testing.assert_allclose([float(fields[k]) for k in "XYZ"], T[:3, 3] * 1e3, atol=1e-5)
    R = Rotation.from_euler("ZYX", [float(fields[k]) for k in "ABC"], degrees=True)
    np.testing.assert_allclose(R.as_matrix(), T[:3, :3], atol=1e-7)
    # turn: A1 > 0, A2 < 0, A3 > 0, A4 > 0, A5 < 0, A6 > 0 -> bits 1 and 4
    assert int(fields["T"]) == 0b010010
    assert int(fields["S"]) & 0b100  # A5 <= 0


def _pty_exchange(fd: int, request: bytes, expect: int, timeout: float = 2.0) -> bytes:
    """Write ``request`` to a serial line and read ``expect`` bytes back (raw pty I/O)."""
    import os
    import select
    import time

    os.write(fd, request)
    buf, deadline = b"", time.monotonic() + timeout
    while len(buf) < expect and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.05)
        if ready:
            buf += os.read(fd, 256)
    return buf


def _open_pty(path: str) -> int:
    import os
    import termios
    import tty

    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    termios.tcflush(fd, termios.TCIOFLUSH)
    return fd


def test_modbus_crc_of_the_classic_rtu_frame():
    # Modbus over Serial Line guide: "01 03 00 00 00 01" carries CRC 84 0A
    assert modbus.with_crc(bytes.fromhex("01 03 00 00 00 01")) == \
        bytes.fromhex("01 03 00 00 00 01 84 0A")


def test_ft300_fake_modbus_transcripts(home_world):
    """FT 300 manual (section 4.3): slave 9, registers 180-185 F/T, 510-514 identity,
    stream start 09 10 01 9A 00 01 02 02 00 CD CA, stop by 0xFF bytes; Modbus exception
    replies (function | 0x80, code) for what the map does not have."""
    import os

    from drivers.sim.fake_ft300 import FakeFT300

    fake = FakeFT300(home_world)
    fake.start()
    fd = _open_pty(fake.path)
    try:
        # no load, no noise: Fx..Mz read 0 with function 3 and with function 4
        for fc in (3, 4):
            req = modbus.with_crc(bytes([9, fc, 0x00, 0xB4, 0x00, 0x06]))
            assert _pty_exchange(fd, req, 17) == modbus.with_crc(bytes([9, fc, 12]) +
                                                                bytes(12))
        # production year (register 514 = 0x0202)
        req = modbus.with_crc(bytes.fromhex("09 03 02 02 00 01"))
        assert _pty_exchange(fd, req, 7) == modbus.with_crc(bytes.fromhex("09 03 02") +
                                                            (2016).to_bytes(2, "big"))
        # an address outside the map -> exception 02; an unknown function -> 01;
        # a count of 0 -> 03; another slave, or a bad CRC -> silence
        assert _pty_exchange(fd, modbus.with_crc(bytes.fromhex("09 03 01 2C 00 01")), 5) \
            == modbus.with_crc(bytes.fromhex("09 83 02"))
        assert _pty_exchange(fd, modbus.with_crc(bytes.fromhex("09 05 00 B4 FF 00")), 5) \
            == modbus.with_crc(bytes.fromhex("09 85 01"))
        assert _pty_exchange(fd, modbus.with_crc(bytes.fromhex("09 04 00 B4 00 00")), 5) \
            == modbus.with_crc(bytes.fromhex("09 84 03"))
        assert _pty_exchange(fd, modbus.with_crc(bytes.fromhex("0A 03 00 B4 00 06")), 1,
                             timeout=0.3) == b""
        assert _pty_exchange(fd, bytes.fromhex("09 03 00 B4 00 06 00 00"), 1,
                             timeout=0.3) == b""
        # the manual's stream start; the reply echoes register 410 and the count
        # the manual's stream start; the reply echoes register 410 and the count, then
        # the 16-byte frames follow at 100 Hz
        got = _pty_exchange(fd, bytes.fromhex("09 10 01 9A 00 01 02 02 00 CD CA"), 8 + 16)
        assert got[:8] == modbus.with_crc(bytes.fromhex("09 10 01 9A 00 01"))
        frame = got[8:24]
        assert frame[:2] == b"\x20\x4e" and robotiq_ft300.decode_stream_frame(frame) \
            .tolist() == [0.0] * 6
        # while streaming the sensor ignores Modbus requests (only 0xFF stops it)
        more = _pty_exchange(fd, modbus.with_crc(bytes.fromhex("09 03 02 02 00 01")), 64)
        assert len(more) >= 64 and all(more[i:i + 2] == b"\x20\x4e"
                                       for i in range(0, len(more) - 15, 16))
        # 0xFF bytes stop the stream; then the registers answer again
        os.write(fd, b"\xff" * 50)
        import time

        time.sleep(0.1)
        import termios

        termios.tcflush(fd, termios.TCIFLUSH)
        req = modbus.with_crc(bytes.fromhex("09 03 00 B4 00 06"))
        assert _pty_exchange(fd, req, 17) == modbus.with_crc(bytes([9, 3, 12]) + bytes(12))
    finally:
        os.close(fd)
        fake.stop()


def test_ft300_fake_answers_minimalmodbus_before_and_after_the_stream(home_world):
    """An independent Modbus RTU client (minimalmodbus) reads the map; our driver's
    stream start and stop leave the register map answering again."""
    minimalmodbus = pytest.importorskip("minimalmodbus")
    from drivers.sim.fake_ft300 import FakeFT300

    home_world.apply_load(np.array([10.0, -20.0, 30.0, 1.0, -2.0, 3.0]))
    time_scale_settle = home_world.tau * 10
    import time

    time.sleep(time_scale_settle)
    fake = FakeFT300(home_world)
    fake.start()
    expected = np.round(home_world.sensor_wrench() / robotiq_ft300.SCALE)

    def read_all():
        inst = minimalmodbus.Instrument(fake.path, 9)
        inst.serial.baudrate = 19200
        inst.serial.timeout = 0.5
        try:
            ft = [inst.read_register(180 + i, signed=True, functioncode=fc)
                  for i, fc in zip(range(6), (3, 4, 3, 4, 3, 4), strict=True)]
            ident = inst.read_registers(510, 5)
            with pytest.raises(minimalmodbus.IllegalRequestError):
                inst.read_register(186)
        finally:
            inst.serial.close()
        return np.array(ft), ident

    try:
        ft, ident = read_all()
        np.testing.assert_array_equal(ft, expected)
        name = b"".join(v.to_bytes(2, "big") for v in ident[:4]).decode()
        assert (name, ident[4]) == ("FT300SIM", 2016)
        with robotiq_ft300.FT300Sensor(fake.url) as sensor:  # start, stream, 0xFF stop
            np.testing.assert_allclose(sensor.read_sample(), expected * robotiq_ft300.SCALE)
        deadline = time.monotonic() + 5
        while fake.streaming and time.monotonic() < deadline:
            time.sleep(0.01)  # the fake reads the stop bytes in its own thread
        assert not fake.streaming
        ft, _ = read_all()
        np.testing.assert_array_equal(ft, expected)
    finally:
        fake.stop()


def test_geocom_fake_transcripts(home_world):
    """TPS1200 GeoCOM manual, section 2.2: request [<LF>]%R1Q,<RPC>[,<TrId>]:<params>,
    reply %R1P,<RC_COM>,<TrId>:<RC>[,<P0>...]; COM_NullProc is RPC 0; a leading LF
    clears the line and gets no reply of its own."""
    import socket

    from drivers.sim.fake_geocom import FakeGeoCom

    fake = FakeGeoCom(home_world)
    fake.start()
    try:
        with socket.create_connection((fake.host, fake.port), timeout=2) as s, \
                s.makefile("rb") as f:
            s.sendall(b"%R1Q,0:\r\n")
            assert f.readline() == b"%R1P,0,0:0\r\n"
            s.sendall(b"\n")  # a bare terminator, as clients send to clear the line
            s.sendall(b"\r\n")
            s.sendall(b"\n%R1Q,0,4:\r\n")  # leading LF, transaction id 4
            assert f.readline() == b"%R1P,0,4:0\r\n"
            s.sendall(b"%R1Q,5003:\r\n")
            assert f.readline() == b"%R1P,0,0:0,123456\r\n"
            s.sendall(b"%R1Q,5004,2:\r\n")
            assert f.readline() == b'%R1P,0,2:0,"SIM GEOCOM"\r\n'
            s.sendall(b"%R1Q,2008,5:1,1\r\n")  # TMC_DoMeasure(TMC_DEF_DIST, TMC_AUTO_INC)
            assert f.readline() == b"%R1P,0,5:0\r\n"
            s.sendall(b"%R1Q,0:\r\n")  # still in step: nothing was left over
            assert f.readline() == b"%R1P,0,0:0\r\n"
    finally:
        fake.stop()


@pytest.mark.parametrize("noise", [b"\r\n", b"\n\r\n", b"%R1P,0,7:0,9.9", b"\x00garbage"])
def test_geocom_driver_survives_stray_terminators_and_partial_lines(noise, scripted_geocom):
    """The instrument sends a bare terminator, or a partial line, before the reply."""
    from drivers.geocom import GeoComTracker

    def reply(rpc, trid):
        good = geocom.encode_reply(0, "1.0", "2.0", "3.0", 0, trid=trid) \
            if rpc == geocom.RPC_GET_COORDINATE else geocom.encode_reply(0, trid=trid)
        return noise, good  # two writes: the stray bytes may arrive alone

    with GeoComTracker(scripted_geocom(reply), timeout=1.0) as drv:
        for _ in range(2):
            np.testing.assert_allclose(drv.measure_point().value, [1.0, 2.0, 3.0])
