"""Run a path and its compensated version on the simulated lab and measure P.

The simulated world of :mod:`drivers.sim.world` (the lab's true joint
stiffness from the protocol's ``[fake_lab]``, its tool, its tracker noise) is
driven directly, not over the loopback sockets (one move + load + reading per
point would be slow for long paths): at each point the joints are commanded,
the point's wrench is applied, and the 6-DoF probe measures the tool pose in
the tracker frame, taken to the base frame with the lab's tracker placement
(a calibrated tracker). Settling is instantaneous (the world's settle time is
set to 0): what is measured is the static equilibrium.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.model.kinematics import pose_difference, tool_pose
from analysis.model.robot_model import RobotModel


@dataclass
class FakeLabCheck:
    """Measured pose error of P (N, 6) (m, rad) along the path before and after compensation."""

    before: np.ndarray
    after: np.ndarray
    true_k: np.ndarray
    readings: int

    def stats(self) -> dict:
        """RMS and max of |dp| (m) and |dr| (rad), before and after; ratio after/before."""
        out = {}
        for name, e in (("before", self.before), ("after", self.after)):
            p, r = np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1)
            out[name] = {"rms_m": float(np.sqrt(np.mean(p**2))), "max_m": float(p.max()),
                         "rms_rad": float(np.sqrt(np.mean(r**2))), "max_rad": float(r.max())}
        out["ratio_rms_translation"] = out["after"]["rms_m"] / out["before"]["rms_m"]
        out["readings_per_point"] = self.readings
        out["true_joint_stiffness_Nm_per_rad"] = self.true_k.tolist()
        return out


def _world(protocol_path: Path, robot: RobotModel):
    from campaign.acquire.instruments import lab_settings
    from campaign.protocol import load_protocol
    from drivers.sim.world import World

    protocol = load_protocol(protocol_path)
    settings = lab_settings(protocol, None)
    settings = dataclasses.replace(settings, settle_time=0.0)
    world = World(settings)
    if world.robot.name != robot.name:
        raise InputError(f"the protocol's lab simulates {world.robot.name}, the model is "
                         f"{robot.name}", where=str(protocol_path))
    probe = np.asarray(world.robot.chain.tip) - np.asarray(robot.chain.tip)
    if np.max(np.abs(probe)) > 1e-9:
        raise InputError("the protocol's tool differs from the model's tool point P: the "
                         "lab would measure another point", where=str(protocol_path))
    return world


def run_on_fake_lab(protocol_path: Path, robot: RobotModel, q: np.ndarray, q_cmd: np.ndarray,
                    w: np.ndarray, readings: int = 1) -> FakeLabCheck:
    """Measured error of P along q and along q_cmd (model convention, rad), under w (N, 6)."""
    world = _world(protocol_path, robot)
    target = tool_pose(robot, q)
    base_from_tracker = np.linalg.inv(world.base_in_tracker)

    def measure(joints: np.ndarray) -> np.ndarray:
        err = np.empty((len(joints), 6))
        for i, (qi, wi) in enumerate(zip(joints, w, strict=True)):
            world.remove_load()
            world.move(robot.to_controller(qi))
            world.apply_load(wi)
            poses = [base_from_tracker @ world.tracker_pose() for _ in range(readings)]
            e = pose_difference(target[i], np.array(poses))
            err[i] = e.mean(axis=0)
        world.remove_load()
        return err

    return FakeLabCheck(measure(q), measure(q_cmd), world.k.copy(), readings)
