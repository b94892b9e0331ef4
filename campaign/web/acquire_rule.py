"""The web's one rule for starting or resuming an acquisition, whatever the route.

Every route that can start or resume an acquisition (``/api/acquire/start``,
``/api/acquire/resume``, ``/api/jobs/acquire``) calls :func:`check_hardware` and
holds a :func:`claim` on the robot while the acquisition runs:

* a real robot moves only from a server started with ``--hardware``
  (``app.state.hardware``; 403 otherwise) and only with the safety question
  answered (400 without it), as ``campaign acquire --yes``; a dry run moves
  nothing and connects nothing, so it needs neither;
* one robot, one acquisition at a time: the robot is the plan's (or the run's)
  ``[instruments.robot]`` driver and address, and its claim is an exclusive
  ``flock`` on ``.gui/robots/<hash>.lock`` in the workspace, held by the process
  that drives the robot and released by the kernel when that process ends (no
  stale claim after a crash). The simulated lab stands for the robot of its
  protocol: the rule is the same with and without ``--hardware``.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
from pathlib import Path

from fastapi import HTTPException

from analysis.errors import InputError

#: where the robots' claims live, inside the workspace
CLAIMS = ".gui/robots"


def check_hardware(hardware: bool, fake: bool, confirmed: bool, dry_run: bool = False) -> None:
    """HTTPException unless the acquisition may run: 403 for a real robot from a server
    started without ``--hardware``, 400 for a real robot without the confirmation."""
    if fake or dry_run:
        return
    if not hardware:
        raise HTTPException(403, "hardware: this GUI server was started without --hardware, "
                                 "so it runs acquisitions on the simulated lab only (restart "
                                 "it with `campaign gui --hardware` to drive a real robot)")
    if not confirmed:
        raise HTTPException(400, "confirmation: the robot WILL move; a run on hardware needs "
                                 "the confirmation (the CLI's --yes)")


def robot_of(directory: Path) -> str | None:
    """The robot a plan or run directory drives: its protocol's ``[instruments.robot]``
    driver and address (``"driver address"``); None when the directory's protocol cannot
    be read (the acquisition itself then refuses, before anything is connected)."""
    from analysis.errors import InputError
    from campaign.planning.plan_output import load_plan

    try:
        protocol = load_plan(directory)[0]
        spec = protocol.instruments["robot"]
    except (InputError, OSError, KeyError, ValueError):
        return None
    return f"{spec.driver} {spec.address}"


def claim_file(ws: Path, robot: str) -> Path:
    """The lock file of ``robot`` in the workspace (its directory made, by the path rule)."""
    from campaign.web.api_jobs import inside

    folder = inside(ws, CLAIMS, "robot")
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"{hashlib.sha256(robot.encode()).hexdigest()[:32]}.lock"


class RobotBusy(InputError):
    """Another acquisition holds the robot's claim (the routes answer 409)."""

    def __init__(self, robot: str) -> None:
        super().__init__(f"an acquisition is already running on this robot ({robot}); one "
                         "robot, one acquisition at a time: wait for it to end or abort it",
                         where="robot")


def claim(lock: Path, robot: str) -> int:
    """An open descriptor holding the exclusive claim on ``lock`` (close it, or end the
    process holding it, to release); RobotBusy when another acquisition holds it."""
    fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise RobotBusy(robot) from None
    return fd


def claim_now(lock: Path, robot: str) -> int:
    """:func:`claim` for a route: 409 when another acquisition holds the robot."""
    try:
        return claim(lock, robot)
    except RobotBusy as err:
        raise HTTPException(409, str(err)) from None


def check_free(ws: Path, directory: Path) -> tuple[Path, str] | None:
    """(lock file, robot) of ``directory``'s robot, refused with 409 when an acquisition
    holds it now; None when the directory names no readable robot."""
    robot = robot_of(directory)
    if robot is None:
        return None
    lock = claim_file(ws, robot)
    os.close(claim_now(lock, robot))
    return lock, robot
