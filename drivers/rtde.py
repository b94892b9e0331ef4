"""Universal Robots RTDE protocol codec (protocol version 2), for the fake controller and tests.

Source: Universal Robots, *Real-Time Data Exchange (RTDE) Guide* (support
article 22229), "Protocol" section: every package is ``uint16 size`` (whole
package, bytes) + ``uint8 type`` + payload, big-endian. Types used:
``V`` (86) request protocol version (payload uint16, answer uint8 accepted),
``v`` (118) get controller version (answer 4 x uint32),
``O`` (79) setup outputs (payload double frequency + comma-separated names;
answer uint8 recipe id + comma-separated types), ``I`` (73) setup inputs,
``S`` (83) start and ``P`` (80) pause (answer uint8 accepted),
``U`` (85) data package (uint8 recipe id + values), ``M`` (77) text message.

Data packages flow both ways: the controller streams the output recipe, and the
client sends input recipes (set up with ``I``; recipe ids count from 1 per
connection, separately from the output recipe) to write the input registers
and a few input variables. Register ranges: ``input_int_register_0..47``,
``input_double_register_0..47``, ``input_bit_register_64..127`` (PolyScope 5.x;
24..47 are the "upper range").
"""

from __future__ import annotations

import struct

from drivers.errors import ProtocolError

HEADER = struct.Struct(">HB")
REQUEST_PROTOCOL_VERSION = 86
GET_URCONTROL_VERSION = 118
TEXT_MESSAGE = 77
DATA_PACKAGE = 85
SETUP_OUTPUTS = 79
SETUP_INPUTS = 73
START = 83
PAUSE = 80

TYPE_FORMATS = {"DOUBLE": "d", "VECTOR6D": "6d", "VECTOR3D": "3d", "VECTOR6INT32": "6i",
                "VECTOR6UINT32": "6I", "INT32": "i", "UINT32": "I", "UINT64": "Q", "UINT8": "B",
                "BOOL": "?"}

_V6D = ("target_q", "target_qd", "target_qdd", "target_current", "target_moment", "actual_q",
        "actual_qd", "actual_current", "joint_control_output", "actual_TCP_pose",
        "actual_TCP_speed", "actual_TCP_force", "target_TCP_pose", "target_TCP_speed",
        "joint_temperatures", "actual_joint_voltage", "ft_raw_wrench", "payload_inertia")
_DOUBLE = ("timestamp", "speed_scaling", "target_speed_fraction", "actual_momentum",
           "actual_main_voltage", "actual_robot_voltage", "actual_robot_current",
           "actual_execution_time", "standard_analog_input0", "standard_analog_input1",
           "standard_analog_output0", "standard_analog_output1", "payload")
OUTPUT_TYPES: dict[str, str] = {
    **{n: "VECTOR6D" for n in _V6D}, **{n: "DOUBLE" for n in _DOUBLE},
    "actual_digital_input_bits": "UINT64", "actual_digital_output_bits": "UINT64",
    "robot_mode": "INT32", "safety_mode": "INT32", "joint_mode": "VECTOR6INT32",
    "actual_tool_accelerometer": "VECTOR3D", "payload_cog": "VECTOR3D",
    "runtime_state": "UINT32", "robot_status_bits": "UINT32", "safety_status_bits": "UINT32",
}


INPUT_TYPES: dict[str, str] = {
    "speed_slider_mask": "UINT32", "speed_slider_fraction": "DOUBLE",
    "standard_digital_output_mask": "UINT8", "standard_digital_output": "UINT8",
    "configurable_digital_output_mask": "UINT8", "configurable_digital_output": "UINT8",
    "tool_digital_output_mask": "UINT8", "tool_digital_output": "UINT8",
    "standard_analog_output_mask": "UINT8", "standard_analog_output_type": "UINT8",
    "standard_analog_output_0": "DOUBLE", "standard_analog_output_1": "DOUBLE",
    "input_bit_registers0_to_31": "UINT32", "input_bit_registers32_to_63": "UINT32",
    "external_force_torque": "VECTOR6D",
}
REGISTERS = range(48)
BIT_REGISTERS = range(64, 128)


def _register(name: str, prefix: str, numbers: range) -> bool:
    tail = name[len(prefix):]
    return name.startswith(prefix) and tail.isdigit() and int(tail) in numbers


def input_type(name: str) -> str:
    """RTDE type of an input variable, ``NOT_FOUND`` if unknown."""
    if name in INPUT_TYPES:
        return INPUT_TYPES[name]
    if _register(name, "input_int_register_", REGISTERS):
        return "INT32"
    if _register(name, "input_double_register_", REGISTERS):
        return "DOUBLE"
    if _register(name, "input_bit_register_", BIT_REGISTERS):
        return "BOOL"
    return "NOT_FOUND"


def output_type(name: str) -> str:
    """RTDE type of an output variable, ``NOT_FOUND`` if unknown."""
    if name in OUTPUT_TYPES:
        return OUTPUT_TYPES[name]
    if name.startswith("output_int_register_"):
        return "INT32"
    if name.startswith("output_double_register_"):
        return "DOUBLE"
    if name.startswith("output_bit_register_"):
        return "BOOL"
    return "NOT_FOUND"


def encode(ptype: int, payload: bytes = b"") -> bytes:
    """One RTDE package."""
    if HEADER.size + len(payload) > 0xFFFF:
        raise ProtocolError("RTDE package too large")
    return HEADER.pack(HEADER.size + len(payload), ptype) + payload


def decode_header(data: bytes) -> tuple[int, int]:
    """``(payload_size, type)`` from the 3-byte header."""
    if len(data) != HEADER.size:
        raise ProtocolError("RTDE header must be 3 bytes")
    size, ptype = HEADER.unpack(data)
    if size < HEADER.size:
        raise ProtocolError(f"RTDE package size {size} smaller than its header")
    return size - HEADER.size, ptype


def decode_setup_outputs(payload: bytes) -> tuple[float, list[str]]:
    """Frequency (Hz) and variable names of an output setup request (protocol v2)."""
    if len(payload) < 8:
        raise ProtocolError("output setup without frequency")
    (freq,) = struct.unpack(">d", payload[:8])
    names = [n for n in payload[8:].decode("ascii", "replace").split(",") if n]
    return freq, names


def decode_names(payload: bytes) -> list[str]:
    """Variable names of an input setup request (comma-separated, trailing comma allowed)."""
    return [n for n in payload.decode("ascii", "replace").split(",") if n]


def unpack_values(types: list[str], data: bytes) -> list:
    """Values of a data package body (after the recipe id); vectors as lists."""
    out: list = []
    offset = 0
    for t in types:
        fmt = ">" + TYPE_FORMATS[t]
        size = struct.calcsize(fmt)
        if offset + size > len(data):
            raise ProtocolError(f"data package too short for its recipe ({len(data)} bytes)")
        vals = struct.unpack_from(fmt, data, offset)
        out.append(list(vals) if len(vals) > 1 else vals[0])
        offset += size
    if offset != len(data):
        raise ProtocolError(f"data package has {len(data) - offset} bytes beyond its recipe")
    return out


def pack_values(types: list[str], values: list) -> bytes:
    """Pack values for a data package (after the recipe id)."""
    out = b""
    for t, v in zip(types, values, strict=True):
        fmt = TYPE_FORMATS[t]
        out += struct.pack(">" + fmt, *(v if len(fmt) > 1 else [v]))
    return out
