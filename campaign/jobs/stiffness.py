"""The ``stiffness`` job: J, K_C (eq. 8), K_X with and without K_C (eqs. 6, 12) and the
deflection of P at one pose, with 95 % intervals from an identified model's covariance."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from analysis.errors import InputError, SingularPoseError
from campaign.jobs.option_checks import floats, joint_stiffness, robot_and_tool, wrench


@dataclass(frozen=True)
class StiffnessOptions:
    """robot: built-in name, robot file or URDF; tip: tool frame of a URDF;
    tool_xyz_mm / tool_rpy_deg: P in the flange frame as the protocol's [tool] gives it
    (mm, deg; None: the robot file's tool or the flange centre);
    q_rad: joint angles (rad), model convention unless ``controller_angles`` (pendant);
    joint_stiffness_Nm_per_rad: None = the model's nominal (or identified) values;
    wrench_N_Nm: [fx, fy, fz, mx, my, mz] at P, base frame (None = the paper's worst case);
    ignore_limits: compute outside the joint limits."""

    robot: str
    q_rad: Sequence[float]
    tip: str | None = None
    tool_xyz_mm: Sequence[float] | None = None
    tool_rpy_deg: Sequence[float] | None = None
    controller_angles: bool = False
    joint_stiffness_Nm_per_rad: Sequence[float] | None = None
    wrench_N_Nm: Sequence[float] | None = None
    ignore_limits: bool = False


@dataclass
class StiffnessResult:
    """The document ``campaign stiffness --json`` prints (SI units; ``units`` says which).

    K_X and K_X_without_K_C are None at a singular pose (``undefined`` says why);
    ``uncertainty`` only with an identified model and no given joint stiffness."""

    robot: str
    tool: dict
    q_rad: list
    joint_stiffness_Nm_per_rad: list
    joint_stiffness_source: str
    wrench_N_Nm: list
    wrench_source: str
    J_m_rad_per_rad: list
    K_C_Nm_per_rad: list
    K_X: list | None
    K_X_without_K_C: list | None
    undefined: dict
    deflection_m_rad: list
    deflection_without_K_C_m_rad: list
    deflection_nonlinear_m_rad: list
    units: dict
    tool_text: str = ""
    uncertainty: dict | None = None
    #: the model file's axis-2 compensator law at this pose (None: the file has none)
    compensator: dict | None = None

    def to_json(self) -> dict:
        """The printed document: keys in their historical order, ``uncertainty`` and
        ``compensator`` if any."""
        doc = {k: v for k, v in self.__dict__.items()
               if k not in ("tool_text", "uncertainty", "compensator")}
        if self.uncertainty is not None:
            doc["uncertainty"] = self.uncertainty
        if self.compensator is not None:
            doc["compensator"] = self.compensator
        return doc


def _intervals(r, q, k, w, J, cov_x, kq) -> dict:
    """95 % intervals of the nonlinear deflection and of diag(K_X) from the model's
    covariance; k (n,) the file's stiffness, kq (n,) the one at this pose (the
    compensator law's k2(q2), else k)."""
    from analysis.kinetostatics.compensator_law import (
        law_uncertainty_text,
        pose_compliance_covariance,
    )
    from analysis.kinetostatics.link_compliance import (
        link_covariance_of,
        links_of,
        stiffness_diag_se_with_links,
        stiffness_with_links,
    )
    from analysis.kinetostatics.stiffness import (
        cartesian_stiffness,
        complementary_stiffness_from_state,
    )
    from analysis.kinetostatics.uncertainty import (
        Z95,
        cartesian_stiffness_se,
        predict_deflection,
        stiffness_covariance,
    )
    from analysis.model.kinematics import chain_state

    pred = predict_deflection(r, q, k, w, cov_x)  # applies the compensator law itself
    lo, hi = pred.bounds(Z95)
    links = links_of(r)
    cov_q = pose_compliance_covariance(r, q, cov_x)  # x2(q2)'s with the law, else cov_x
    if links:  # K_X = C_X^-1 with the links; their entries' covariance when the file has it
        se = stiffness_diag_se_with_links(r, q, kq, w, links, cov_q)[0]
        K_X = np.diagonal(stiffness_with_links(r, q, kq, w, links)[0])
    else:
        se = np.diagonal(cartesian_stiffness_se(J, stiffness_covariance(kq, cov_q)))
        K_X = np.diagonal(cartesian_stiffness(J, kq, complementary_stiffness_from_state(
            chain_state(r, q), w)))
    return {
        "confidence": 0.95,
        "deflection_nonlinear_sd_m_rad": pred.sd.tolist(),
        "deflection_nonlinear_lo95_m_rad": lo.tolist(),
        "deflection_nonlinear_hi95_m_rad": hi.tolist(),
        "K_X_diag_se": se.tolist(),
        "K_X_diag_lo95": (K_X - Z95 * se).tolist(),
        "K_X_diag_hi95": (K_X + Z95 * se).tolist(),
        "method": "covariance of the identified compliances (model file [identification]) "
                  "propagated by the delta method: d(dq)/dx_j = (K_theta - K_C)^-1 e_j "
                  "k_j^2 dq_j at the loaded pose (exact for the linear model without K_C); "
                  "K_X is linear in k, cov(k) from cov(x) by the delta method"
                  + ("; with the model file's link compliance: C_X = J (K_theta - K_C)^-1 "
                     "J^T + sum_l J_l C_l J_l^T, K_X = C_X^-1, the link entries' covariance "
                     + ("and cross-covariance with x propagated (delta method)"
                        if link_covariance_of(r) is not None else
                        "not in the file: the links taken as exact")
                     if links else "")
                  + ("; " + law_uncertainty_text(r) if kq is not k else ""),
    }


#: what the default wrench is, said wherever it is used (campaign stiffness, campaign maps)
WORST_CASE_TEXT = ("default: the paper's worst case, 2200 N and 400 N m along every base "
                   "axis; --wrench to choose another")


def check_limits(robot, q: np.ndarray, controller: bool) -> None:
    """Refuse joint angles (rad, model convention) outside the limits, naming the joint."""
    out = (q < robot.lower - 1e-12) | (q > robot.upper + 1e-12)
    if not np.any(out):
        return
    j = int(np.flatnonzero(out)[0])
    typed = (f" (typed {np.degrees(robot.to_controller(q)[j]):.4g} deg in the pendant "
             "convention)") if controller else ""
    raise InputError(
        f"q{j + 1} = {np.degrees(q[j]):.4g} deg{typed} is outside the joint limits "
        f"[{np.degrees(robot.lower[j]):g}, {np.degrees(robot.upper[j]):g}] deg of "
        f"{robot.name} (model convention); add --ignore-limits to compute anyway",
        where="--q")


def run(o: StiffnessOptions) -> StiffnessResult:
    """Compute everything at the pose; refuse angles outside the limits unless told."""
    # analysis.* pulls in pinocchio: imported when the job runs, not at start-up
    from analysis.kinetostatics.equilibrium import solve_deflection
    from analysis.kinetostatics.maps import WORST_CASE_WRENCH
    from analysis.kinetostatics.stiffness import (
        cartesian_stiffness,
        complementary_stiffness_from_state,
        deflection,
    )
    from analysis.kinetostatics.validity import check_small_displacement
    from analysis.model.kinematics import chain_state, jacobian_from_state, pose_difference

    r, tool = robot_and_tool(o.robot, o.tip, o.tool_xyz_mm, o.tool_rpy_deg)
    q = floats(o.q_rad, "--q", r.n)
    if o.controller_angles:
        q = r.from_controller(q)
    qr = r.check_q(q, where="--q")
    if not o.ignore_limits:
        check_limits(r, qr, o.controller_angles)
    k = joint_stiffness(r, o.joint_stiffness_Nm_per_rad)
    w = wrench(o.wrench_N_Nm, WORST_CASE_WRENCH)
    k_source = ("--joint-stiffness" if o.joint_stiffness_Nm_per_rad is not None else
                "the identified model's values" if r.compliance_covariance is not None
                else "the model's nominal values")
    w_source = "--wrench" if o.wrench_N_Nm is not None else WORST_CASE_TEXT
    from analysis.kinetostatics.compensator_law import compensator_law_of, pose_stiffness

    # the model file's axis-2 compensator law: k2 at this q2 (k itself, no law)
    kq = pose_stiffness(r, qr, k)
    law = compensator_law_of(r)
    if law is not None:  # said where k is shown (terminal, the GUI's Use view)
        from analysis.report.formatting import k_kNm

        k_source += (f"; joint 2 here {k_kNm(kq[1])} kN m/rad from the model file's axis-2 "
                     f"compensator law at q2 = {np.degrees(qr[1]):.4g} deg (k2 above at "
                     f"q2ref = {np.degrees(law.q2ref):.4g} deg)")
    state = chain_state(r, qr)
    J = jacobian_from_state(state)
    K_C = complementary_stiffness_from_state(state, w)
    # K_X needs J^-1; at a singular pose (e.g. the KUKA home pose, A5 = 0) J, K_C and
    # the deflections are still defined and are reported, K_X is marked undefined.
    undefined: dict[str, str] = {}
    K_X = K_X0 = None
    try:
        K_X = cartesian_stiffness(J, kq, K_C)
        K_X0 = cartesian_stiffness(J, kq)
    except SingularPoseError:
        sv = np.linalg.svd(J, compute_uv=False)
        reason = (f"J is singular at this pose (smallest singular value {sv[-1]:.3g}, "
                  f"largest {sv[0]:.3g}): K_X = J^-T (K_theta - K_C) J^-1 needs J^-1; "
                  "the compliance J (K_theta - K_C)^-1 J^T and the deflections are defined")
        undefined = {"K_X": reason, "K_X_without_K_C": reason}
    lin = deflection(J, kq, w, K_C)
    lin0 = deflection(J, kq, w)
    dq = solve_deflection(r, qr, kq, w)
    exact = pose_difference(state.tip, chain_state(r, qr + dq).tip)
    check_small_displacement(r, dq, exact)
    from analysis.kinetostatics.link_compliance import (
        deflection_with_links,
        link_terms,
        links_of,
        stiffness_with_links,
    )

    links = links_of(r)
    if links:  # a model.toml with link compliance: the one kernel, C_X = J (K - K_C)^-1 J^T + ...
        lin = deflection_with_links(r, qr, kq, w, links)[0]
        lin0 = deflection_with_links(r, qr, kq, w, links, with_kc=False)[0]
        exact = exact + link_terms(r, qr, links)[0] @ w
        K_X = stiffness_with_links(r, qr, kq, w, links)[0]
        K_X0 = stiffness_with_links(r, qr, kq, w, links, with_kc=False)[0]
        undefined = {}
    cov_x = None if o.joint_stiffness_Nm_per_rad is not None else r.compliance_covariance
    return StiffnessResult(
        robot=r.name, tool=tool.describe(), q_rad=qr.tolist(),
        joint_stiffness_Nm_per_rad=k.tolist(), joint_stiffness_source=k_source,
        wrench_N_Nm=w.tolist(), wrench_source=w_source,
        J_m_rad_per_rad=J.tolist(), K_C_Nm_per_rad=K_C.tolist(),
        K_X=None if K_X is None else K_X.tolist(),
        K_X_without_K_C=None if K_X0 is None else K_X0.tolist(),
        undefined=undefined, deflection_m_rad=lin.tolist(),
        deflection_without_K_C_m_rad=lin0.tolist(),
        deflection_nonlinear_m_rad=exact.tolist(),
        units={
            "J_m_rad_per_rad": "rows 1-3 m/rad, rows 4-6 rad/rad; base axes at P",
            "K_C_Nm_per_rad": "N m/rad",
            "K_X": "N/m | N/rad ; N | N m/rad blocks, base frame at P (as results.json)",
            "deflection_*_m_rad": "[dx, dy, dz] m, [rx, ry, rz] rad (small rotation "
                                  "vector)",
        },
        tool_text=tool.text(),
        uncertainty=None if cov_x is None else _intervals(r, qr, k, w, J, cov_x, kq),
        compensator=None if law is None else {
            "law": law.text(), "c1_rad_per_Nm_per_rad": law.c1,
            "c2_rad_per_Nm_per_rad2": law.c2, "q2ref_rad": law.q2ref,
            "k2_at_q2ref_Nm_per_rad": float(k[1]),
            "k2_at_q2_Nm_per_rad": float(kq[1]),
            "note": "K_X, the deflections and their intervals use k2(q2); "
                    "joint_stiffness_Nm_per_rad is the file's (at q2ref)"},
    )
