"""FANUC Remote Motion Interface (RMI, R-30iB Plus option R912) message codec.

Facts from FANUC's *Remote Motion Interface Operator's Manual* (B-84184EN/03):

* Every packet is one JSON object in ASCII terminated by CR LF, over TCP.
* A client first connects to port 16001 and sends ``{"Communication": "FRC_Connect"}``;
  the answer carries ``ErrorID``, ``PortNumber`` (the session port, 16002 on a real
  controller), ``MajorVersion`` and ``MinorVersion``. The client closes that socket and
  opens the session port, where it ends with ``{"Communication": "FRC_Disconnect"}``.
* ``Command`` packets (``FRC_Initialize``, ``FRC_GetStatus``, ``FRC_ReadJointAngles``,
  ``FRC_ReadCartesianPosition``, ``FRC_Abort``, ``FRC_Reset``, ``FRC_ReadError``, ...)
  are answered at once with the same ``Command`` key and an ``ErrorID``.
* ``Instruction`` packets (``FRC_JointMotionJRep``, ...) carry a ``SequenceID``: the
  first after ``FRC_Initialize`` is ``NextSequenceID`` of ``FRC_GetStatus`` (1), each
  next one larger by one. Each is answered with its ``Instruction``, ``ErrorID`` and
  ``SequenceID`` once the controller has executed it (for a ``FINE`` motion: the robot
  stands at the target).
* Joint angles are in degrees, ``J1``..``J9``, in the controller's convention (on most
  arms J3 relative to the horizontal).
* A non-zero ``ErrorID`` is a controller error; ``FRC_ReadError`` returns its text in
  ``ErrorData``. RMI's own codes are 2556928 + N for RMIT-0NN (appendix A).
* Unsolicited packets: ``{"Communication": "FRC_Terminate"}`` (the controller ends an
  idle session) and ``{"Communication": "FRC_SystemFault", "SequenceID": n}`` (an
  error while executing the RMI program).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from drivers.errors import ProtocolError

HANDSHAKE_PORT = 16001
SESSION_PORT = 16002
MAX_PACKET = 65536
RMIT_BASE = 2556928

#: A few RMIT error texts of appendix A (ErrorID = RMIT_BASE + N).
RMIT = {
    7: "Controller Servo is Off",
    8: "Teach Pendant is Enabled",
    9: "RMI is Not Running",
    13: "Invalid RMI Command",
    14: "RMI Command Fail",
    15: "Invalid Controller State",
    20: "Invalid RMI Instruction",
    21: "Invalid Value",
    24: "RMI is In HOLD State",
    26: "Robot is Already Connected",
    29: "Invalid sequence ID number",
    30: "Invalid Speed Type",
    31: "Invalid Speed Value",
    32: "Invalid Term Type",
    33: "Invalid Term Value",
    36: "Invalid Destination Position",
    43: "Robot in Single Step Mode",
}


def rmit(n: int) -> int:
    """ErrorID of RMIT-0NN."""
    return RMIT_BASE + n


def error_name(error_id: int) -> str:
    """``RMIT-029 Invalid sequence ID number`` for an RMIT ErrorID, else ``ErrorID n``."""
    n = int(error_id) - RMIT_BASE
    if 0 < n < 100:
        return f"RMIT-{n:03d}" + (f" {RMIT[n]}" if n in RMIT else "")
    return f"ErrorID {error_id}"


def encode(packet: dict[str, Any]) -> bytes:
    """One packet on the wire: compact JSON, ASCII, CR LF."""
    return (json.dumps(packet, separators=(",", ":")) + "\r\n").encode("ascii")


def decode(line: bytes) -> dict[str, Any]:
    """Parse one CR LF-terminated packet (the terminator may be stripped already)."""
    try:
        obj = json.loads(line.decode("ascii").strip())
    except (UnicodeDecodeError, ValueError) as err:
        raise ProtocolError(f"RMI packet is not ASCII JSON: {line[:80]!r}") from err
    if not isinstance(obj, dict):
        raise ProtocolError(f"RMI packet is not a JSON object: {line[:80]!r}")
    return obj


def kind(packet: dict[str, Any]) -> tuple[str, str]:
    """``("Command", "FRC_GetStatus")``: which of the three packet families, and its name."""
    for key in ("Communication", "Command", "Instruction"):
        if isinstance(packet.get(key), str):
            return key, packet[key]
    raise ProtocolError(f"RMI packet without Communication/Command/Instruction: {packet!r}")


def joint_angles(packet: dict[str, Any], n: int = 6) -> np.ndarray:
    """``JointAngle`` J1..Jn (deg) of a packet, in rad."""
    ja = packet.get("JointAngle")
    if not isinstance(ja, dict):
        raise ProtocolError(f"RMI packet has no JointAngle object: {packet!r}")
    try:
        return np.deg2rad([float(ja[f"J{i}"]) for i in range(1, n + 1)])
    except (KeyError, TypeError, ValueError) as err:
        raise ProtocolError(f"RMI JointAngle lacks J1..J{n} numbers: {ja!r}") from err


def joint_object(q: np.ndarray) -> dict[str, float]:
    """``{"J1": .., ..., "J9": ..}`` (deg, 4 decimals) of six angles in rad; J7..J9 zero."""
    deg = np.rad2deg(np.asarray(q, float))
    out = {f"J{i + 1}": round(float(v), 4) for i, v in enumerate(deg)}
    out.update({f"J{i}": 0.0 for i in range(len(deg) + 1, 10)})
    return out


def position_matrix(packet: dict[str, Any]) -> np.ndarray:
    """4x4 pose (m) of a ``Position`` object: X, Y, Z in mm, W, P, R in degrees.

    FANUC's W, P, R turn about the fixed x, y, z axes in that order:
    R = Rz(R) Ry(P) Rx(W).
    """
    from scipy.spatial.transform import Rotation

    pos = packet.get("Position")
    try:
        x, y, z, w, p, r = (float(pos[k]) for k in ("X", "Y", "Z", "W", "P", "R"))
    except (KeyError, TypeError, ValueError) as err:
        raise ProtocolError(f"RMI Position lacks X, Y, Z, W, P, R numbers: {pos!r}") from err
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [w, p, r], degrees=True).as_matrix()
    T[:3, 3] = np.array([x, y, z]) * 1e-3
    return T
