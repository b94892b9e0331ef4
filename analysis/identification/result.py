"""The result of an identification (:class:`IdentificationResult`), as results.json has it;
the files are written by :mod:`analysis.identification.io.results_json`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from analysis.identification.io.measurements import TestArrays
from analysis.identification.io.residual_rows import ResidualRows
from analysis.identification.noise import NoiseModel

CI_METHOD = (
    "interval of the compliance x = 1/k, x +- c se(x), mapped through 1/x "
    "(upper bound infinite when the x interval reaches 0); se(k) = se(x)/x^2 (delta method)"
)


@dataclass(frozen=True)
class IdentificationResult:
    """Identified joint stiffness with its uncertainty and diagnostics (SI units).

    A frozen record: the stages after the identification (the analyze job's assumptions,
    warnings and refusals) make a new one with :func:`dataclasses.replace`.

    Attributes
    ----------
    robot, method : robot name; "ols", "wls" or "exact".
    joints : 0-based joints identified; the others are taken as rigid.
    k : (6,) joint stiffness (N m/rad), NaN for joints not identified.
    x : (6,) joint compliance (rad/(N m)), 0 for rigid joints.
    cov_x : (p, p) covariance of the identified compliances ((rad/(N m))^2).
    se_k : (6,) standard error of k by the delta method (N m/rad), NaN if not identified.
    ci : (6, 2) confidence interval of k (N m/rad); hi may be inf; NaN if not identified.
    confidence, covariance : interval level; "model" (known sigmas) or "residual".
    condition_number : of the column-scaled A of the linear model (eqs. 16-18).
    condition_number_weighted : of the column-scaled whitened system actually solved.
    n_tests, n_poses, n_equations, dof : sizes (equations = measured components).
    chi2_reduced, p_value : goodness of fit against the noise model.
    residuals : table, one row per test and measured component: test, line,
        pose, component, unit (m or rad), measured, predicted, residual, sigma,
        studentized, outlier (|t| beyond outlier_threshold), set_aside (the rows the
        sequential outlier test set aside, or a robust fit down-weighted).
    linear : {"ols": x (p,), "wls": x (p,)} linear-model compliances of the
        identified joints, for comparison (results.json: k per joint, 6 entries).
    change_vs_linear : {name: (6,) relative change of k, chosen vs that linear fit}.
    validation : leave-one-pose-out table (one row per held-out pose) or None.
    iterations : Gauss-Newton iterations (exact), 0 otherwise.
    noise : the noise model used. warnings : messages for the user (a tuple).
    outlier_threshold : |studentized residual| beyond which a residual is an
        outlier (Sidak-corrected for the number of residuals).
    assumptions : what the result rests on (tool point, noise figures and
        their source, method, ...), filled by the caller; results.json ``assumptions``.
    misfit_accepted : refusals of :mod:`analysis.identification.checks.plausibility`
        overridden by the user (``--accept-misfit``, a tuple); empty when none.
    residual_rows : None when ``residuals`` holds every row; for large campaigns
        (:data:`analysis.identification.checks.outliers.RESIDUAL_ROWS_HELD`) ``residuals`` holds
        only the rows of the tests with the largest |studentized| residuals (outliers
        first) and this holds the whole table as arrays (residuals.csv, histogram).
    robust : None for the Gaussian fit, else the robust fit's summary
        (:meth:`analysis.identification.estimators.irls.RobustFit.describe`: method, constant,
        iterations, down-weighted rows); results.json ``robust``.
    wrench_eiv : the correction for the wrench noise in the regressor
        (:func:`analysis.identification.corrections.wrench_eiv.shift_summary`), None when not
        applied;
        results.json ``wrench_errors_in_variables``.
    linear_bias : ols/wls only, the linearisation-bias correction
        (:func:`analysis.identification.corrections.linear_bias.summary`: raw and corrected k, the
        bias in standard errors, whether the correction is reliable); None for exact.
        results.json ``linearisation_bias``.
    encoder_eiv : the bias of the encoder noise in J, added to the intervals as a
        systematic term (:func:`analysis.identification.corrections.encoder_eiv.summary`);
        results.json ``encoder_errors_in_variables``.
    tests_data : fingerprint of the tests analysed
        (:func:`analysis.identification.io.data_fingerprint.fingerprint`), filled by the
        caller; results.json ``tests_data`` (``campaign compare`` refuses campaigns that
        share tests).
    pose_group : (m,) the pose index of each test
        (:func:`analysis.identification.poses.pose_groups`), for the writers that group
        the same tests (not written).
    """

    robot: str
    method: str
    joints: tuple[int, ...]
    k: np.ndarray
    x: np.ndarray
    cov_x: np.ndarray
    se_k: np.ndarray
    ci: np.ndarray
    confidence: float
    covariance: str
    condition_number: float
    condition_number_weighted: float
    n_tests: int
    n_poses: int
    n_equations: int
    dof: int
    chi2_reduced: float
    p_value: float
    residuals: pd.DataFrame
    linear: dict[str, np.ndarray]
    change_vs_linear: dict[str, np.ndarray]
    iterations: int
    noise: NoiseModel
    warnings: tuple[str, ...] = ()
    validation: pd.DataFrame | None = None
    outlier_threshold: float = float("nan")
    assumptions: dict = field(default_factory=dict)
    misfit_accepted: tuple[str, ...] = ()
    robust: dict | None = None
    residual_rows: ResidualRows | None = None
    wrench_eiv: dict | None = None
    linear_bias: dict | None = None
    encoder_eiv: dict | None = None
    tests_data: dict | None = None
    pose_group: np.ndarray | None = None

    @classmethod
    def build(cls, *, robot, method, joints, x, cov_x, ci, confidence, covariance,
              condition_number, condition_number_weighted, tests: TestArrays, n_equations,
              dof, chi2_reduced, p_value, residuals, linear, iterations, noise, warnings,
              n_poses: int, outlier_threshold: float, **rest):
        """The result of the fit's values on the identified joints (``x`` (p,), ``cov_x``,
        ``ci`` (p, 2)), spread over the six joints; ``rest``: the other fields as they
        are."""
        cols = list(joints)
        x_full = np.zeros(6)
        x_full[cols] = x
        k = np.full(6, np.nan)
        with np.errstate(divide="ignore"):
            k[cols] = np.where(x > 0, 1.0 / np.where(x > 0, x, 1.0), np.nan)
        se_x = np.sqrt(np.diag(cov_x))
        se_k = np.full(6, np.nan)
        se_k[cols] = np.where(x > 0, se_x / np.where(x > 0, x, 1.0) ** 2, np.nan)
        ci_full = np.full((6, 2), np.nan)
        ci_full[cols] = ci
        change = {}
        for name, xl in linear.items():
            c = np.full(6, np.nan)
            with np.errstate(divide="ignore", invalid="ignore"):
                c[cols] = xl / x - 1.0  # k_chosen / k_linear - 1
            change[name] = c
        return cls(
            robot=robot, method=method, joints=tuple(joints), k=k, x=x_full, cov_x=cov_x,
            se_k=se_k, ci=ci_full, confidence=confidence, covariance=covariance,
            condition_number=condition_number,
            condition_number_weighted=condition_number_weighted, n_tests=tests.m,
            n_poses=int(n_poses), n_equations=n_equations,
            dof=dof, chi2_reduced=chi2_reduced, p_value=p_value, residuals=residuals,
            linear=linear, change_vs_linear=change, iterations=iterations, noise=noise,
            warnings=tuple(warnings), outlier_threshold=float(outlier_threshold), **rest,
        )

    def _per_joint(self, values: list) -> list:
        """Values of the identified joints spread over 6 entries, None elsewhere."""
        out: list = [None] * 6
        for j, v in zip(self.joints, values, strict=True):
            out[j] = v
        return out

    def to_dict(self) -> dict:
        """JSON-ready dictionary (null for joints not identified; inf bounds as null)."""

        def num(v):
            v = float(v)
            return v if math.isfinite(v) else None

        ci = [None if np.isnan(self.ci[j, 0]) else [num(self.ci[j, 0]), num(self.ci[j, 1])]
              for j in range(6)]
        level = f"{100 * self.confidence:g}"
        out = {
            "assumptions": self.assumptions,
            "misfit_accepted": {"accepted": bool(self.misfit_accepted),
                                "problems": list(self.misfit_accepted)},
            "robot": self.robot,
            "method": self.method,
            "joints_identified": [j + 1 for j in self.joints],
            "joint_stiffness_Nm_per_rad": [num(v) for v in self.k],
            f"ci{level}_Nm_per_rad": ci,
            "standard_error_Nm_per_rad": [num(v) for v in self.se_k],
            "joint_compliance_rad_per_Nm": [num(v) for v in self.x],
            "covariance_of_compliance": self.cov_x.tolist(),
            "confidence": self.confidence,
            "ci_method": CI_METHOD,
            "covariance_source": self.covariance,
            "n_tests": self.n_tests,
            "n_poses": self.n_poses,
            "n_equations": self.n_equations,
            "dof": self.dof,
            "condition_number": num(self.condition_number),
            "condition_number_weighted": num(self.condition_number_weighted),
            "chi2_reduced": num(self.chi2_reduced),
            "chi2_p_value": num(self.p_value),
            "outlier_threshold_studentized": num(self.outlier_threshold),
            "iterations": self.iterations,
            "linear_fits_Nm_per_rad": {
                name: self._per_joint([num(1.0 / v) if v > 0 else None for v in xl])
                for name, xl in self.linear.items()
            },
            "relative_change_vs_linear": {
                name: [num(v) for v in c] for name, c in self.change_vs_linear.items()
            },
            "noise": self.noise.describe(),
            "robust": self.robust,
            "wrench_errors_in_variables": self.wrench_eiv,
            "linearisation_bias": self.linear_bias,
            "encoder_errors_in_variables": self.encoder_eiv,
            "warnings": list(self.warnings),
            "tests_data": self.tests_data,
            **_summaries(self),
        }
        return out


def _summaries(result: IdentificationResult) -> dict:
    """results.json's residual and validation summaries
    (:mod:`analysis.identification.io.results_json`)."""
    from analysis.identification.io.results_json import residual_summary, validation_summary

    return {**residual_summary(result.residuals, rows=result.residual_rows),
            **validation_summary(result.validation)}
