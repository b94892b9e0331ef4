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
    if c.extras and not c.error:
        ho = c.heldout_chi2_nu
        doc["prediction_sigma_scale"] = float(np.sqrt(max(1.0, ho))) if np.isfinite(ho) \
            else None
        doc["prediction_sigma_scale_note"] = (
            "sqrt(max(1, held-out chi2/nu)) of the chosen class: a result kept with "
            "--accept-misfit widens its prediction intervals by this factor")
    out = replace(result, assumptions={**result.assumptions, "model_classes": doc})
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
