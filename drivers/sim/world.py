"""The one seeded simulated world shared by every fake instrument.

State: the robot's commanded joint angles, the applied load, and the time of
the last change. The tool's true pose follows the nonlinear elastostatic
equilibrium ``K_theta dq = J(q + dq)^T w`` with the lab's true joint stiffness
(:func:`analysis.kinetostatics.equilibrium.solve_deflection`), reached by an exponential
settling with time constant ``settle_time / time_scale`` (wall-clock seconds).
Joint encoders sit on the motor side, so the reported joint angles do not
include the elastic deflection, as on a real robot. The settling is taken as
over :data:`SETTLED_AFTER` time constants after a change (a residual of
e^-6 = 0.25 % of the step, below the tracker noise at the lab's loads): from
then on the state is exactly the equilibrium, so readings taken after a
settling detection do not depend on when they were taken.

A protocol's real-arm effects (``[fake_lab]`` gravity, lost motion, link compliance,
compensator: :mod:`analysis.kinetostatics.realistic`) replace that equilibrium by the
realistic one (joint angles and the links' bending twist of P), with or without load.
Instrument drifts follow the lab's own simulated time, which advances only by events:
a motion by its duration at the commanded speed, a load change by its settling
(:data:`SETTLED_AFTER` ``settle_time``), so drifted readings stay reproducible.

Noise comes from :class:`drivers.sim.noise.NoiseStreams`: one generator per
(seed, instrument, context, sample), so a seeded campaign reads the same
numbers whatever the order in which the fakes' threads run.

All quantities SI: m, rad, N, N m. Thread-safe (one re-entrant lock).
"""

from __future__ import annotations

import threading
import time

import numpy as np

from analysis.kinetostatics.equilibrium import solve_deflection
from analysis.kinetostatics.realistic import apply_twist, joint_deflection, link_twist
from analysis.kinetostatics.realistic_lab import realistic_lab
from analysis.model.kinematics import tool_pose
from analysis.model.robots import load_robot, with_tool
from drivers.frames import matrix_to_rotvec, rotvec_to_matrix
from drivers.sim.faults import Faults
from drivers.sim.noise import NoiseStreams
from drivers.sim.settings import LabSettings

#: time constants after a change from which the settling is over (state = equilibrium)
SETTLED_AFTER = 6.0


class World:
    """Robot, load, noise and time of the simulated lab."""

    def __init__(self, settings: LabSettings) -> None:
        self.settings = settings
        self.robot = with_tool(load_robot(settings.robot), np.asarray(settings.tool_xyz, float),
                               np.asarray(settings.tool_rpy, float))
        n = self.robot.n
        self.k = np.asarray(settings.true_joint_stiffness, dtype=float)
        if self.k.shape != (n,):
            raise ValueError(f"{self.robot.name} has {n} joints, stiffness has {self.k.size}")
        #: generator of the fault injections' garbage only (not of measurement noise)
        self.rng = np.random.default_rng(settings.seed)
        self.noise_streams = NoiseStreams(settings.seed)
        self.faults = Faults()
        self._lock = threading.RLock()
        if settings.home is not None:
            q0 = np.asarray(settings.home, dtype=float)
        else:
            q0 = self.robot.to_controller(self._default_home())
        self._q_cmd = q0.copy()
        self._load = np.zeros(6)
        self.load_name = ""
        self._dq_from = np.zeros(n)
        self._dq_to = np.zeros(n)
        #: the real-arm effects (inactive: the joint-spring equilibrium above)
        self.lab = realistic_lab(self.robot, settings.effects())
        self._tw_from = np.zeros(6)
        self._tw_to = np.zeros(6)
        #: the lab's simulated time (s): motions and settlings only
        self.sim_time = 0.0
        self._t_change = time.monotonic()
        self._motion_end = self._t_change
        self.aimed = next(iter(settings.reflectors))
        self.reflectors = {k: np.asarray(v, float) for k, v in settings.reflectors.items()}
        self.sensor_mount = np.eye(4)
        self.sensor_mount[:3, :3] = rotvec_to_matrix(settings.sensor_rotation)
        self.sensor_mount[:3, 3] = settings.sensor_offset
        self.base_in_tracker = np.eye(4)
        self.base_in_tracker[:3, :3] = rotvec_to_matrix([0.0, 0.0, settings.tracker_yaw])
        self.base_in_tracker[:3, 3] = settings.tracker_position
        if self.lab.active:  # the arm sags under gravity before any command
            self._retarget()

    def _default_home(self) -> np.ndarray:
        """A pose well inside the limits, away from the wrist singularity (model rad)."""
        lo, hi = self.robot.lower, self.robot.upper
        q = (lo + hi) / 2
        if self.robot.n >= 5:
            q = q.copy()
            q[4] = np.clip(q[4] + 0.6, lo[4] + 0.1, hi[4] - 0.1)
        return q

    # --- time -----------------------------------------------------------
    @property
    def tau(self) -> float:
        """Settling time constant in wall-clock seconds."""
        return self.settings.settle_time / self.settings.time_scale

    def _blend(self, start: np.ndarray, end: np.ndarray, now: float) -> np.ndarray:
        elapsed = now - self._t_change
        if self.tau <= 0 or elapsed >= SETTLED_AFTER * self.tau:
            return end.copy()
        a = 1.0 - np.exp(-elapsed / self.tau)
        return start + (end - start) * a

    def _deflection(self, now: float) -> np.ndarray:
        return self._blend(self._dq_from, self._dq_to, now)

    def _retarget(self) -> None:
        now = time.monotonic()
        self._dq_from = self._deflection(now)
        self._tw_from = self._blend(self._tw_from, self._tw_to, now)
        q_model = self.robot.from_controller(self._q_cmd)
        if self.lab.active:
            self._dq_to = joint_deflection(self.robot, self.lab, self.k, q_model[None],
                                           self._load)[0]
            self._tw_to = link_twist(self.robot, self.lab, (q_model + self._dq_to)[None],
                                     self._load)[0]
        elif np.any(self._load):
            self._dq_to = solve_deflection(self.robot, q_model, self.k, self._load)
        else:
            self._dq_to = np.zeros(self.robot.n)
        self._t_change = now

    # --- commands -------------------------------------------------------
    def move(self, q_ctrl: np.ndarray, speed: float = 1.0) -> float:
        """Command joint angles (rad, controller); returns the motion time (wall s)."""
        q = np.asarray(q_ctrl, dtype=float)
        q_model = self.robot.from_controller(self.robot.check_q(q, "joint target"))
        if not np.all(self.robot.within_limits(q_model)):
            raise ValueError("joint target outside the robot's limits")
        if speed <= 0:
            raise ValueError("speed must be positive")
        with self._lock:
            duration = float(np.max(np.abs(q - self._q_cmd))) / speed / self.settings.time_scale
            self.sim_time += float(np.max(np.abs(q - self._q_cmd))) / speed
            self._q_cmd = q.copy()
            self._retarget()
            self._motion_end = time.monotonic() + duration
        return duration

    def apply_load(self, wrench: np.ndarray, name: str = "") -> None:
        """Apply a wrench [f (N), m (N m)] at the tool point, base frame."""
        w = np.asarray(wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise ValueError("load wrench must be 6 finite numbers")
        with self._lock:
            self._load = w.copy()
            self.load_name = name
            self.sim_time += SETTLED_AFTER * self.settings.settle_time
            self._retarget()

    def remove_load(self) -> None:
        """Remove the load."""
        self.apply_load(np.zeros(6), "")

    def aim(self, target: str) -> None:
        """Point the tracker beam at reflector ``target``."""
        if target not in self.reflectors:
            raise ValueError(f"no reflector {target!r}; known: {', '.join(self.reflectors)}")
        with self._lock:
            self.aimed = target

    # --- readings -------------------------------------------------------
    def moving(self) -> bool:
        """True while a commanded motion is still under way."""
        return time.monotonic() < self._motion_end

    def joint_angles(self, source: str = "encoders", held: bool = False) -> np.ndarray:
        """Reported joint angles (rad, controller convention): motor side, no deflection.

        ``source`` names the noise stream (the fake reading them); ``held``: the
        encoder noise is one draw held through the acquisition's current phase
        (for a fake that polls the world at its own pace, whose number of reads
        follows the wall clock), else the next sample of the stream.
        """
        with self._lock:
            q = self._q_cmd.copy()
        if self.settings.encoder_noise:
            rng = (self.noise_streams.held(source) if held
                   else self.noise_streams.generator(source))
            q += rng.normal(0, self.settings.encoder_noise, q.shape)
        return q

    def nominal_tool_pose(self) -> np.ndarray:
        """Tool pose the controller computes from its encoders (rigid model), base frame."""
        with self._lock:
            return tool_pose(self.robot, self.robot.from_controller(self._q_cmd))

    def true_tool_pose(self) -> np.ndarray:
        """Tool pose including the elastic deflection at this instant, base frame."""
        with self._lock:
            now = time.monotonic()
            q = self.robot.from_controller(self._q_cmd) + self._deflection(now)
            T = tool_pose(self.robot, q)
            if self.lab.links:
                T = apply_twist(T[None], self._blend(self._tw_from, self._tw_to, now)[None])[0]
            return T

    def true_deflection(self) -> np.ndarray:
        """Joint deflection dq (rad, model convention) at this instant."""
        with self._lock:
            return self._deflection(time.monotonic())

    def load(self) -> np.ndarray:
        """Applied wrench (base frame at the tool point)."""
        with self._lock:
            return self._load.copy()

    def sensor_wrench(self, source: str = "force_torque") -> np.ndarray:
        """Noisy wrench seen by the F/T sensor: sensor frame, sensor origin (N, N m).

        ``source`` names the noise stream (the fake reading it).
        """
        with self._lock:
            T = self.true_tool_pose() @ self.sensor_mount
            R, o = T[:3, :3], T[:3, 3]
            p = self.true_tool_pose()[:3, 3]
            f_b, m_p = self._load[:3], self._load[3:]
            m_o = m_p + np.cross(p - o, f_b)
            w = np.concatenate([R.T @ f_b, R.T @ m_o])
            s = self.settings
            if s.ft_drift is not None:
                w += np.asarray(s.ft_drift, float) * self.sim_time
        rng = self.noise_streams.generator(source)
        w += np.concatenate([rng.normal(0, s.force_noise, 3), rng.normal(0, s.torque_noise, 3)])
        return w

    def tracker_point(self, target: str | None = None, source: str = "tracker") -> np.ndarray:
        """Noisy position (m, tracker frame) of the aimed (or named) reflector.

        ``source`` names the noise stream (the fake reading it).
        """
        with self._lock:
            name = target or self.aimed
            r = np.append(self.reflectors[name], 1.0)
            p = (self.base_in_tracker @ self.true_tool_pose() @ r)[:3]
            if self.settings.tracker_drift is not None:
                p += np.asarray(self.settings.tracker_drift, float) * self.sim_time
        return p + self.noise_streams.generator(source).normal(0, self.settings.tracker_noise, 3)

    def tracker_pose(self, source: str = "tracker") -> np.ndarray:
        """Noisy 6-DoF probe pose of the tool frame in the tracker frame.

        ``source`` names the noise stream (the fake reading it).
        """
        with self._lock:
            T = self.base_in_tracker @ self.true_tool_pose()
            if self.settings.tracker_drift is not None:
                T[:3, 3] += np.asarray(self.settings.tracker_drift, float) * self.sim_time
        s = self.settings
        rng = self.noise_streams.generator(source)
        dR = rotvec_to_matrix(rng.normal(0, s.tracker_angle_noise, 3))
        T = T.copy()
        T[:3, :3] = dR @ T[:3, :3]
        T[:3, 3] += rng.normal(0, s.tracker_noise, 3)
        return T

    def state(self) -> dict:
        """JSON-able snapshot for the control channel; ``q`` carries the held encoder
        noise (its readers poll it at their own pace, see :meth:`joint_angles`)."""
        T = self.nominal_tool_pose()
        return {
            "q": self.joint_angles(held=True).tolist(),
            "tcp_pose": [*T[:3, 3].tolist(), *matrix_to_rotvec(T[:3, :3]).tolist()],
            "load": self.load().tolist(),
            "load_name": self.load_name,
            "moving": self.moving(),
            "aimed": self.aimed,
        }
