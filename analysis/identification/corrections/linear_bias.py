"""Linearisation bias of the linear estimators (OLS, WLS), estimated and corrected.

The linear model ``A x`` (eqs. 14-18) is the first-order term of the finite
displacement ``f(x)`` of the equilibrium. A linear estimator ``x_hat = G d``
therefore has the expectation ``g(x) = x + b(x)``, with the bias
``b(x) = G (f(x) - A x)`` (the exact-minus-linear prediction of every test,
mapped through the estimator).

Correction (:func:`correct_linear_bias`): the corrected estimate ``x_c`` solves
``g(x_c) = x_hat``, i.e. ``x_c = x_hat - b(x_c)``: the compliances whose
expected linear estimate is the one observed. It is found by quasi-Newton steps
with the Jacobian ``I + B``, ``B = G (F - A)`` (F = df/dx, the exact model's
Jacobian) at ``x_hat``; its covariance is ``M cov(x_hat) M^T``, ``M = (I + B)^-1``
(first order). Where the correction is reliable the interval of the corrected
estimate covers as the exact fit's does; no widening.

Reliability: ``B`` scaled by the standard errors, ``S^-1 B S`` (S = diag(se)), says
by how many standard errors the bias moves when x moves by one standard error. Its
2-norm (:data:`CONTRACTION_LIMIT`) must stay at most 0.5: then the fixed point is
unique near the estimate, the steps contract at least by half, and ``M`` changes
no standard error by more than a factor 2, so its first-order propagation is
sound. Beyond, or when the equilibrium cannot be solved at an iterate, or the
steps do not converge, the correction is unreliable: the raw estimate is kept,
its interval widened by |b(x_hat)| (when finite), and the result refused
(:func:`analysis.identification.checks.plausibility.problems`; ``--accept-misfit``
keeps it, marked).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.estimators.exact_model import model_displacement_masked
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import stack_vector
from analysis.identification.streaming.blocks import EVAL_BLOCK
from analysis.model.robot_model import RobotModel

#: the correction is unreliable when || S^-1 B S ||_2 exceeds this (S = diag(se))
CONTRACTION_LIMIT = 0.5
#: quasi-Newton steps allowed to solve x_c + b(x_c) = x_hat, each one reducing the residual
#: (2 on the examples; at 35 x w_eff, contraction 0.43, 7 were needed and a limit of 6
#: refused a correction that then converged to the truth)
MAX_STEPS = 20
#: converged when the equation's residual is below this fraction of every se
TOLERANCE_SE = 1e-6


def linearisation_bias(
    robot: RobotModel,
    tests: TestArrays,
    joints: tuple[int, ...],
    x: np.ndarray,
    G,
    predicted: np.ndarray,
) -> np.ndarray:
    """Bias (p,) of the linear estimate at compliances x (p,) (rad/(N m)): ``G (f(x) - A x)``.

    ``G`` (p, 6m): the estimator (x = G d, stacked measured components; an array or
    a :class:`~analysis.identification.estimators.fit_record.FactoredEstimator`); ``predicted``
    (m, 6): the linear model's A x. NaN where the equilibrium cannot be solved at x.
    """
    x_full = np.zeros(robot.n)
    x_full[list(joints)] = x
    # the equilibrium in blocks of tests: its chain states are ~2.6 kB per test at once
    diff = np.empty_like(predicted)
    for s in range(0, tests.m, EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        f, _, ok = model_displacement_masked(robot, tests.q[sl], x_full, tests.w[sl],
                                             with_jacobian=False,
                                             w_ref=None if tests.w_ref is None else tests.w_ref[sl])
        if not np.all(ok):
            return np.full(len(joints), np.nan)
        diff[sl] = np.where(tests.measured[sl], f - predicted[sl], 0.0)
    return G @ stack_vector(diff)


def _gather(G, sl, V: np.ndarray) -> np.ndarray:
    """``A^T W V`` (p, k) of the tests ``sl`` for the factored estimator G = bread A^T W;
    V (b, 6, k), zero where not measured."""
    if G.Linv is not None:  # W V = Linv^T Linv V per test
        Lb = np.asarray(G.Linv[sl], dtype=float)
        V = np.einsum("mji,mjk->mik", Lb, np.einsum("mij,mjk->mik", Lb, V))
    return np.einsum("mrp,mrk->pk", np.asarray(G.A[sl], dtype=float), V)


def _bias_and_slope(robot, tests, joints, x, G, A, slope: bool = True, out=None):
    """(b (p,), B (p, p) or None) at x: ``G (f(x) - A x)`` and ``G (F(x) - A)``, blockwise;
    NaN when the equilibrium cannot be solved at x. ``A`` (m, 6, p), array or made when
    sliced; ``out`` (m, 6): receives f(x) (m, rad)."""
    p = len(joints)
    x_full = np.zeros(robot.n)
    x_full[list(joints)] = x
    acc = np.zeros((p, p + 1 if slope else 1))
    for s in range(0, tests.m, EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        f, D, ok = model_displacement_masked(robot, tests.q[sl], x_full, tests.w[sl],
                                             with_jacobian=slope,
                                             w_ref=None if tests.w_ref is None else tests.w_ref[sl])
        if not np.all(ok):
            return np.full(p, np.nan), (np.full((p, p), np.nan) if slope else None)
        if out is not None:
            out[sl] = f
        Ab = np.asarray(A[sl], dtype=float)
        meas = tests.measured[sl][..., None]
        V = np.where(meas, (f - Ab @ x)[..., None], 0.0)
        if slope:
            V = np.concatenate([np.where(meas, D[..., list(joints)] - Ab, 0.0), V], axis=-1)
        acc += _gather(G, sl, V)
    res = G.bread @ acc
    return res[:, -1], (res[:, :p] if slope else None)


@dataclass(frozen=True)
class BiasCorrection:
    """Outcome of :func:`correct_linear_bias` (compliances in rad/(N m)).

    ``x_raw`` the linear estimate, ``bias`` b(x_raw) (p,), ``x`` the corrected
    estimate (x_raw where not reliable), ``propagation`` M (p, p) with cov(x) = M
    cov(x_raw) M^T (identity where not reliable), ``contraction`` ||S^-1 B S||_2,
    ``steps`` quasi-Newton steps taken, ``residual_se`` the largest |x + b(x) - x_raw|
    / se left, ``reliable`` and ``reason`` (why not; empty when reliable);
    ``predicted`` (m, 6) the exact model's displacement at x (m, rad), None where not
    reliable.
    """

    method: str
    joints: tuple[int, ...]
    x_raw: np.ndarray
    bias: np.ndarray
    x: np.ndarray
    propagation: np.ndarray
    contraction: float
    steps: int
    residual_se: float
    reliable: bool
    reason: str = ""
    predicted: np.ndarray | None = None


def correct_linear_bias(robot: RobotModel, tests: TestArrays, joints: tuple[int, ...], fit,
                        se_x: np.ndarray, method: str,
                        limit: float | None = None) -> BiasCorrection:
    """Solve ``x + G (f(x) - A x) = x_hat`` for the linear fit ``fit`` (its x, A, estimator).

    ``se_x`` (p,): standard errors of ``fit.x`` (rad/(N m)). See the module docstring
    for the criterion of reliability. ``fit`` is not changed: a reliable correction
    carries the exact model's values f(x_c) (m, 6) in ``predicted``
    (:func:`corrected_fit` makes the fit whose residuals are those).
    """
    limit = CONTRACTION_LIMIT if limit is None else limit
    x_hat = np.asarray(fit.x, dtype=float)
    p = len(joints)
    G, A = fit.estimator, fit.A
    b0, B = _bias_and_slope(robot, tests, joints, x_hat, G, A)

    def give_up(reason: str, contraction: float = float("nan"), steps: int = 0):
        return BiasCorrection(method, joints, x_hat, b0, x_hat, np.eye(p), contraction,
                              steps, float("nan"), False, reason)

    if not (np.all(np.isfinite(b0)) and np.all(np.isfinite(B))):
        return give_up("the equilibrium cannot be solved at the linear estimate, so its "
                       "linearisation bias is unknown")
    scaled = B * (se_x[None, :] / se_x[:, None])  # S^-1 B S
    contraction = float(np.linalg.norm(scaled, 2))
    if contraction > limit:
        return give_up(f"the bias moves by {contraction:.2f} standard errors per standard "
                       f"error of x (limit {limit:g}): it depends on the unknown compliances "
                       "too strongly for the correction to be trusted", contraction)
    M = np.linalg.inv(np.eye(p) + B)
    x = x_hat - M @ b0
    residual = float("inf")
    f = np.empty(tests.measured.shape)  # the model at the last iterate (48 MB at 1e6 tests)
    for step in range(1, MAX_STEPS + 1):
        b, _ = _bias_and_slope(robot, tests, joints, x, G, A, slope=False, out=f)
        if not np.all(np.isfinite(b)):
            return give_up("the equilibrium cannot be solved at a corrected estimate",
                           contraction, step)
        r = x + b - x_hat
        last, residual = residual, float(np.max(np.abs(r) / se_x))
        if residual <= TOLERANCE_SE:
            break
        if not residual < last:  # the steps no longer contract: no fixed point near x_hat
            return give_up(f"the correction's steps do not converge (residual {residual:.2g} "
                           f"se after step {step}, {last:.2g} before)", contraction, step)
        x = x - M @ r
    else:
        return give_up(f"the correction did not converge in {MAX_STEPS} steps "
                       f"(residual {residual:.2g} se)", contraction, MAX_STEPS)
    return BiasCorrection(method, joints, x_hat, b0, x, M, contraction, step, residual, True,
                          predicted=f)


def corrected_fit(fit, c: BiasCorrection):
    """``fit`` as the residuals see it after the correction ``c``: where ``c`` is reliable,
    a new fit whose ``predicted`` is the exact model's f(x_c) (chi-square, outliers,
    notes), else the linear model's A x_hat (``fit`` itself, or, when its prediction was
    let go during the correction, a new fit with it made again: no (m, 6) array held
    beside f(x_c) while the correction runs)."""
    from dataclasses import replace

    from analysis.identification.streaming.per_test import apply

    if c.reliable:
        return replace(fit, predicted=c.predicted)
    return fit if fit.predicted is not None else replace(fit, predicted=apply(fit.A, fit.x))


def summary(c: BiasCorrection, se_raw: np.ndarray, se: np.ndarray) -> dict:
    """results.json ``linearisation_bias``: raw and corrected k per joint (6 entries, null
    for joints not identified), the bias in standard errors and relative to k, the
    criterion and a one-line note. ``se_raw``, ``se`` (p,): standard errors of x_raw, x."""

    def per_joint(v):
        out = [None] * 6
        for j, val in zip(c.joints, v, strict=True):
            out[j] = None if not np.isfinite(val) else float(val)
        return out

    with np.errstate(divide="ignore", invalid="ignore"):
        k_raw, k = 1.0 / c.x_raw, 1.0 / c.x
        in_se = c.bias / se_raw
        k_change = c.x_raw / c.x - 1.0  # k_corrected / k_raw - 1
    worst = int(np.nanargmax(np.abs(in_se))) if np.any(np.isfinite(in_se)) else 0
    j = c.joints[worst]
    if c.reliable:
        note = (f"{c.method}: linearisation bias corrected (the compliances whose expected "
                f"linear fit is the one observed): largest on joint {j + 1}, the raw "
                f"compliance off by {in_se[worst]:+.2f} standard errors, k{j + 1} "
                f"{100 * k_change[worst]:+.2f} % from the raw {c.method} value; raw "
                "estimates in results.json linearisation_bias")
    else:
        note = (f"{c.method}: linearisation bias NOT corrected: {c.reason}; the raw estimate "
                "is kept, its interval widened by the estimated bias; use --method exact")
    return {
        "corrected": bool(c.reliable),
        "reliable": bool(c.reliable),
        "reason": c.reason or None,
        "raw_joint_stiffness_Nm_per_rad": per_joint(np.where(c.x_raw > 0, k_raw, np.nan)),
        "raw_standard_error_Nm_per_rad": per_joint(se_raw / c.x_raw ** 2),
        "corrected_joint_stiffness_Nm_per_rad": per_joint(
            np.where(c.x > 0, k, np.nan) if c.reliable else np.full(len(c.x), np.nan)),
        "bias_of_compliance_rad_per_Nm": per_joint(c.bias),
        "bias_in_standard_errors": per_joint(in_se),
        "relative_change_of_k": per_joint(k_change if c.reliable else np.full(len(c.x),
                                                                               np.nan)),
        "standard_error_ratio_corrected_to_raw": per_joint(se / se_raw),
        "contraction": None if not np.isfinite(c.contraction) else c.contraction,
        "contraction_limit": CONTRACTION_LIMIT,
        "criterion": ("reliable when ||S^-1 G (F - A) S||_2 <= "
                      f"{CONTRACTION_LIMIT:g} (S = diag(se)), the equilibrium solves at every "
                      "iterate and the steps converge"),
        "steps": c.steps,
        "note": note,
    }
