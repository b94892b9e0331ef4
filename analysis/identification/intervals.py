"""The reported estimate and its intervals: the covariance scaled, the linear fits' bias
corrected (or added as a systematic term), the encoder noise's bias added, and the notes
that say so.

The interval formulas: :mod:`analysis.identification.uncertainty`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.errors import InputError
from analysis.identification.uncertainty import interval_critical_value, stiffness_interval
from analysis.text_format import level

#: the errors-in-variables corrections are a warning when they move some k by this many se
EIV_WARN_SE = 0.1


@dataclass(frozen=True)
class Intervals:
    """x (p,): the reported compliances (rad/(N m)): the exact or robust fit's, or for
    ols/wls the bias-corrected estimate where the correction is reliable, else the raw
    one; cov_x (p, p), se_x (p,): their covariance and standard errors (scaled by
    ``scale``, the reduced chi-square for covariance "residual", else 1); ci (p, 2): the
    stiffness interval (N m/rad); crit: its critical value; se_raw: the standard errors
    of the raw linear estimate (None for exact); linear_bias, encoder, wrench_eiv: the
    summaries of the corrections (results.json); notes: the warnings, in order."""

    x: np.ndarray
    cov_x: np.ndarray
    se_x: np.ndarray
    ci: np.ndarray
    crit: float
    scale: float
    se_raw: np.ndarray | None
    linear_bias: dict | None
    encoder: dict
    wrench_eiv: dict | None
    notes: tuple[str, ...]


def reported_intervals(problem, outcome, stats, corr) -> Intervals:
    """The intervals of ``outcome``'s fit with ``stats``
    (:class:`~analysis.identification.statistics.FitStatistics`); ``corr``: the
    linearisation-bias correction of a linear fit
    (:class:`~analysis.identification.corrections.linear_bias.BiasCorrection`) or None."""
    options, joints, chosen = problem.options, problem.joints, outcome.fit
    notes: list[str] = []
    scale = 1.0
    if options.covariance == "residual":
        if stats.dof <= 0:
            raise InputError("no residual degrees of freedom to estimate the variance",
                             where="covariance")
        scale = stats.chi2_reduced
    cov_x = stats.cov_x * scale
    robust_dof = None
    if outcome.robust is not None:
        # the M-estimator's sandwich with one noise scale per test (not scaled by the
        # chi-square), each joint's t by Satterthwaite
        # (analysis.identification.estimators.robust_covariance)
        robust_dof = outcome.robust.covariance.dof
        cov_x = outcome.robust.covariance.cov
    crit = interval_critical_value(options.confidence, options.covariance, stats.dof,
                                   robust_dof)
    se_x = np.sqrt(np.diag(cov_x))
    x_out = chosen.x  # the raw linear estimate for ols/wls (the outlier refits start there)
    bias = None
    se_raw = None
    # systematic terms added to the interval's half-width of x (rad/(N m))
    widen = np.zeros(len(joints))
    if corr is not None:
        from analysis.identification.corrections.linear_bias import summary

        se_raw = se_x
        if corr.reliable:
            x_out = corr.x
            cov_x = corr.propagation @ cov_x @ corr.propagation.T
            se_x = np.sqrt(np.diag(cov_x))
        else:  # the raw estimate, its interval widened by |b| where b is known
            widen += np.where(np.isfinite(corr.bias), np.abs(corr.bias), 0.0)
        bias = summary(corr, se_raw, se_x)
        notes.append(bias["note"])
    from analysis.identification.corrections import encoder_eiv

    tests, noise = problem.tests, problem.noise
    b_q = encoder_eiv.encoder_bias(problem.robot, tests, joints, x_out, noise)
    widen += np.abs(b_q)
    encoder = encoder_eiv.summary(joints, x_out, b_q, se_x, noise,
                                  min(tests.m, encoder_eiv.MAX_TESTS))
    if max(encoder["bias_in_standard_errors"][j] for j in joints) >= EIV_WARN_SE:
        notes.append(encoder["note"])
    ci = stiffness_interval(x_out, se_x + widen / crit, crit)
    eiv = None
    if chosen.eiv_shift is not None:
        from analysis.identification.corrections.wrench_eiv import shift_summary

        eiv = shift_summary(joints, chosen.x, chosen.eiv_shift, se_x, noise)
        # always in results.json and the printed assumptions; a warning only where it
        # moves k by a tenth of its standard error or more (large campaigns)
        if (eiv["max_abs_shift_in_se"] or 0.0) >= EIV_WARN_SE:
            notes.append(eiv["note"])
    if np.isfinite(stats.p_value) and stats.p_value < 1e-3:
        notes.append(f"reduced chi-square {stats.chi2_reduced:.3g} (p = {stats.p_value:.2g}):"
                     " residuals do not match the noise model; check the noise figures or "
                     "use covariance='residual'")
    for idx, j in enumerate(joints):
        if x_out[idx] - np.broadcast_to(crit, se_x.shape)[idx] * se_x[idx] <= 0:
            notes.append(f"joint {j + 1}: the {level(options.confidence)} interval of its "
                         "compliance reaches 0, the data do not bound k from above")
    return Intervals(x=x_out, cov_x=cov_x, se_x=se_x, ci=ci, crit=crit, scale=scale,
                     se_raw=se_raw, linear_bias=bias, encoder=encoder, wrench_eiv=eiv,
                     notes=tuple(notes))
