"""Manual robot and manual load: the operator does the work, the tool guides and records.

:class:`ManualRobot` shows each joint target in degrees, waits for the
operator to jog the robot there, and reads back the angles the teach pendant
shows, typed by the operator. :class:`ManualLoad` asks the operator to hang
or remove a load. Input and output functions are injectable (``ask``,
``say``) so a simulated operator can stand in during tests.

The target is announced on a line of its own, ``target (deg): a1 a2 ...``, so
a simulated operator can read it like a person reads the screen.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np

from drivers.errors import DeviceFault, SafetyRefusal
from drivers.roles import LoadApplicator, LoadCase, RobotController

_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def parse_angles(text: str, n: int) -> np.ndarray:
    """Parse ``n`` angles in degrees (spaces, commas or semicolons between); returns rad."""
    nums = _NUMBER.findall(text)
    if len(nums) != n:
        raise ValueError(f"expected {n} angles in degrees, got {len(nums)}: {text!r}")
    return np.deg2rad([float(v) for v in nums])


class ManualRobot(RobotController):
    """Any robot, driven by an operator at the teach pendant.

    Parameters
    ----------
    address : str
        ``manual://`` (nothing to connect to).
    ask, say : callable
        Input and output functions (default ``input`` and ``print``).
    n_joints : int
        Number of joints to ask for.
    tolerance : float
        Largest accepted difference (rad) between target and typed angles;
        larger differences are asked again.
    """

    attempts = 3

    def __init__(self, address: str = "manual://", *, timeout: float = 1.0,
                 ask: Callable[[str], str] = input, say: Callable[[str], None] = print,
                 n_joints: int = 6, tolerance: float = np.deg2rad(0.5), **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        self.ask, self.say = ask, say
        self.n_joints = n_joints
        self.tolerance = tolerance
        self._last: np.ndarray | None = None

    def _connect(self) -> None:
        pass

    def _close(self) -> None:
        pass

    def _ask_angles(self, prompt: str, target: np.ndarray | None) -> np.ndarray:
        for _ in range(self.attempts):
            answer = self.ask(prompt)
            if answer.strip().lower() in ("stop", "abort", "q"):
                raise SafetyRefusal("operator stopped the campaign")
            try:
                q = parse_angles(answer, self.n_joints)
            except ValueError as err:
                self.say(f"not understood: {err}")
                continue
            if target is not None and np.max(np.abs(q - target)) > self.tolerance:
                worst = int(np.argmax(np.abs(q - target)))
                self.say(f"J{worst + 1} is {np.rad2deg(q[worst] - target[worst]):+.2f} deg from "
                         "the target: jog closer and type the angles again")
                continue
            return q
        raise DeviceFault(f"no valid joint angles after {self.attempts} attempts")

    def _read_joints(self) -> np.ndarray:
        if self._last is None:
            self._last = self._ask_angles(
                f"Type the {self.n_joints} joint angles shown on the pendant (deg): ", None)
        return self._last

    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None:
        self.say("Jog the robot to these joint angles, then type the angles the pendant shows.")
        self.say("target (deg): " + " ".join(f"{v:.3f}" for v in np.rad2deg(q)))
        self.say(f"speed limit {np.rad2deg(speed):.1f} deg/s")
        self._last = self._ask_angles("angles reached (deg), or 'stop': ", q)

    def _stop(self) -> None:
        self.say("STOP: release the enabling switch.")

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(operator=True, tolerance_rad=self.tolerance)
        return d


class ManualLoad(LoadApplicator):
    """Loads hung by the operator; the tool prompts and waits for Enter."""

    def __init__(self, address: str = "manual://", *, timeout: float = 1.0,
                 ask: Callable[[str], str] = input, say: Callable[[str], None] = print,
                 **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        self.ask, self.say = ask, say

    def _connect(self) -> None:
        pass

    def _close(self) -> None:
        pass

    def _apply(self, load: LoadCase) -> None:
        w = np.asarray(load.wrench, float)
        self.say(f"Apply load {load.name!r} at the tool point: force "
                 f"[{w[0]:.1f} {w[1]:.1f} {w[2]:.1f}] N, moment [{w[3]:.2f} {w[4]:.2f} "
                 f"{w[5]:.2f}] N m (robot base frame).")
        self.say("load wrench: " + " ".join(f"{v:.6g}" for v in w))
        self._confirm("Press Enter when the load hangs still, or type 'stop': ")

    def _remove(self) -> None:
        self.say("Remove the load from the tool.")
        self.say("load wrench: 0 0 0 0 0 0")
        self._confirm("Press Enter when the tool is free, or type 'stop': ")

    def _confirm(self, prompt: str) -> None:
        if self.ask(prompt).strip().lower() in ("stop", "abort", "q"):
            raise SafetyRefusal("operator stopped the campaign")
