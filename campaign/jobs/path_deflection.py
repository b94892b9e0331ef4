"""The ``path_deflection`` job: the predicted deflection of P along a path, with its band.

What ``compensate`` predicts before it compensates (the same options record,
extended by compensate's; the same path reader, :func:`load_path`; the same
checks of the joint limits and of the singularity, the same nonlinear
equilibrium and covariance of an identified model), without the compensation
and without writing anything: the Use view draws it as the path is chosen.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from analysis.errors import InputError
from campaign.jobs.choices import WrenchFrame
from campaign.jobs.option_checks import floats, joint_stiffness, robot_and_tool

if TYPE_CHECKING:
    from analysis.model.robot_model import RobotModel
    from campaign.use.path_file import PathInput

#: points of a path read at most (a path is a program's moves, not a point cloud)
MAX_POINTS = 20_000


@dataclass(frozen=True)
class PathDeflectionOptions:
    """A path under its process load, and the robot that follows it (the compensate job's
    options extend this record).

    robot: model.toml from analyze, a built-in name, robot file or URDF; path: the path
    CSV (q1_deg..q6_deg per point as :mod:`campaign.use.path_file` says, optional wrench
    columns); tip, tool_xyz_mm, tool_rpy_deg: as the stiffness job's; controller_angles:
    the path's joints are pendant angles; wrench_N_Nm: constant wrench at P when the path
    has none (N, N m); wrench_frame: base or tool; joint_stiffness_Nm_per_rad: instead of
    the model's (no band, no uncertainty then); min_inv_kappa: refuse points where
    1/kappa_F is below it."""

    robot: str
    path: Path
    tip: str | None = None
    tool_xyz_mm: Sequence[float] | None = None
    tool_rpy_deg: Sequence[float] | None = None
    controller_angles: bool = False
    wrench_N_Nm: Sequence[float] | None = None
    wrench_frame: WrenchFrame = WrenchFrame.base
    joint_stiffness_Nm_per_rad: Sequence[float] | None = None
    min_inv_kappa: float = 0.02


@dataclass
class LoadedPath:
    """What :func:`load_path` read: the robot (6 joints), its joint stiffness k (6,)
    (N m/rad), the covariance of its compliances (6, 6) or None (no identified model, or
    --joint-stiffness given), the path in SI (:class:`campaign.use.path_file.PathInput`)
    and where the stiffness came from, in words."""

    robot: RobotModel
    k: np.ndarray
    cov: np.ndarray | None
    path: PathInput
    stiffness_source: str


def load_path(o: PathDeflectionOptions) -> LoadedPath:
    """Check ``o``'s numbers, load the robot and read the path (the one reader of both jobs)."""
    from campaign.use.path_file import read_path

    if not o.min_inv_kappa > 0:
        raise InputError("expected a positive number", where="--min-inv-kappa")
    r, _ = robot_and_tool(o.robot, o.tip, o.tool_xyz_mm, o.tool_rpy_deg)
    k = joint_stiffness(r, o.joint_stiffness_Nm_per_rad)
    given_k = o.joint_stiffness_Nm_per_rad is not None
    cov = None if given_k else r.compliance_covariance
    w_const = None if o.wrench_N_Nm is None else floats(o.wrench_N_Nm, "--wrench", 6)
    pin = read_path(Path(o.path), r, o.controller_angles, w_const, str(o.wrench_frame))
    source = ("--joint-stiffness" if given_k else "identified (model.toml)"
              if r.identification else "nominal (robot file)")
    from analysis.kinetostatics.compensator_law import compensator_law_of, law_uncertainty_text

    law = compensator_law_of(r)
    if law is not None:  # the deflection and compensation take k2(q2) at each point
        source += (f"; joint 2 at each point's q2 from the {law.text()} (k2 taken at q2ref)"
                   + (f"; {law_uncertainty_text(r)}" if cov is not None else ""))
    return LoadedPath(r, k, cov, pin, source)


@dataclass
class PathDeflectionResult:
    """Per point (SI, base frame at P): line of the CSV, screw (N, 6) [dp (m); rotation
    (rad)], lo95/hi95 (N, 6) the 95 % interval of each component (None without a
    covariance), norm_p (N,) |dp| (m) and its 95 % upper bound norm_p_hi (or None)."""

    robot: str
    line: np.ndarray
    screw: np.ndarray
    lo95: np.ndarray | None
    hi95: np.ndarray | None
    norm_p: np.ndarray
    norm_p_hi: np.ndarray | None
    wrench_source: str
    stiffness_source: str

    def to_json(self) -> dict:
        def listed(a):
            return None if a is None else np.asarray(a).tolist()

        worst = int(np.argmax(self.norm_p))
        return {"robot": self.robot, "points": int(self.line.size),
                "line": self.line.astype(int).tolist(),
                "deflection_m_rad": listed(self.screw), "lo95_m_rad": listed(self.lo95),
                "hi95_m_rad": listed(self.hi95), "norm_p_m": listed(self.norm_p),
                "norm_p_upper95_m": listed(self.norm_p_hi),
                "max_norm_p_m": float(self.norm_p[worst]),
                "worst_line": int(self.line[worst]),
                "wrench_source": self.wrench_source,
                "joint_stiffness_source": self.stiffness_source}


def run(o: PathDeflectionOptions) -> PathDeflectionResult:
    """Read the path and predict the deflection at each point (nothing is written)."""
    from analysis.kinetostatics.path_compensation import check_path, predict_path
    from analysis.kinetostatics.uncertainty import Z95

    loaded = load_path(o)
    r, cov, pin, path = loaded.robot, loaded.cov, loaded.path, Path(o.path)
    if len(pin.q) > MAX_POINTS:
        raise InputError(f"{len(pin.q)} points, more than {MAX_POINTS}", where=str(path))
    check_path(r, pin.q, pin.line, str(path), o.min_inv_kappa)
    pred = predict_path(r, pin.q, loaded.k, pin.w, cov, pin.line, str(path))
    lo, hi = pred.bounds(Z95) if cov is not None else (None, None)
    return PathDeflectionResult(
        r.name, np.asarray(pin.line), pred.screw, lo, hi,
        np.linalg.norm(pred.screw[:, :3], axis=1),
        pred.norm_upper() if cov is not None else None, pin.wrench_source,
        loaded.stiffness_source)
