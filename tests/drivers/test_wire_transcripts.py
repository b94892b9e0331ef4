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
