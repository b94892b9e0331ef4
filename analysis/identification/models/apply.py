"""The model-class step of an analysis: fit the classes ``--model`` asks for on the tests
of a joint-spring result, record them side by side, and make the chosen class the result.

Called by the analyze job after the joint-spring identification. ``--model joints``
never comes here (today's result, unchanged). The chosen class's joint stiffness,
covariance, intervals and chi-square replace the joint fit's (so the refusal checks judge
the class); the residual table and the report's residual figures stay the joint fit's,
and a warning says so. The compensator's geometry is not in the robot files: the CLI
fits the stated k2(q2) law (:mod:`analysis.identification.models.fit`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from analysis.identification.models.fit import prepare
from analysis.identification.models.names import ModelChoice
from analysis.identification.models.select import Selection, select_model


def classes_of(result, robot, tests, noise, method: str, choice: ModelChoice,
               holdout_radius: float) -> Selection:
    """The classes ``choice`` asks for fitted on ``tests`` from the joint fit ``result``
    (``method`` the model whose residuals are the chi-square's), pose groups within
    ``holdout_radius`` (rad) held out together."""
    from analysis.identification.checks.misfit_causes import gear_torque_pair
    from analysis.identification.poses import pose_groups

    data = prepare(robot, tests, result.joints, result.x, noise, method,
                   gear_torque_pair(robot, tests), pose_groups(tests.q, holdout_radius))
    return select_model(data, choice)


def with_class(result, sel: Selection):
    """``result`` with the selection recorded (``assumptions.model_classes``) and, when the
    chosen class is not the joint springs, its joint stiffness, covariance, 95 % intervals
    and chi-square in place of the joint fit's."""
    doc = sel.describe()
    c = sel.chosen
    if not c.error:
        ho = c.heldout_chi2_nu
        doc["prediction_sigma_scale"] = float(np.sqrt(max(1.0, ho))) if np.isfinite(ho) \
            else None
        doc["prediction_sigma_scale_note"] = (
            "sqrt(max(1, held-out chi2/nu)) of the chosen class: a result kept with "
            "--accept-misfit widens its prediction intervals by this factor")
    out = replace(result, assumptions={**result.assumptions, "model_classes": doc},
                  warnings=(*result.warnings, *design_warnings(sel)))
    if not c.extras or c.error:
        return out
    cols = list(result.joints)
    p = len(cols)
    k = c.k
    se_x = np.sqrt(np.clip(np.diag(c.cov)[:p], 0.0, None))
    se_k = np.full(6, np.nan)
    se_k[cols] = se_x / c.x[cols] ** 2
    from scipy import special

    return replace(
        out, k=k, x=c.x, cov_x=c.cov[:p, :p], se_k=se_k, ci=c.k_ci,
        dof=c.dof, chi2_reduced=c.chi2_nu,
        p_value=float(special.chdtrc(c.dof, c.chi2)) if c.dof > 0 else float("nan"),
        warnings=(*out.warnings,
                  f"model class {c.name} chosen ({'--model auto' if sel.auto else '--model'}): "
                  "k, intervals and chi-square are its own; residuals.csv and the report's "
                  "residual figures are the joint-spring fit's"))


def design_warnings(sel: Selection) -> tuple[str, ...]:
    """What the campaign's design could not test: the untestable candidates ``auto`` set
    aside, or the class asked for when the design cannot test it."""
    bad = sel.untestable()
    if not bad:
        return ()
    size = sel.design
    if sel.chosen.untestable and not sel.auto:
        return (f"model class {sel.chosen.name} asked (--model) but this design cannot test "
                f"it: {sel.chosen.untestable}; its intervals assume the class is right and "
                "nothing here checks that. Plan with `campaign plan --model` (it raises the "
                "tests to what the class needs) or choose a smaller class",)
    return (f"--model auto: {len(bad)} class(es) not testable on this design "
            f"({size.tests} distinct tests, {size.equations} equations, "
            f"{size.equations_held_out} with a pose held out) set aside: "
            + "; ".join(f"{c.name} ({c.n_params} parameters)" for c in bad)
            + ". The evidence cannot support them; plan with `campaign plan --model` "
            "(it raises the tests to what the class needs) to test them",)


def widened(result):
    """A result kept with --accept-misfit: the chosen class's covariance, k intervals and
    standard errors (hence K_X's and the predictions' intervals) widened by
    ``prediction_sigma_scale`` = sqrt(max(1, held-out chi2/nu)), and a warning saying so;
    unchanged when nothing was refused or no class was fitted."""
    from analysis.identification.models.fit import Z95
    from analysis.identification.uncertainty import stiffness_interval

    rec = (result.assumptions or {}).get("model_classes") or {}
    s = rec.get("prediction_sigma_scale")
    if not result.misfit_accepted or not s or s <= 1.0:
        return result
    cols = list(result.joints)
    cov = result.cov_x * s**2
    ci = np.full((6, 2), np.nan)
    ci[cols] = stiffness_interval(result.x[cols], np.sqrt(np.diag(cov)), Z95)
    return replace(result, cov_x=cov, se_k=result.se_k * s, ci=ci, warnings=(
        *result.warnings,
        f"--accept-misfit: the intervals of k, K_X and the predicted deflections are widened "
        f"by {s:.3g} x, sqrt of the chosen class's held-out chi2/nu "
        f"({rec.get('chosen')}; assumptions.model_classes.prediction_sigma_scale)"))
