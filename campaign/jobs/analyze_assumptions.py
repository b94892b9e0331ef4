"""What an analysis rests on, in words: the analyze job's assumptions (results.json
``assumptions``, the terminal, the report) and the held-out validation's pose radius."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from campaign.jobs.analyze_input import AnalysisInput

#: each estimator in a sentence (results.json ``assumptions.method``)
METHOD_TEXT = {
    "ols": "ols: unweighted least squares on the linear model (the paper's eqs. 16-21)",
    "wls": "wls: linear model weighted by the measurement covariance",
    "exact": "exact: weighted Gauss-Newton on the nonlinear equilibrium",
}


def assumptions(inp: AnalysisInput, method: str, covariance: str, joints,
                robust: str = "none") -> dict:
    """What the analysis of ``inp`` (its noise with the options' overrides) rests on
    (results.json ``assumptions``, the terminal, the report); ``joints``: 0-based indices
    of the joints identified, None: the default set."""
    from analysis.identification.poses import POSE_TOLERANCE_SIGMAS, pose_tolerance
    from campaign.run_format.tests_meta import CONVENTIONS

    tool = inp.tool
    return {
        "robot": f"{inp.robot.name} ({inp.robot_source})",
        "tool_point": tool.describe(),
        "noise": {**inp.noise.describe(), "source": inp.noise_source},
        "method": METHOD_TEXT.get(method, method),
        "covariance": ("model: the noise figures are taken as known" if covariance == "model"
                       else "residual: scaled by the reduced chi-square"),
        "robust": ("none: the Gaussian fit" if robust == "none" else
                   f"{robust} IRLS on the residuals whitened by the noise model's sigma "
                   "(scale 1: the noise figures are taken as known)"),
        "joints": ("all six, or 1-3 when no rotation is measured" if joints is None
                   else ", ".join(str(j + 1) for j in joints) + " (others rigid)"),
        "wrench_errors_in_variables": ("bias of the F/T noise in the regressor, "
                                       "~(sigma_w/|w|)^2, corrected with the figures above"),
        "poses": (f"tests whose joint angles agree to within "
                  f"{np.degrees(pose_tolerance(inp.noise)):.2g} deg ({POSE_TOLERANCE_SIGMAS:g} "
                  "encoder sigmas) are at one pose"),
        "validation_folds": _folds_text(inp.protocol),
        "conventions": CONVENTIONS,
    }


def holdout_deg(protocol) -> tuple[float, str]:
    """Poses closer than this (deg) are held out together, and where that comes from."""
    from analysis.identification.validation.holdout_check import CLUSTER_DEG

    if protocol is not None:
        name = Path(protocol.path).name
        if "min_pose_separation_deg" in protocol.thresholds.model_fields_set:
            return (float(protocol.thresholds.min_pose_separation_deg),
                    f"protocol {name} [thresholds] min_pose_separation_deg")
        return (float(protocol.thresholds.min_pose_separation_deg),
                f"default: protocol {name} has no [thresholds] min_pose_separation_deg")
    return CLUSTER_DEG, "default, the planner's default minimum pose separation"


def _folds_text(protocol) -> str:
    deg, source = holdout_deg(protocol)
    return (f"held-out validation: poses within {deg:g} deg of each other (joint space) are "
            f"held out together ({source})")
