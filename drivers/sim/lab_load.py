"""Automated load applicator of the simulated lab, and a simulated operator.

:class:`LabLoadApplicator` is a real driver whose wire protocol is the lab's
JSON-lines control channel (``lab://127.0.0.1:PORT``). :class:`LabOperator`
stands in for the person at the teach pendant for :class:`~drivers.manual.ManualRobot`
and :class:`~drivers.manual.ManualLoad`: it reads what they print, acts on the
simulated world, and types the answers a careful operator would.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from drivers.manual import parse_angles
from drivers.roles import LoadApplicator, LoadCase
from drivers.sim.control import LabClient


class LabLoadApplicator(LoadApplicator):
    """Applies load cases in the simulated lab through its control channel."""

    def __init__(self, address: str, *, timeout: float = 10.0, **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        self._client: LabClient | None = None

    def _connect(self) -> None:
        self._client = LabClient(self.address, timeout=self.timeout)

    def _close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None

    def _apply(self, load: LoadCase) -> None:
        self._client.call("apply_load", wrench=np.asarray(load.wrench, float).tolist(),
                          name=load.name)

    def _remove(self) -> None:
        self._client.call("remove_load")


class LabOperator:
    """Simulated operator: pass ``ask=op.ask, say=op.say`` to the manual drivers."""

    def __init__(self, control: str, speed: float = 1.0) -> None:
        self.client = LabClient(control)
        self.speed = speed
        self.lines: list[str] = []
        self._target: np.ndarray | None = None
        self._load: np.ndarray | None = None

    def say(self, text: str) -> None:
        self.lines.append(text)
        if text.startswith("target (deg):"):
            self._target = parse_angles(text.split(":", 1)[1], len(text.split(":")[1].split()))
        elif text.startswith("load wrench:"):
            self._load = np.array([float(v) for v in text.split(":", 1)[1].split()])

    def ask(self, prompt: str) -> str:
        self.lines.append(prompt)
        if self._target is not None:
            duration = self.client.call("move", q=self._target.tolist(),
                                        speed=self.speed)["duration"]
            time.sleep(duration)
            self._target = None
        elif self._load is not None:
            if np.any(self._load):
                self.client.call("apply_load", wrench=self._load.tolist(), name="manual")
            else:
                self.client.call("remove_load")
            self._load = None
            return ""
        q = np.asarray(self.client.call("state")["q"])
        return " ".join(f"{v:.4f}" for v in np.rad2deg(q))

    def close(self) -> None:
        self.client.close()
