"""Start and stop the simulated lab: world, control channel and fake instruments.

Programmatic use::

    from drivers.sim.lab import Lab
    from drivers.sim.settings import LabSettings

    with Lab(LabSettings(seed=1, time_scale=50)) as lab:
        lab.addresses        # {"ati-netft": "udp://127.0.0.1:...", ..., "control": "tcp://..."}
        sensor = open_driver("ati-netft", lab.addresses["ati-netft"])

Keys of :attr:`Lab.addresses` are registry driver names (so
``open_driver(name, url)`` works for each), plus ``control`` for the control
channel (:mod:`drivers.sim.control`).
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import threading
from pathlib import Path

from drivers.loopback_guard import child_environment
from drivers.sim.base import FakeServer
from drivers.sim.control import ControlServer
from drivers.sim.settings import LabSettings
from drivers.sim.world import World


def robot_fake_name(robot: str) -> str:
    """Which robot fake serves ``robot``: ``ur`` for UR models, ``fanuc-rmi`` for FANUC
    and ``abb-rws`` for ABB models (by the model's name), else ``kuka-kvp``."""
    key = robot.strip().lower()
    if key.startswith("ur"):
        return "ur"
    try:
        from analysis.model.robots import load_robot

        name = load_robot(robot).name.lower()
    except Exception:  # an unreadable robot fails later, where the world loads it
        name = key
    if "fanuc" in name:
        return "fanuc-rmi"
    if name.startswith("abb") or "irb" in name:
        return "abb-rws"
    return "kuka-kvp"


#: fakes that can listen on a given port (one TCP listener each)
FIXED_PORTS = ("emscon", "geocom", "kuka-kvp", "fanuc-rmi")
#: the fakes that stream readings against a client's real-time deadline
STREAMING = ("ati-netft", "robotiq-ft300", "ati-netcan")
#: the deadline (s) their addresses state (``?timeout=``; the drivers' own: 1 s)
STREAM_DEADLINE_S = 3.0


class Lab:
    """The simulated lab (threads in this process; the UR fake in a child process)."""

    def __init__(self, settings: LabSettings | None = None, control_port: int = 0,
                 ports: dict[str, int] | None = None) -> None:
        """``control_port``: TCP port of the control channel on 127.0.0.1 (0: a free one);
        ``ports``: fixed ports of fakes by driver name, for those of :data:`FIXED_PORTS`;
        the others take free ports (the control channel's ``addresses`` lists them all)."""
        ports = dict(ports or {})
        other = sorted(set(ports) - set(FIXED_PORTS))
        if other:
            raise ValueError(f"a fixed port for {', '.join(other)}: only "
                             f"{', '.join(FIXED_PORTS)} take one (the others: free ports)")
        self.ports = ports
        self.settings = settings or LabSettings()
        self.world = World(self.settings)
        self.fakes: list[FakeServer] = []
        self.addresses: dict[str, str] = {}
        self.notes: list[str] = []
        self._ur: subprocess.Popen | None = None
        self._done = threading.Event()
        self.control = ControlServer(self.world, self.addresses, on_shutdown=self._done.set,
                                     port=control_port)

    @property
    def control_url(self) -> str:
        return self.control.url

    def _make(self, name: str) -> FakeServer | None:
        if name == "ati-netft":
            from drivers.sim.fake_netft import FakeNetFT

            return FakeNetFT(self.world)
        if name == "robotiq-ft300":
            from drivers.sim.fake_ft300 import FakeFT300, stream_rate

            # 100 Hz of simulated time: a sped-up lab streams faster (capped)
            return FakeFT300(self.world, stream_rate(self.settings.time_scale))
        if name == "ati-netcan":
            from drivers.sim.fake_netcan import FakeNetCAN

            return FakeNetCAN(self.world, interface=self.settings.can_interface)
        if name == "emscon":
            from drivers.sim.fake_emscon import FakeEmscon

            return FakeEmscon(self.world, port=self.ports.get("emscon", 0))
        if name == "geocom":
            from drivers.sim.fake_geocom import FakeGeoCom

            return FakeGeoCom(self.world, port=self.ports.get("geocom", 0))
        if name == "kuka-kvp":
            from drivers.sim.fake_kvp import FakeKukaVarProxy

            return FakeKukaVarProxy(self.world, port=self.ports.get("kuka-kvp", 0))
        if name == "fanuc-rmi":
            from drivers.sim.fake_rmi import FakeRMI

            return FakeRMI(self.world, port=self.ports.get("fanuc-rmi", 0))
        if name in ("abb-rws", "abb-rws2"):
            from drivers.sim.fake_rws import FakeRWS

            return FakeRWS(self.world, version=1 if name == "abb-rws" else 2)
        raise ValueError(f"no fake for {name!r}")

    def start(self) -> dict[str, str]:
        """Start everything; returns :attr:`addresses`."""
        self.control.start()
        self.addresses["control"] = self.control.url
        self.addresses["lab-load"] = self.control.url.replace("tcp://", "lab://")
        self.addresses["manual"] = "manual://"
        self.addresses["manual-load"] = "manual://"
        for name in self.settings.instruments:
            if name == "robot":
                name = robot_fake_name(self.settings.robot)
                if name == "ur":
                    self._start_ur()
                    continue
                if name == "abb-rws":  # an ABB arm: IRC5 (RobotWare 6) and OmniCore (7)
                    self._add(self._make("abb-rws2"))
            self._add(self._make(name))
        return self.addresses

    def _add(self, fake: FakeServer | None) -> None:
        if fake is None:
            return
        fake.start()
        self.fakes.append(fake)
        url = fake.url
        if fake.driver in STREAMING:
            # the fake streams from a thread of this process: starved of CPU (a loaded
            # machine, a niced test run) it can be late by more than a real sensor's
            # deadline, which is no device fault; its clients wait this long instead
            url += ("&" if "?" in url else "?") + f"timeout={STREAM_DEADLINE_S:g}"
        self.addresses[fake.driver] = url

    def _start_ur(self) -> None:
        root = str(Path(__file__).resolve().parents[2])
        # the fake's process is held to loopback as the run that starts it
        env = dict(child_environment(), PYTHONPATH=os.pathsep.join(
            [root, *filter(None, [os.environ.get("PYTHONPATH")])]))
        self._ur = subprocess.Popen(
            [sys.executable, "-m", "drivers.sim.fake_rtde", "--control", self.control.url],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, text=True)
        ready, _, _ = select.select([self._ur.stdout], [], [], 20.0)
        line = self._ur.stdout.readline().strip() if ready else ""
        if not line.startswith("ur="):
            self._ur.kill()
            self._ur = None
            self.notes.append("ur fake did not start")
            return
        self.addresses["ur"] = line.split("=", 1)[1]

    def window_guard(self, driver: str):
        """The context a client of fake ``driver`` enters when it opens an averaging window
        (:meth:`drivers.sim.base.FakeServer.window`), or None when no such fake runs."""
        return next((fake.window for fake in self.fakes if fake.driver == driver), None)

    def mark(self, *context: object) -> None:
        """Tell the simulation what the client does now (test, repeat, attempt, phase):
        the noise of each reading is drawn from (seed, instrument, context, sample)."""
        self.world.noise_streams.mark(*context)

    def wait(self) -> None:
        """Block until a ``shutdown`` control command (or :meth:`stop`)."""
        while not self._done.wait(0.5):
            pass

    def stop(self) -> None:
        """Stop every fake, the UR process and the control channel."""
        self._done.set()
        for fake in self.fakes:
            fake.stop()
        self.fakes.clear()
        if self._ur is not None:
            self._ur.terminate()
            try:
                self._ur.wait(5)
            except subprocess.TimeoutExpired:
                self._ur.kill()
            self._ur = None
        self.control.stop()

    def __enter__(self) -> Lab:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
