"""Is the tool point P the one the data were measured at? An F-test on the residuals.

A tool point that is wrong by r (flange frame) changes every predicted
displacement: the translation of the measured point P' is ``v + omega x p``
with ``p = R r`` in the base frame. Part of that error is absorbed by the
joint compliances, so the misfit test alone can miss it while k is far off
(a UR10e measured 120 mm from the flange, analysed at the flange, gives k2
half its value at a reduced chi-square of 1.2). This module refits the
residuals of the chosen fit with the compliances AND a tool offset free (one
Gauss-Newton step from the fit's solution, the offset's columns from the
linear model) and asks whether the offset explains significantly more than
noise: F = (delta chi2 / 3) / (chi2 / (n_eq - p - 3)), F(3, n_eq - p - 3)
under "the tool is right". The ratio makes the test independent of a
common scale error of the noise figures. The estimate of r says where P
probably was (one step: about right, not a calibration).

Above :data:`MAX_TESTS` tests an evenly spaced subset is used: the test has
all the power it needs with a few thousand tests, and the analysis of 1e6
tests must not pay a second pass over them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import TallR, whitening
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.model.kinematics import jacobian, tool_pose
from analysis.model.robot_model import RobotModel

#: at most this many tests (evenly spaced) enter the test
MAX_TESTS = 20_000
#: p-value below which the analysis is refused when P was assumed (no tool point given)
P_ASSUMED = 1e-3
#: p-value below which it is refused when a tool point was given (as the misfit test)
P_GIVEN = 1e-6
#: p-value below which a warning is written
P_WARN = 1e-2
#: step of the finite difference along each tool axis (m)
STEP = 1e-3


@dataclass(frozen=True)
class ToolCheck:
    """Result of the tool-point F-test.

    offset_m, se_m : (3,) estimated move of P from the assumed point, flange
        (tool) frame axes, and its standard error (m).
    f_value, p_value : the F statistic and P(F >= observed) under "P is right".
    delta_chi2, chi2 : chi-square explained by the offset, and left after it.
    dof : residual degrees of freedom of the augmented fit.
    n_tests : tests used. k_moved : (6,) k of the augmented step (N m/rad; NaN where not
        identified or not positive): what k would be with P moved by ``offset_m``.
    """

    offset_m: np.ndarray
    se_m: np.ndarray
    f_value: float
    p_value: float
    delta_chi2: float
    chi2: float
    dof: int
    n_tests: int
    k_moved: np.ndarray

    def text(self) -> str:
        mm = np.round(self.offset_m * 1e3, 1) + 0.0
        se = np.round(self.se_m * 1e3, 1) + 0.0
        return (f"the residuals point to P at xyz {mm.tolist()} +- {se.tolist()} mm (flange "
                f"axes) from the tool point used: F = {self.f_value:.3g}, P(F >= observed) = "
                f"{self.p_value:.2g} ({self.n_tests} tests; chi-square "
                f"{self.chi2 + self.delta_chi2:.4g} -> {self.chi2:.4g})")

    def describe(self) -> dict:
        """JSON-ready record (mm)."""
        return {"offset_mm": (self.offset_m * 1e3).tolist(), "se_mm": (self.se_m * 1e3).tolist(),
                "F": self.f_value, "p_value": self.p_value, "dof": self.dof,
                "n_tests": self.n_tests,
                "k_moved_Nm_per_rad": [None if not np.isfinite(v) else float(v)
                                       for v in self.k_moved]}


def _subset(m: int) -> np.ndarray:
    if m <= MAX_TESTS:
        return np.arange(m)
    return np.unique(np.linspace(0, m - 1, MAX_TESTS).round().astype(np.int64))


#: tests per block of the augmented system (its per-test arrays stay small)
BLOCK = 4096


def tool_columns(robot, q: np.ndarray, J: np.ndarray, w: np.ndarray, x: np.ndarray,
                 base: np.ndarray) -> np.ndarray:
    """B (m, 6, 3): the linear model's displacement [m; rad] per metre of a move of P along
    each tool (flange) axis, finite differences of :data:`STEP`; J (m, 6, 6) the Jacobian at
    q, w (m, 6) the wrench at P, x (6,) the compliances, ``base`` (m, 6) the linear model's
    prediction J X J^T w."""
    R = tool_pose(robot, q)[:, :3, :3]
    B = np.empty((q.shape[0], 6, 3))
    for i in range(3):
        p = R[:, :, i] * STEP  # P moved by STEP along tool axis i, in the base frame
        Jr = J.copy()
        # translation rows of the point moved by p: v - p x omega, column by column
        Jr[:, :3, :] -= np.cross(p[:, None, :], np.swapaxes(J[:, 3:, :], 1, 2)).swapaxes(1, 2)
        B[:, :, i] = (np.einsum("mrj,j->mr", design_block(Jr, w), x) - base) / STEP
    return B


def _whitened_rows(robot, sub: TestArrays, cols, x, noise, method) -> np.ndarray:
    """Rows [L^-1 A | L^-1 B | L^-1 e] (6 b, p + 4) of the tests ``sub``: the compliance
    columns A of ``method``'s model, the tool offset's columns B (finite differences of
    STEP along the tool axes), the residuals e, whitened by the fits' own covariances
    (components not measured get zero rows)."""
    q, w, d, meas = sub.q, sub.w, sub.d, sub.measured
    J = jacobian(robot, q)
    A_lin = design_block(J, w)
    base = np.einsum("mrj,j->mr", A_lin, x)  # the linear model's prediction
    if method == "exact":
        from analysis.identification.estimators.exact_model import model_displacement

        pred, D = model_displacement(robot, q, x, w, w_ref=sub.w_ref)
        A = D[..., cols]
    else:
        pred, A = base, A_lin[..., cols]
    B = tool_columns(robot, q, J, w, x, base)
    C = np.einsum("mrj,j,msj->mrs", J, x, J)
    Linv = whitening(residual_covariance(noise, C, w), meas)
    e = np.where(meas, d - pred, 0.0)
    M = np.concatenate([A, B], axis=2)
    return np.column_stack([(Linv @ M).reshape(-1, M.shape[-1]),
                            np.einsum("mij,mj->mi", Linv, e).reshape(-1)])


def tool_point_check(robot: RobotModel, tests: TestArrays, joints, x: np.ndarray,
                     noise: NoiseModel, method: str) -> ToolCheck | None:
    """F-test of a tool offset on the residuals of a fit (see the module docstring).

    ``x`` (6,) joint compliances of the fit (rad/(N m), 0 for joints taken rigid);
    ``method`` "exact" uses the equilibrium model for residuals and compliance
    columns, "ols"/"wls" the linear model (each fit's own model). None when the
    augmented system leaves no degrees of freedom or the offset is not
    determined by the poses.
    """
    sub = tests.subset(_subset(tests.m))
    cols = list(joints)
    p = len(cols)
    x = np.asarray(x, dtype=float)
    # the whitened augmented system [L^-1 M | L^-1 e] (M = [A | B]) reduced block by block
    # to its triangular factor (TSQR): both least squares below come from it
    n_eq = int(sub.measured.sum())
    dof = n_eq - p - 3
    if dof <= 0:
        return None
    acc = TallR()
    for s in range(0, sub.m, BLOCK):
        part = sub.subset(slice(s, s + BLOCK))
        acc.add(_whitened_rows(robot, part, cols, x, noise, method))
    R = acc.r()  # (p + 4, p + 4): 6 m >= n_eq > p + 3 rows
    scale = np.linalg.norm(R[:, :p + 3], axis=0)
    scale[scale == 0] = 1.0
    Rm = R[:p + 3, :p + 3] / scale
    if np.linalg.cond(Rm) > 1e10:
        return None
    step = np.linalg.solve(Rm, R[:p + 3, p + 3]) / scale
    chi2_aug = float(R[p + 3, p + 3] ** 2)
    # compliances alone: the same system without the offset's columns (a column subset of
    # R is Q^T times that subset of the system, so its triangular factor gives the residual)
    Ra = np.linalg.qr(R[:, [*range(p), p + 3]], mode="r")
    chi2_x = float(Ra[p, p] ** 2)
    delta = max(chi2_x - chi2_aug, 0.0)
    f_value = (delta / 3.0) / (chi2_aug / dof) if chi2_aug > 0 else float("inf")
    from scipy import special  # F survival function, without importing scipy.stats

    p_value = float(special.fdtrc(3, dof, f_value))
    Rinv = np.linalg.inv(Rm)
    cov = (Rinv @ Rinv.T) / np.outer(scale, scale) * (chi2_aug / dof)
    k_moved = np.full(6, np.nan)
    x_new = x[cols] + step[:p]
    k_moved[cols] = np.where(x_new > 0, 1.0 / np.where(x_new > 0, x_new, 1.0), np.nan)
    return ToolCheck(offset_m=step[p:], se_m=np.sqrt(np.diag(cov)[p:]), f_value=float(f_value),
                     p_value=p_value, delta_chi2=delta, chi2=chi2_aug, dof=dof,
                     n_tests=sub.m, k_moved=k_moved)
