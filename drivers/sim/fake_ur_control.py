"""Control side of the fake UR controller: registers, the ur-rtde control program, dashboard.

What ``rtde_control.RTDEControlInterface(host)`` (ur-rtde 1.6.5) does on a real
e-Series controller, and what this module answers in its place. The fake is
built for the client's default flag, ``FLAG_UPLOAD_SCRIPT``: it is how the
driver and most deployments use ur-rtde, and it runs the most of the real
client (dashboard checks, script upload, waiting for the program to run).
``FLAG_NO_WAIT`` / ``FLAG_CUSTOM_SCRIPT`` would skip the upload and the wait,
and ``FLAG_USE_EXT_UR_CAP`` needs the External Control URCap, which is not
emulated.

1. Dashboard server, TCP 29999, one ASCII line per request and per answer,
   after a greeting line. ur-rtde 1.6.5 asks, in this order,
   ``PolyscopeVersion``, ``get serial number`` (PolyScope 5.6 or later),
   ``PolyscopeVersion`` and ``is in remote control`` (not on localhost /
   127.0.0.1); :class:`DashboardServer` answers those and a few more.
2. RTDE on 30004 (served by :mod:`drivers.sim.fake_rtde`): an output recipe
   with ``robot_status_bits``, ``safety_status_bits``, ``runtime_state``,
   ``output_int_register_0..2`` and ``output_double_register_0..5``, then twenty
   input recipes over ``input_int_register_*`` / ``input_double_register_*``
   (plus ``external_force_torque``). Commands arrive as data packages of those
   input recipes; the state comes back in the output registers.
3. Script upload to the secondary/real-time interface (TCP 30003; 30002 is
   served the same way): the text of ur-rtde's URScript control program,
   ``def rtde_control(): ... end``. :class:`ScriptServer` recognises that
   program by its name and does not interpret URScript; instead
   :class:`ControlProgram` emulates what the program does on the registers
   (reading the register offset, 0 or 24, that ur-rtde injected into it):

   - it starts: ``runtime_state`` becomes PLAYING (2) and bit 1 of
     ``robot_status_bits`` (program running) is set; ur-rtde waits for this;
   - main loop: while ``input_int_register_0`` (the command) is 0 it writes 1
     ("ready") to ``output_int_register_0``; a non-zero command is executed
     once, then 2 ("done") is written until the command goes back to 0;
   - command 1 (MOVEJ): joint target from ``input_double_register_0..5``,
     speed from 6, acceleration from 7, ``input_int_register_1`` = async;
     command 34 (STOPJ) and 33 (STOPL): deceleration from
     ``input_double_register_0``; command 255 stops the program
     (``runtime_state`` STOPPED). Other commands are acknowledged ("done")
     without effect and listed in :attr:`URController.unsupported`.

Motion: at the start of a MOVEJ the world receives the joint target through the
lab's control channel (``move``); the world answers with the wall-clock time of
the motion at the commanded speed, which also gives the lab's time scale. The
RTDE stream then reports ``actual_q`` / ``actual_qd`` along a trapezoidal
profile of the leading joint (speed ``v``, acceleration ``a``, all joints in
step), time-scaled like every other simulated motion; a synchronous MOVEJ
answers "done" when that profile ends, so ``moveJ`` returns with the robot at
the target. STOPJ decelerates the current profile at its rate and moves the
world to where the robot comes to rest. A target the world refuses (outside
the joint limits) stops the control program, as a runtime error of the program
does on a real controller, so ur-rtde's ``moveJ`` returns False.

Limits: the TCP pose reported mid-motion is the world's (that of the target);
asynchronous-operation progress (``output_int_register_2``), realtime commands
(servo, speed, force mode) and the primary-interface state stream are not
emulated; RTDE input registers are not reserved per connection (no ``IN_USE``).
"""

from __future__ import annotations

import math
import re
import socket
import sys
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.errors import DriverError
from drivers.sim.tcp import serve_then_close

# runtime_state values (RTDE guide) and status bits (ur-rtde RobotStatus / SafetyStatus)
STOPPED, PLAYING = 1, 2
POWER_ON, PROGRAM_RUNNING = 0x1, 0x2
SAFETY_NORMAL = 0x1

RDY_FOR_CMD, DONE_WITH_CMD = 1, 2
MOVEJ, STOPL, STOPJ, STOP_SCRIPT = 1, 33, 34, 255
#: realtime commands of ur-rtde's program: executed and answered "ready" at once
REALTIME_COMMANDS = {6, 9, 10, 11, 24, 25, 26, 27, 38, 58}

POLYSCOPE_VERSION = "URSoftware 5.11.0.108249 (Mar 02 2021)"
SERIAL_NUMBER = "20185500001"


@dataclass
class _Segment:
    t0: float  # start (s, robot time since the motion began)
    s0: float  # path position (rad of the leading joint)
    v0: float  # path speed (rad/s)
    acc: float  # path acceleration (rad/s^2)


class Profile:
    """Path position ``s(t)`` along a straight joint-space segment of length ``length`` (rad).

    Trapezoidal speed (or triangular when ``v`` is not reached), robot time.
    """

    def __init__(self, length: float, v: float, a: float) -> None:
        self.length = length
        if length <= 0:
            self.segments = [_Segment(0.0, 0.0, 0.0, 0.0)]
            self.end = 0.0
            return
        v = min(v, math.sqrt(length * a))
        t_acc = v / a
        t_cruise = (length - v * t_acc) / v
        self.segments = [_Segment(0.0, 0.0, 0.0, a),
                         _Segment(t_acc, 0.5 * a * t_acc**2, v, 0.0),
                         _Segment(t_acc + t_cruise, length - 0.5 * a * t_acc**2, v, -a)]
        self.end = 2 * t_acc + t_cruise

    def at(self, t: float) -> tuple[float, float]:
        """``(s, ds/dt)`` at robot time ``t`` (clamped to the profile)."""
        if t >= self.end:
            return self.length, 0.0
        t = max(t, 0.0)
        seg = next(s for s in reversed(self.segments) if s.t0 <= t)
        dt = t - seg.t0
        return seg.s0 + seg.v0 * dt + 0.5 * seg.acc * dt**2, seg.v0 + seg.acc * dt

    def stop(self, t: float, dec: float) -> None:
        """From robot time ``t`` on, decelerate at ``dec`` (rad/s^2) to rest."""
        s, sd = self.at(t)
        if sd <= 0 or t >= self.end:
            return
        t_dec = sd / dec
        s_end = s + 0.5 * sd * t_dec
        if s_end >= self.length:  # the planned ramp already stops sooner
            return
        self.segments = [seg for seg in self.segments if seg.t0 < t]
        self.segments.append(_Segment(t, s, sd, -dec))
        self.length = s_end
        self.end = t + t_dec


class Motion:
    """One joint motion: start, direction, profile, and the clock that maps wall to robot time."""

    def __init__(self, q0: np.ndarray, q1: np.ndarray, v: float, a: float,
                 time_scale: float) -> None:
        delta = q1 - q0
        length = float(np.max(np.abs(delta)))
        self.q0 = q0
        self.u = delta / length if length > 0 else np.zeros_like(q0)
        self.profile = Profile(length, v, a)
        self.time_scale = time_scale
        self.wall0 = time.monotonic()

    def robot_time(self) -> float:
        return (time.monotonic() - self.wall0) * self.time_scale

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles (rad) and speeds (rad/s, robot time) now."""
        s, sd = self.profile.at(self.robot_time())
        return self.q0 + self.u * s, self.u * sd

    def end_point(self) -> np.ndarray:
        return self.q0 + self.u * self.profile.length

    @property
    def done(self) -> bool:
        return self.robot_time() >= self.profile.end

    def wall_left(self) -> float:
        return max(0.0, (self.profile.end - self.robot_time()) / self.time_scale)


class URController:
    """Registers, program state and motion of the emulated controller (thread-safe).

    Parameters
    ----------
    lab_call : callable
        ``lab_call(cmd, **fields)``: a lab control-channel request (the
        ``call`` method of :class:`drivers.sim.control.LabClient`).
    """

    def __init__(self, lab_call: Callable[..., dict]) -> None:
        self.lab_call = lab_call
        self.lock = threading.RLock()
        self.inputs: dict[str, object] = {}
        self.outputs: dict[str, object] = {}
        self.runtime_state = STOPPED
        self.world_state: dict = lab_call("state")
        self.motion: Motion | None = None
        #: joint angles reported while a new motion is being set up with the world (two lab
        #: calls): the world already stands at the end point then, the robot not yet
        self.setting_up: list[float] | None = None
        self.time_scale: float | None = None
        self.program: ControlProgram | None = None
        self.unsupported: list[int] = []
        self.log: list[str] = []

    # --- registers ------------------------------------------------------
    def set_inputs(self, names: list[str], values: list) -> None:
        with self.lock:
            self.inputs.update(zip(names, values, strict=True))

    def input_int(self, i: int) -> int:
        with self.lock:
            return int(self.inputs.get(f"input_int_register_{i}", 0))

    def input_double(self, i: int) -> float:
        with self.lock:
            return float(self.inputs.get(f"input_double_register_{i}", 0.0))

    def write_output(self, name: str, value: object) -> None:
        with self.lock:
            self.outputs[name] = value

    @property
    def robot_status_bits(self) -> int:
        return POWER_ON | (PROGRAM_RUNNING if self.runtime_state == PLAYING else 0)

    # --- joints ---------------------------------------------------------
    def joints(self) -> tuple[list[float], list[float]]:
        """Reported joint angles and speeds: along the motion, else the world's."""
        with self.lock:
            if self.setting_up is not None:
                return list(self.setting_up), [0.0] * len(self.setting_up)
            m = self.motion
            if m is not None:
                if not m.done:
                    q, qd = m.state()
                    return q.tolist(), qd.tolist()
                self.motion = None
            return list(self.world_state["q"]), [0.0] * len(self.world_state["q"])

    def move_joints(self, target: np.ndarray, v: float, a: float) -> Motion | None:
        """Start a joint motion; raises :class:`DriverError` if the world refuses it."""
        if not (v > 0 and a > 0):
            raise DriverError(f"movej with speed {v} and acceleration {a}")
        with self.lock:
            q0 = np.asarray(self.joints()[0], dtype=float)
            self.motion = None
            self.setting_up = q0.tolist()
        try:
            duration = float(self.lab_call("move", q=[float(x) for x in target],
                                           speed=v)["duration"])
            state = self.lab_call("state")  # the end point, whatever the polling interval
        except BaseException:
            with self.lock:
                self.setting_up = None
            raise
        length = float(np.max(np.abs(target - q0)))
        with self.lock:
            self.setting_up = None
            self.world_state = state
            if length > 0 and duration > 0:
                self.time_scale = length / v / duration
            if length == 0 or self.time_scale is None:
                return None
            self.motion = Motion(q0, np.asarray(target, dtype=float), v, a, self.time_scale)
            self.log.append(f"movej v={v:g} a={a:g} length={length:.6g} "
                            f"wall={self.motion.wall_left():.4g}")
            return self.motion

    def stop_joints(self, dec: float) -> Motion | None:
        """Decelerate the current motion at ``dec`` (rad/s^2); the world goes to the rest point."""
        with self.lock:
            m = self.motion
            if m is None or m.done:
                return None
            if not dec > 0:
                dec = 1e9  # an immediate stop
            t = m.robot_time()
            q_now, qd_now = m.state()
            m.profile.stop(t, dec)
            q_rest = m.end_point()
            wall = m.wall_left()
            self.log.append(f"stopj a={dec:g} at s={float(np.max(np.abs(q_now - m.q0))):.6g}")
        step = float(np.max(np.abs(q_rest - q_now)))
        # the speed given to the world only sets how long it reports "moving"
        speed = step / (wall * (self.time_scale or 1.0)) if wall > 0 and step > 0 else 1.0
        self.lab_call("move", q=[float(x) for x in q_rest], speed=speed)
        self.world_state = self.lab_call("state")
        return m

    # --- program --------------------------------------------------------
    def start_program(self, int_offset: int, float_offset: int) -> None:
        self.stop_program()
        with self.lock:
            self.program = ControlProgram(self, int_offset, float_offset)
            self.program.start()

    def stop_program(self) -> None:
        with self.lock:
            program, self.program = self.program, None
        if program is not None:
            program.halt()
        with self.lock:
            self.runtime_state = STOPPED

    def shutdown(self) -> None:
        self.stop_program()


class ControlProgram(threading.Thread):
    """Emulation of ur-rtde's ``rtde_control`` URScript program (its register protocol)."""

    PERIOD = 0.002  # one controller cycle at 500 Hz

    def __init__(self, ctrl: URController, int_offset: int, float_offset: int) -> None:
        super().__init__(daemon=True, name="ur-control-program")
        self.ctrl = ctrl
        self.oi, self.of = int_offset, float_offset
        self.halted = threading.Event()

    def halt(self) -> None:
        self.halted.set()
        if threading.current_thread() is not self:
            self.join(timeout=2.0)

    def _out_int(self, i: int, value: int) -> None:
        self.ctrl.write_output(f"output_int_register_{i + self.oi}", value)

    def _in_int(self, i: int) -> int:
        return self.ctrl.input_int(i + self.oi)

    def _in_double(self, i: int) -> float:
        return self.ctrl.input_double(i + self.of)

    def run(self) -> None:
        ctrl = self.ctrl
        with ctrl.lock:
            ctrl.runtime_state = PLAYING
        executing = False
        try:
            self._out_int(0, RDY_FOR_CMD)
            while not self.halted.is_set():
                cmd = self._in_int(0)
                if cmd in REALTIME_COMMANDS:
                    self._unsupported(cmd)
                    self._out_int(0, RDY_FOR_CMD)
                elif cmd == 0:
                    executing = False
                    self._out_int(0, RDY_FOR_CMD)
                elif not executing:
                    executing = True
                    if cmd == STOP_SCRIPT:
                        break
                    if not self.execute(cmd):
                        break
                    self._out_int(0, DONE_WITH_CMD)
                time.sleep(self.PERIOD)
        finally:
            with ctrl.lock:
                if ctrl.program is self:
                    ctrl.program = None
                    ctrl.runtime_state = STOPPED

    def _unsupported(self, cmd: int) -> None:
        if cmd not in self.ctrl.unsupported:
            self.ctrl.unsupported.append(cmd)
            print(f"fake UR: command {cmd} of the control program is not emulated",
                  file=sys.stderr, flush=True)

    def _wait(self, motion: Motion | None) -> None:
        while motion is not None and not motion.done and not self.halted.is_set():
            time.sleep(min(self.PERIOD, motion.wall_left()))

    def execute(self, cmd: int) -> bool:
        """Run one command; False when the program stops (runtime error)."""
        try:
            if cmd == MOVEJ:
                q = np.array([self._in_double(i) for i in range(6)])
                v, a = self._in_double(6), self._in_double(7)
                asynchronous = self._in_int(1) == 1
                motion = self.ctrl.move_joints(q, v, a)
                if not asynchronous:
                    self._wait(motion)
            elif cmd in (STOPJ, STOPL):
                motion = self.ctrl.stop_joints(self._in_double(0))
                if self._in_int(1) != 1:
                    self._wait(motion)
            else:
                self._unsupported(cmd)
        except DriverError as err:
            self.ctrl.log.append(f"program stopped: {err}")
            print(f"fake UR: control program stopped: {err}", file=sys.stderr, flush=True)
            return False
        return True


class _LineServer(ABC):
    """Accept loop on ``(host, port)``; each connection handled in its own thread."""

    def __init__(self, host: str, port: int, stop: threading.Event) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.sock.listen(4)
        self.sock.settimeout(0.2)
        self.stop = stop
        self.conns: list[socket.socket] = []

    def start(self) -> None:
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.settimeout(0.2)
            self.conns.append(conn)
            threading.Thread(target=serve_then_close, args=(self.serve, conn),
                             daemon=True).start()
        self.close()

    def lines(self, conn: socket.socket):
        """Yield received lines (str, without line end) until the peer closes or we stop."""
        buf = b""
        while not self.stop.is_set():
            try:
                chunk = conn.recv(65536)
            except TimeoutError:
                continue
            if not chunk:
                return
            buf += chunk
            *complete, buf = buf.split(b"\n")
            for line in complete:
                yield line.decode("utf-8", "replace").rstrip("\r")

    @abstractmethod
    def serve(self, conn: socket.socket) -> None:
        """Answer one client until it closes."""

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass
        for c in self.conns:
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass


class DashboardServer(_LineServer):
    """Dashboard server (29999): greeting, then one answer line per request line."""

    def __init__(self, host: str, ctrl: URController, stop: threading.Event) -> None:
        super().__init__(host, 29999, stop)
        self.ctrl = ctrl

    def answer(self, request: str) -> str | None:
        req = request.strip()
        low = req.lower()
        running = self.ctrl.runtime_state == PLAYING
        if low == "polyscopeversion":
            return POLYSCOPE_VERSION
        if low == "get serial number":
            return SERIAL_NUMBER
        if low == "get robot model":
            return "UR10"
        if low == "is in remote control":
            return "true"
        if low == "robotmode":
            return "Robotmode: RUNNING"
        if low == "safetystatus":
            return "Safetystatus: NORMAL"
        if low == "safetymode":
            return "Safetymode: NORMAL"
        if low == "running":
            return f"Program running: {'true' if running else 'false'}"
        if low == "programstate":
            return "PLAYING rtde_control" if running else "STOPPED <unnamed>"
        if low == "stop":
            if not running:
                return "Failed to execute: stop"
            self.ctrl.stop_program()
            return "Stopped"
        if low in ("power on", "brake release", "unlock protective stop",
                   "close safety popup", "close popup"):
            return {"power on": "Powering on", "brake release": "Brake releasing",
                    "unlock protective stop": "Protective stop releasing",
                    "close safety popup": "closing safety popup",
                    "close popup": "closing popup"}[low]
        if low == "quit":
            return None
        return f"could not understand: '{req}'"

    def serve(self, conn: socket.socket) -> None:
        conn.sendall(b"Connected: Universal Robots Dashboard Server\n")
        for line in self.lines(conn):
            reply = self.answer(line)
            self.ctrl.log.append(f"dashboard: {line!r} -> {reply!r}")
            if reply is None:
                conn.sendall(b"Disconnected\n")
                return
            conn.sendall(reply.encode() + b"\n")


_DEF = re.compile(r"^(def|sec)\s+(\w+)\s*\(\s*\)\s*:")
_OFFSET = re.compile(r"global\s+reg_offset_(int|float)\s*=\s*(\d+)")


class ScriptServer(_LineServer):
    """Secondary (30002) or real-time (30003) interface: accepts URScript programs.

    Programs are cut from the stream (``def name():`` up to an ``end`` in column
    0). Only ur-rtde's control program is recognised and emulated; any other
    program replaces the running one, as on a real controller, but is not run.
    """

    def __init__(self, host: str, port: int, ctrl: URController, stop: threading.Event) -> None:
        super().__init__(host, port, stop)
        self.ctrl = ctrl
        self.programs: list[str] = []

    def serve(self, conn: socket.socket) -> None:
        program: list[str] | None = None
        for line in self.lines(conn):
            if program is None:
                if _DEF.match(line):
                    program = [line]
                elif line.strip():
                    self.ctrl.log.append(f"script line not interpreted: {line.strip()[:60]}")
                continue
            program.append(line)
            if line.rstrip() == "end":
                self.run_program("\n".join(program) + "\n")
                program = None

    def run_program(self, text: str) -> None:
        name = _DEF.match(text).group(2)
        self.programs.append(name)
        if name == "rtde_control" and "RTDE Control Script" in text:
            offsets = {kind: int(n) for kind, n in _OFFSET.findall(text)}
            self.ctrl.start_program(offsets.get("int", 0), offsets.get("float", 0))
        else:
            self.ctrl.stop_program()
            self.ctrl.log.append(f"program {name!r} received, not interpreted")
            print(f"fake UR: program {name!r} is not emulated", file=sys.stderr, flush=True)
