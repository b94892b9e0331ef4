"""Why does the joint-spring model misfit? Nested alternatives tested on the residuals.

Each alternative adds columns B to the fitted model (regressors in
:mod:`analysis.identification.checks.cause_columns`): compliant links 2 and 3,
a lost-motion step per joint that follows the sign change of the joint's gear
torque, a k2 that varies with q2 (a gravity compensator), a relative scale of
rotations and moments (units).
The compensator's columns also hold a static deflection of joint 2 that follows q2:
the spring's torque deflects the gear at both readings, so the arm does not stand at
the encoders' q2. On the whitened residuals e of the fit and the
whitened compliance columns A, the columns are projected off A, scaled to unit
norm and reduced to their identifiable combinations by an SVD (singular values
above :data:`RANK_TOL` times the largest: r combinations). Then, as for the
tool point (:mod:`analysis.identification.checks.tool_check`, whose test is
reused here),

    F = (delta chi2 / r) / (chi2_left / (n - p - r)),  F(r, n - p - r) under
    "the joint springs are right",

independent of a common scale error of the noise figures. Causes are ranked by
the Bayesian information criterion of the augmented fit with the variance
estimated, ``n ln(chi2_left / chi2) + r ln n`` (the more negative, the stronger
the evidence; it weighs the number of parameters, which a p-value alone does
not), significant ones (p < :data:`LEVEL`) first.

The lost-motion alternative needs the gear torques at the reference and at the
loaded reading (from a mass model of the robot): without them it is not
tested, and :class:`CauseRanking` says so rather than guess the flanks.

Larger F/T noise is suggested only if it would make the fit pass: the smallest
factor of :data:`FT_FACTORS` on the F/T sigmas whose chi-square (at the fitted
x) passes the misfit test, or none.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from analysis.identification.checks import cause_columns as cc
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import whitening
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.model.kinematics import jacobian

#: level of each cause's own test
LEVEL = 0.01
#: singular values of the projected, column-normalised extra regressor below this times the
#: largest are taken as not identified from these poses
RANK_TOL = 1e-3
#: at most this many tests (evenly spaced) enter the tests
MAX_TESTS = 5000
#: factors on the F/T noise tried before suggesting a larger F/T noise
FT_FACTORS = (1.25, 1.5, 2.0, 3.0, 5.0)
#: the misfit test's level (as plausibility.MISFIT_P)
MISFIT_P = 1e-6
#: rows named as evidence per cause
EVIDENCE_ROWS = 3

NAMES = {
    "link_compliance": "compliant links (links 2 and 3 bend or twist under the load: a "
                       "virtual-joint model of their 6 x 6 compliances)",
    "lost_motion": "lost motion (gear play: joints whose transmitted torque changes sign "
                   "between the reference and the loaded reading travel through their dead "
                   "band; a reference reading under a preload in the load's direction keeps "
                   "each joint on one flank)",
    "compensator": "a spring on joint 2 whose stiffness and torque vary with q2 (an axis-2 "
                   "gravity compensator: k2 and the static deflection of joint 2 follow q2)",
    "tool_point": "the tool point P (the displacements and wrench must be at the P given to "
                  "the analysis: --tool-xyz-mm/--tool-rpy-deg or the protocol's [tool])",
    "units": "units of rotations or moments relative to translations and forces (rotations "
             "in mrad, moments in N m)",
}


@dataclass(frozen=True)
class CauseTest:
    """One alternative's F-test on the residuals of the joint-spring fit.

    cause : key (``link_compliance``, ``lost_motion``, ``compensator``, ``tool_point``,
        ``units``). f_value, p_value : F statistic and P(F >= observed) under "joint springs".
    dof : (r, n - p - r): combinations identified, residual degrees of freedom.
    chi2, chi2_left : chi-square of the fit and after the alternative.
    bic : change of the information criterion (negative: evidence for the alternative).
    estimate : what the alternative's fit says (text, SI made readable), or "".
    rows : input lines of the tests the alternative explains most of.
    given, p_given : the best-ranked cause this one was tested beside, and the p-value of
        this one's columns added to that cause's fit (its F with this one's identified
        combinations beyond that cause's and the residual dof left by both); "" and None
        for the best-ranked cause itself.
    """

    cause: str
    f_value: float
    p_value: float
    dof: tuple[int, int]
    chi2: float
    chi2_left: float
    bic: float
    estimate: str = ""
    rows: tuple[int, ...] = ()
    given: str = ""
    p_given: float | None = None

    @property
    def significant(self) -> bool:
        """Its own test is significant at :data:`LEVEL`."""
        return bool(self.p_value < LEVEL)

    @property
    def beyond(self) -> bool:
        """It explains significantly more than the best-ranked cause alone (True for that
        cause itself when significant). The tool point only as the best-ranked cause: its
        three columns (a move of P) take up part of any smooth misfit of the translations,
        and of another cause's misfit left by that cause's own approximate columns (a
        compensator's quadratic in q2 on a k2(q2) that is not quite quadratic): beside a
        better cause it is no evidence of a wrong P."""
        if self.p_given is not None and self.cause == "tool_point":
            return False
        return self.significant and (self.p_given is None or self.p_given < LEVEL)

    def text(self) -> str:
        est = f"; {self.estimate}" if self.estimate else ""
        rows = f"; lines {', '.join(str(r) for r in self.rows)}" if self.rows else ""
        return (f"{NAMES[self.cause]}: F = {self.f_value:.3g} with ({self.dof[0]}, "
                f"{self.dof[1]}) dof, p = {self.p_value:.2g}, chi-square {self.chi2:.4g} -> "
                f"{self.chi2_left:.4g}{est}{rows}")

    def describe(self) -> dict:
        return {"cause": self.cause, "F": self.f_value, "dof": list(self.dof),
                "p_value": self.p_value, "chi2": self.chi2, "chi2_left": self.chi2_left,
                "bic_change": self.bic, "significant": self.significant,
                "estimate": self.estimate, "evidence_lines": list(self.rows),
                # beside a significant first cause: the test given it, and the verdict
                **({"given": self.given, "p_value_given": self.p_given, "named": self.beyond}
                   if self.given else {})}


@dataclass(frozen=True)
class CauseRanking:
    """The alternatives tested, ranked (significant first, by information criterion), the
    ones not tested with why, the F/T noise factor that would make the fit pass (None:
    none of :data:`FT_FACTORS` would), the tests used, and the flagged components set
    aside."""

    tests: tuple[CauseTest, ...]
    not_tested: tuple[tuple[str, str], ...]
    ft_factor: float | None
    n_tests: int
    #: components the outlier test flagged, set aside before the tests (a few glitches)
    set_aside: int = 0
    #: refits in other pose conventions (:mod:`.conventions`), best first
    conventions: tuple = ()

    @property
    def convention(self):
        """The convention that explains the misfit (its refit passes), or None."""
        return next((c for c in self.conventions if c.explains), None)

    @property
    def named(self) -> tuple[CauseTest, ...]:
        """The causes named, best first: the best-ranked one when its own test is
        significant, then each other whose own test is significant AND that adds
        significantly to the best one's fit (a cause whose columns only mimic the best
        one's is not named beside it)."""
        return tuple(t for t in self.tests if t.beyond)

    def first(self) -> str | None:
        if self.convention is not None:
            return "sign_convention"
        named = self.named
        return named[0].cause if named else None

    def describe(self) -> dict:
        return {"level": LEVEL, "n_tests": self.n_tests,
                "ranked": [t.describe() for t in self.tests],
                "not_tested": [{"cause": c, "why": why} for c, why in self.not_tested],
                "outlier_components_set_aside": self.set_aside,
                "conventions": [c.describe() for c in self.conventions],
                "ft_noise_factor_that_passes": self.ft_factor}


@dataclass(frozen=True)
class _Whitened:
    """The fit's whitened system on a subset of the tests: Q (n, p) an orthonormal basis of
    the compliance columns, e (n,) the residuals projected off them, Linv (m, 6, 6), the
    Jacobian J (m, 6, 6), the compliance columns A (m, 6, 6) and prediction (m, 6)."""

    Q: np.ndarray
    e: np.ndarray
    Linv: np.ndarray
    J: np.ndarray
    A: np.ndarray
    predicted: np.ndarray
    n_eq: int
    p: int


def _subset(m: int) -> np.ndarray:
    if m <= MAX_TESTS:
        return np.arange(m)
    return np.unique(np.linspace(0, m - 1, MAX_TESTS).round().astype(np.int64))


def _whitened(robot, tests: TestArrays, cols, x, noise: NoiseModel, method: str) -> _Whitened:
    q, w, d, meas = tests.q, tests.w, tests.d, tests.measured
    J = jacobian(robot, q)
    if method == "exact":
        from analysis.identification.estimators.exact_model import model_displacement

        pred, A = model_displacement(robot, q, x, w, w_ref=tests.w_ref)
    else:
        A = design_block(J, w)
        pred = np.einsum("mrj,j->mr", A, x)
    C = np.einsum("mrj,j,msj->mrs", J, x, J)
    Linv = whitening(residual_covariance(noise, C, w), meas)
    WA = (Linv @ A[..., list(cols)]).reshape(-1, len(cols))
    e = np.einsum("mij,mj->mi", Linv, np.where(meas, d - pred, 0.0)).reshape(-1)
    Q, _ = np.linalg.qr(WA)
    e = e - Q @ (Q.T @ e)
    return _Whitened(Q, e, Linv, J, A, pred, int(meas.sum()), len(cols))


def _reduced(wh: _Whitened, B: np.ndarray):
    """(U (n, r), V (r0, r) / s, kept): an orthonormal basis of B's whitened columns projected
    off the model's, reduced by SVD (singular values >= RANK_TOL of the largest), and the map
    from its coordinates back to B's parameters (None when nothing is left)."""
    WB = (wh.Linv @ B).reshape(-1, B.shape[-1])
    WB = WB - wh.Q @ (wh.Q.T @ WB)
    norm = np.linalg.norm(WB, axis=0)
    keep = norm > 0
    if not keep.any():
        return None
    Wn = WB[:, keep] / norm[keep]
    U, s, Vt = np.linalg.svd(Wn, full_matrices=False)
    r = int(np.sum(s > RANK_TOL * s[0]))
    back = np.zeros((B.shape[-1], r))
    back[keep] = (Vt[:r].T / s[:r]) / norm[keep][:, None]
    return U[:, :r], back


def _f_test(wh: _Whitened, cause: str, U: np.ndarray, lines, estimate: str = "") -> CauseTest:
    """The F-test of the alternative whose projected whitened columns span U (n, r)."""
    from scipy import special  # F survival function, without importing scipy.stats

    r = U.shape[1]
    chi2 = float(wh.e @ wh.e)
    proj = U.T @ wh.e
    delta = float(proj @ proj)
    left = max(chi2 - delta, 0.0)
    dof2 = wh.n_eq - wh.p - r
    f = (delta / r) / (left / dof2) if left > 0 else float("inf")
    p = float(special.fdtrc(r, dof2, f))
    fitted = (U @ proj).reshape(-1, 6)
    gain = np.sum(fitted**2, axis=1)
    top = np.argsort(gain)[::-1][:EVIDENCE_ROWS]
    bic = wh.n_eq * float(np.log(max(left, 1e-300) / chi2)) + r * float(np.log(wh.n_eq))
    return CauseTest(cause, float(f), p, (r, dof2), chi2, left, bic, estimate,
                     tuple(int(lines[i]) for i in top))


def _lost_motion(wh: _Whitened, taus, lines):
    tau_ref, tau_load = taus
    B, flips = cc.lost_motion_columns(wh.J, tau_ref, tau_load)
    red = _reduced(wh, B)
    if red is None or red[0].shape[1] == 0:
        return None, "no joint's gear torque changes sign between reference and loaded reading"
    U, back = red
    band = back @ (U.T @ wh.e)  # 2b per joint (rad), minimum-norm where not all identified
    n_flip = flips.sum(axis=0)
    est = ", ".join(f"joint {j + 1} {band[j] * 1e3:.2g} mrad ({n_flip[j]} flips)"
                    for j in range(6) if n_flip[j])
    return (_f_test(wh, "lost_motion", U, lines, f"dead band 2b: {est}"), U), None


def _simple(wh: _Whitened, cause: str, B: np.ndarray, lines):
    red = _reduced(wh, B)
    if red is None or red[0].shape[1] == 0 or wh.n_eq - wh.p - red[0].shape[1] <= 0:
        return None
    return _f_test(wh, cause, red[0], lines), red[0]


#: step of the finite difference along a joint angle (rad)
ANGLE_STEP = 1e-5


def _angle_derivative(robot, tests: TestArrays, x, method: str, predicted: np.ndarray,
                      joint: int) -> np.ndarray:
    """(m, 6) derivative of the fit's model displacement with respect to ``joint``'s angle
    (m/rad, rad/rad), a forward difference of ANGLE_STEP."""
    q = tests.q.copy()
    q[:, joint] += ANGLE_STEP
    if method == "exact":
        from analysis.identification.estimators.exact_model import model_displacement

        moved, _ = model_displacement(robot, q, x, tests.w, with_jacobian=False,
                                      w_ref=tests.w_ref)
    else:
        moved = np.einsum("mrj,j->mr", design_block(jacobian(robot, q), tests.w), x)
    return (moved - predicted) / ANGLE_STEP


def _tool(robot, tests, joints, x, noise, method):
    from analysis.identification.checks.tool_check import tool_point_check

    chk = tool_point_check(robot, tests, joints, x, noise, method)
    if chk is None:
        return None
    n = chk.dof + len(joints) + 3
    chi2 = chk.chi2 + chk.delta_chi2
    bic = n * float(np.log(max(chk.chi2, 1e-300) / chi2)) + 3 * float(np.log(n))
    mm = np.round(chk.offset_m * 1e3, 1) + 0.0
    return CauseTest("tool_point", chk.f_value, chk.p_value, (3, chk.dof), chi2, chk.chi2, bic,
                     f"P at xyz {mm.tolist()} mm (flange axes) from the one used")


def _tool_basis(wh: _Whitened, robot, sub: TestArrays, x) -> np.ndarray | None:
    """The tool offset's projected whitened columns (n, r) on ``wh`` (the tool check's
    columns, :func:`~analysis.identification.checks.tool_check.tool_columns`)."""
    from analysis.identification.checks.tool_check import tool_columns

    base = np.einsum("mrj,j->mr", design_block(wh.J, sub.w), x)
    red = _reduced(wh, tool_columns(robot, sub.q, wh.J, sub.w, x, base))
    return None if red is None or red[0].shape[1] == 0 else red[0]


def _given(wh: _Whitened, top: np.ndarray, U: np.ndarray) -> float:
    """p-value of the columns U (n, r) added to the fit that already has ``top`` (n, r0)
    (both orthonormal, projected off the model): U's part beyond top, reduced by SVD as in
    :func:`_reduced`, F((r', n - p - r0 - r')); 1.0 when nothing is left beyond top."""
    from scipy import special

    V = U - top @ (top.T @ U)
    if not V.size:
        return 1.0
    W, s, _ = np.linalg.svd(V, full_matrices=False)
    r = int(np.sum(s > RANK_TOL))  # U's columns are unit vectors: s <= 1
    if r == 0:
        return 1.0
    W = W[:, :r]
    e = wh.e - top @ (top.T @ wh.e)
    proj = W.T @ e
    delta = float(proj @ proj)
    left = max(float(e @ e) - delta, 0.0)
    dof2 = wh.n_eq - wh.p - top.shape[1] - r
    if dof2 <= 0:
        return 1.0
    f = (delta / r) / (left / dof2) if left > 0 else float("inf")
    return float(special.fdtrc(r, dof2, f))


def ft_noise_factor(robot, tests: TestArrays, joints, x, noise: NoiseModel, method: str,
                    predicted: np.ndarray | None = None) -> float | None:
    """The smallest factor of :data:`FT_FACTORS` on the F/T sigmas (absolute and relative)
    with which the fit's chi-square (at x) passes the misfit test (1.0: it passes as
    declared), or None."""
    from scipy import special

    J = jacobian(robot, tests.q)
    if predicted is None:
        if method == "exact":
            from analysis.identification.estimators.exact_model import model_displacement

            predicted, _ = model_displacement(robot, tests.q, x, tests.w, with_jacobian=False,
                                              w_ref=tests.w_ref)
        else:
            predicted = np.einsum("mrj,j->mr", design_block(J, tests.w), x)
    C = np.einsum("mrj,j,msj->mrs", J, x, J)
    e = np.where(tests.measured, tests.d - predicted, 0.0)
    dof = int(tests.measured.sum()) - len(joints)
    if dof <= 0:
        return None
    for s in (1.0, *FT_FACTORS):
        wider = replace(noise, force_sigma=noise.force_sigma * s,
                        moment_sigma=noise.moment_sigma * s,
                        force_relative=noise.force_relative * s,
                        moment_relative=noise.moment_relative * s)
        Linv = whitening(residual_covariance(wider, C, tests.w), tests.measured)
        chi2 = float(np.sum(np.einsum("mij,mj->mi", Linv, e) ** 2))
        if float(special.chdtrc(dof, chi2)) >= MISFIT_P:
            return s
    return None


def rank_causes(robot, tests: TestArrays, joints, x: np.ndarray, noise: NoiseModel,
                method: str, gear_torques: tuple[np.ndarray, np.ndarray] | None = None,
                no_torques_reason: str = "no mass model of the robot: the gear torques, "
                                         "and so each joint's flank, are unknown",
                ) -> CauseRanking:
    """Test every alternative on the residuals of a fit and rank them (module docstring).

    ``x`` (6,) the fit's joint compliances (rad/(N m)), ``joints`` the fitted ones,
    ``method`` "exact" (the equilibrium model's residuals and columns) or "ols"/"wls"
    (the linear model's). ``gear_torques``: (tau_ref, tau_load) (m, 6) each (N m), the
    torque each gear transmits at the reference and at the loaded reading, or None
    (lost motion then not tested, for ``no_torques_reason``).
    """
    idx = _subset(tests.m)
    sub = tests.subset(idx)
    cols = tuple(joints)
    x = np.asarray(x, dtype=float)
    wh = _whitened(robot, sub, cols, x, noise, method)
    lines = sub.line
    out: list[tuple[CauseTest, np.ndarray | None]] = []
    skipped: list[tuple[str, str]] = []
    t = _simple(wh, "link_compliance", cc.link_compliance_columns(robot, sub.q, sub.w), lines)
    if t is not None:
        out.append(t)
    if gear_torques is None:
        skipped.append(("lost_motion", no_torques_reason))
    else:
        taus = (np.asarray(gear_torques[0])[idx], np.asarray(gear_torques[1])[idx])
        t, why = _lost_motion(wh, taus, lines)
        if t is None:
            skipped.append(("lost_motion", why))
        else:
            out.append(t)
    if 1 in cols:
        G = _angle_derivative(robot, sub, x, method, wh.predicted, 1)
        t = _simple(wh, "compensator", cc.compensator_columns(wh.A[:, :, 1], G, sub.q, 1),
                    lines)
        if t is not None:
            out.append(t)
    else:
        skipped.append(("compensator", "joint 2 not identified"))
    t = _tool(robot, tests, cols, x, noise, method)
    if t is not None:
        out.append((t, _tool_basis(wh, robot, sub, x)))
    t = _simple(wh, "units", cc.units_columns(wh.J, x, sub.w, wh.predicted), lines)
    if t is not None:
        out.append(t)
    out.sort(key=lambda cu: (not cu[0].significant, cu[0].bic if cu[0].significant
                             else np.log(max(cu[0].p_value, 1e-300))))
    ranked = [c for c, _ in out]
    if ranked and ranked[0].significant and out[0][1] is not None:
        top = out[0][1]
        ranked = [ranked[0], *(replace(c, given=ranked[0].cause,
                                       p_given=1.0 if U is None else _given(wh, top, U))
                               for c, U in out[1:])]
    ft = ft_noise_factor(robot, sub, cols, x, noise, method, wh.predicted)
    from analysis.identification.checks.conventions import convention_checks

    return CauseRanking(tuple(ranked), tuple(skipped), ft, sub.m,
                        conventions=convention_checks(robot, sub, cols, x, noise))
