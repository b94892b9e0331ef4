"""One robot, one acquisition at a time, across every process of this machine.

A hardware acquisition holds a claim on its robot, named by the protocol's
``[instruments.robot]`` driver and address, for as long as it may move it. The
claim is a Unix socket bound in Linux's abstract namespace: binding a name that
another process holds fails at once, and the kernel releases the name when the
holder closes the socket or ends, so a crashed acquisition leaves no stale claim
and nothing is written on disk. The command line and every GUI route go through
the acquisition job, so they share this rule whatever their workspace.

The simulated lab is not claimed here: each fake run owns its own simulated
robot (the GUI's workspace rule, :mod:`campaign.web.acquire_rule`, still keeps
one acquisition per protocol robot inside a workspace). Where abstract sockets
do not exist (not Linux), :func:`hold` says so and claims nothing.
"""

from __future__ import annotations

import errno
import hashlib
import socket
import sys
from dataclasses import dataclass

from analysis.errors import InputError

#: prefix of the abstract socket names (the leading NUL makes them abstract)
PREFIX = b"\0robot-stiffness-campaign/robot/"


class RobotBusy(InputError):
    """Another acquisition on this machine holds the robot's claim."""

    def __init__(self, robot: str) -> None:
        super().__init__(f"an acquisition is already running on this robot ({robot}) in "
                         "another process of this machine; one robot, one acquisition at a "
                         "time: wait for it to end or abort it", where="robot")


@dataclass
class RobotClaim:
    """A held claim on one robot (``robot`` is "driver address"); ``release`` ends it."""

    robot: str
    sock: socket.socket | None

    def release(self) -> None:
        """Give the robot back (idempotent)."""
        if self.sock is not None:
            self.sock.close()
            self.sock = None


def claim_name(robot: str) -> bytes:
    """The abstract socket name of ``robot`` ("driver address"): a hash, so that any
    address fits the 108-byte limit of a socket name."""
    return PREFIX + hashlib.sha256(robot.encode()).hexdigest()[:40].encode()


def hold(robot: str) -> RobotClaim:
    """Claim ``robot`` for this process; RobotBusy when another process holds it."""
    if not sys.platform.startswith("linux"):
        return RobotClaim(robot, None)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.bind(claim_name(robot))
    except OSError as err:
        sock.close()
        if err.errno == errno.EADDRINUSE:
            raise RobotBusy(robot) from None
        raise
    return RobotClaim(robot, sock)
