"""The result of an identification, and its files (results.json, residuals.csv)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.identification.io.measurements import COMPONENTS, TestArrays
from analysis.identification.noise import NoiseModel

CI_METHOD = (
    "interval of the compliance x = 1/k, x +- c se(x), mapped through 1/x "
    "(upper bound infinite when the x interval reaches 0); se(k) = se(x)/x^2 (delta method)"
)


@dataclass(frozen=True)
class FactoredEstimator:
    """x = G d with G = bread A^T W (W = Linv^T Linv per test, identity if Linv is None),
    applied to stacked vectors (6m,) block by block (never forming the p x 6m G)."""

    bread: np.ndarray
    A: np.ndarray
    Linv: np.ndarray | None = None
    block: int = 8_000

    @property
    def shape(self) -> tuple[int, int]:
        return (self.bread.shape[0], 6 * self.A.shape[0])

    def __matmul__(self, v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, dtype=float).reshape(self.A.shape[0], 6)
        acc = np.zeros(self.A.shape[-1])
        for s in range(0, self.A.shape[0], self.block):
            vb = v[s:s + self.block]
            if self.Linv is not None:
                Lb = self.Linv[s:s + self.block]
                vb = np.einsum("mji,mj->mi", Lb, np.einsum("mij,mj->mi", Lb, vb))
            acc += np.einsum("mrp,mr->p", self.A[s:s + self.block], vb)
        return self.bread @ acc


@dataclass
class Fit:
    """One estimator's output on per-test blocks (internal).

    x (p,) compliances (rad/(N m)); A (m, 6, p) model (or its Jacobian) per
    test; cov (m, 6, 6) residual covariance per test; predicted (m, 6) model
    displacement (m, rad). The linear(ised) estimator x = G d is kept in
    factored form, G = bread A^T W with W = Linv^T Linv per test (identity
    when ``Linv`` is None, OLS) and bread (p, p) = (A^T W A)^-1: memory
    linear in the number of tests (:mod:`analysis.identification.linalg.lsq` computes
    its covariance and residual variances blockwise). ``deflection`` (m, 6): the
    exact fit's joint deflections at x (rad), None for the linear fits. ``eiv_shift``
    (p,): how far the wrench errors-in-variables correction moved x
    (:mod:`analysis.identification.corrections.wrench_eiv`; None when not applied); ``bread`` is
    then the
    corrected (A^T W A - S)^-1. ``R`` (p + 1, p + 1): for a fit of one large campaign
    whose A and Linv are made when sliced (:mod:`analysis.identification.streaming.per_test`), the
    triangular factor of its final whitened system [Linv A | Linv r] at x - eiv_shift,
    else None. ``predicted_shifted`` False: ``predicted`` is still at x - eiv_shift (the
    caller moves it by A eiv_shift, :func:`analysis.identification.estimators.fitting.fit_exact`).
    """

    x: np.ndarray
    A: np.ndarray
    cov: np.ndarray
    predicted: np.ndarray
    iterations: int
    bread: np.ndarray
    Linv: np.ndarray | None = None
    deflection: np.ndarray | None = None
    eiv_shift: np.ndarray | None = None
    R: np.ndarray | None = None
    predicted_shifted: bool = True

    @property
    def estimator(self) -> FactoredEstimator:
        """G as an operator: ``fit.estimator @ v`` = G v for stacked v (6m,), blockwise."""
        return FactoredEstimator(self.bread, self.A, self.Linv)

    @property
    def G(self) -> np.ndarray:
        """The dense estimator matrix (p, 6m); for small campaigns and tests only."""
        WA = self.A if self.Linv is None else np.swapaxes(self.Linv, -1, -2) @ (
            self.Linv @ self.A)
        return self.bread @ WA.reshape(-1, WA.shape[-1]).T


@dataclass(frozen=True)
class ResidualRows:
    """The residual table held as per-test arrays, made into rows a block of tests at a time.

    ``tests`` the tests analysed; ``predicted``, ``sigma`` (model sigma of each
    component, or a :class:`~analysis.identification.streaming.per_test.PerTestSigma` made for the
    tests written; else
    component), ``t`` (studentized residual) (m, 6); ``flags`` (m, 6) bool, the residuals
    the fit set aside (the sequential outlier test's refits, or a robust fit's
    down-weighted ones): column ``set_aside``; ``threshold``: the stated outlier
    threshold, column ``outlier`` = |t| beyond it (so the ``outlier`` rows are exactly
    the residuals beyond the threshold, whatever the procedure set aside);
    ``weights`` (m, 6) robust weights or None. A 1e6-test campaign has 6e6 rows (~0.4 GB
    as a DataFrame): its full table is only ever made in blocks, for residuals.csv.
    """

    tests: TestArrays
    predicted: np.ndarray
    sigma: np.ndarray
    t: np.ndarray
    flags: np.ndarray
    weights: np.ndarray | None = None
    threshold: float = float("inf")

    def __post_init__(self) -> None:
        # pose labels as category codes and the categoricals' dtypes, once (every block of
        # rows uses them; a dtype made per block would check 1e5 categories each time)
        from analysis.identification.poses import factorize_labels

        codes, labels = factorize_labels(self.tests.pose)
        dtypes = {"pose": pd.CategoricalDtype(labels),
                  "component": pd.CategoricalDtype(COMPONENTS),
                  "unit": pd.CategoricalDtype(["m", "rad"])}
        object.__setattr__(self, "_pose_codes", (codes, dtypes))

    @property
    def n_rows(self) -> int:
        return int(self.tests.measured.sum())

    @property
    def n_tests(self) -> int:
        """Tests with at least one measured component (one row or more)."""
        return int(self.tests.measured.any(axis=1).sum())

    #: the columns of the table, in order
    COLUMNS = ("test", "line", "pose", "component", "unit", "measured", "predicted",
               "residual", "sigma", "studentized", "outlier", "set_aside")

    @property
    def names(self) -> list[str]:
        """The table's column names (``weight`` last for a robust fit)."""
        return [*self.COLUMNS, *(["weight"] if self.weights is not None else [])]

    def columns(self, which: np.ndarray | slice = slice(None)) -> dict:
        """Columns (arrays; text as categoricals) of the rows of the tests ``which`` (sorted
        indices or a slice): one per test and measured component, tests in order,
        components in order."""
        tests = self.tests
        idx = np.arange(tests.m)[which]
        meas = tests.measured[idx]
        k, c = np.nonzero(meas)  # row-major: by test, then component
        i = idx[k]
        # text columns as categoricals: millions of Python strings would take ~1 GB
        codes, dtypes = self._pose_codes
        measured = tests.d[i, c]
        predicted = self.predicted[i, c]
        out = {
            "test": i.astype(np.int64), "line": tests.line[i].astype(np.int64),
            "pose": pd.Categorical.from_codes(codes[i], dtype=dtypes["pose"]),
            "component": pd.Categorical.from_codes(c, dtype=dtypes["component"]),
            "unit": pd.Categorical.from_codes((c >= 3).astype(np.int8), dtype=dtypes["unit"]),
            "measured": measured, "predicted": predicted,
            "residual": measured - predicted, "sigma": (
                self.sigma[i, c] if isinstance(self.sigma, np.ndarray)
                else self.sigma.take(idx)[k, c]),  # made for these tests
            "studentized": self.t[i, c], "outlier": self.beyond(i, c),
            "set_aside": self.flags[i, c].astype(bool),
        }
        if self.weights is not None:
            out["weight"] = self.weights[i, c]
        return out

    def beyond(self, i, c) -> np.ndarray:
        """bool: |studentized residual| of rows (i, c) beyond :attr:`threshold` (NaN: no)."""
        with np.errstate(invalid="ignore"):
            return np.abs(self.t[i, c]) > self.threshold

    def n_beyond(self, block: int = 1 << 16) -> int:
        """Measured residuals with |studentized| beyond :attr:`threshold` (all rows)."""
        with np.errstate(invalid="ignore"):
            return int(sum(int(np.sum(self.tests.measured[s:s + block]
                                      & (np.abs(self.t[s:s + block]) > self.threshold)))
                           for s in range(0, self.tests.m, block)))

    def marked(self, rows=slice(None)) -> np.ndarray:
        """(m, 6) bool of the tests ``rows``: beyond the threshold or set aside."""
        with np.errstate(invalid="ignore"):
            return self.flags[rows] | (np.abs(self.t[rows]) > self.threshold)

    def frame(self, which: np.ndarray | slice = slice(None)) -> pd.DataFrame:
        """:meth:`columns` as a DataFrame."""
        return pd.DataFrame(self.columns(which))

    def blocks(self, block: int = 5_000):
        """The whole table as :meth:`columns` of ``block`` tests each, in order (blocks of
        ~30000 rows keep the writer's memory to ~25-50 MB)."""
        for s in range(0, self.tests.m, block):
            yield self.columns(slice(s, s + block))

    def frames(self, block: int = 80_000):
        """The whole table as DataFrames of ``block`` tests each, in order."""
        for s in range(0, self.tests.m, block):
            yield self.frame(slice(s, s + block))

    def key(self, rows=slice(None)) -> np.ndarray:
        """(m, 6) ranking of the rows (of the tests ``rows``): |studentized| (-1 if not
        finite), outliers first."""
        key = np.abs(self.t[rows])  # one array, edited in place
        key[~np.isfinite(key)] = -1.0
        key[self.marked(rows)] = np.inf
        key[~self.tests.measured[rows]] = -np.inf
        return key

    def worst_tests(self, rows: int, block: int = 1 << 16) -> np.ndarray:
        """Sorted indices of the tests holding the ``rows`` highest-ranked rows (outliers
        first, then largest |studentized|), and of those holding the ``rows`` largest
        |studentized| outliers. The ranking is made a block of tests at a time."""
        top = np.zeros(0, dtype=np.int64)
        for s in range(0, self.tests.m, block):
            key = self.key(slice(s, s + block)).reshape(-1)
            cand = np.concatenate([top, 6 * s + np.arange(key.size)])
            values = np.concatenate([self._flat_key(top), key])
            top = cand[_largest(values, rows)]
        out = np.flatnonzero((self.marked() & self.tests.measured).reshape(-1))
        t = np.abs(np.nan_to_num(self.t.reshape(-1)[out]))
        top_out = out[_largest(t, rows)]
        return np.unique(np.concatenate([top, top_out]) // 6)

    def _flat_key(self, flat: np.ndarray) -> np.ndarray:
        """The ranking key of the rows at flat indices ``flat`` (test * 6 + component)."""
        i, c = np.divmod(flat, 6)
        key = np.abs(self.t[i, c])
        key[~np.isfinite(key)] = -1.0
        key[self.flags[i, c] | self.beyond(i, c)] = np.inf
        key[~self.tests.measured[i, c]] = -np.inf
        return key

    def histogram(self, block: int = 1 << 16) -> dict:
        """results.json ``residual_histogram`` of every row (counted a block of tests at a
        time: the rows of 1e6 tests are 48 MB)."""
        parts = [_histogram(self.t[s:s + block][self.tests.measured[s:s + block]])
                 for s in range(0, self.tests.m, block)]
        out = parts[0]
        out["counts"] = np.sum([h["counts"] for h in parts], axis=0).tolist()
        out["not_finite"] = int(sum(h["not_finite"] for h in parts))
        return out


def _largest(values: np.ndarray, n: int, block: int = 1 << 18) -> np.ndarray:
    """Indices of the ``n`` largest of ``values`` (1-D), in no particular order, found
    block by block (an index array of every value would be 8 bytes per value)."""
    n = min(n, values.size)
    if n <= 0:
        return np.zeros(0, dtype=np.int64)
    keep = np.zeros(0, dtype=np.int64)
    for s in range(0, values.size, block):
        idx = np.concatenate([keep, np.arange(s, min(s + block, values.size))])
        if idx.size > n:
            idx = idx[np.argpartition(values[idx], idx.size - n)[idx.size - n:]]
        keep = idx
    return keep


@dataclass
class IdentificationResult:
    """Identified joint stiffness with its uncertainty and diagnostics (SI units).

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
    noise : the noise model used. warnings : messages for the user.
    outlier_threshold : |studentized residual| beyond which a residual is an
        outlier (Sidak-corrected for the number of residuals).
    assumptions : what the result rests on (tool point, noise figures and
        their source, method, ...), filled by the caller; results.json ``assumptions``.
    misfit_accepted : refusals of :mod:`analysis.identification.checks.plausibility`
        overridden by the user (``--accept-misfit``); empty when none.
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
    warnings: list[str] = field(default_factory=list)
    validation: pd.DataFrame | None = None
    outlier_threshold: float = float("nan")
    assumptions: dict = field(default_factory=dict)
    misfit_accepted: list[str] = field(default_factory=list)
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
              n_poses: int, outlier_threshold: float):
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
            warnings=list(warnings), outlier_threshold=float(outlier_threshold),
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
            "warnings": self.warnings,
            "tests_data": self.tests_data,
            **residual_summary(self.residuals, rows=self.residual_rows),
            **validation_summary(self.validation),
        }
        return out


#: results.json lists every held-out pose up to this many; beyond, the worst ones by
#: RMS error / sigma and a summary (every pose stays in validation.csv)
VALIDATION_LISTED = 200


def worst_poses(validation: pd.DataFrame, listed: int = VALIDATION_LISTED) -> pd.DataFrame:
    """The ``listed`` rows of ``validation`` of largest RMS error over the prediction's total
    uncertainty (or over sigma in a table without it; NaN, i.e. folds that could not be
    fitted, first), largest first; all rows in order when there are no more than
    ``listed``."""
    if len(validation) <= listed:
        return validation
    col = "rms_normalized_total" if "rms_normalized_total" in validation else "rms_normalized"
    key = validation[col].to_numpy(dtype=float)
    key = np.where(np.isfinite(key), key, np.inf)
    return validation.iloc[np.argsort(-key, kind="stable")[:listed]]


def validation_summary(validation: pd.DataFrame | None, listed: int = VALIDATION_LISTED) -> dict:
    """results.json entries for the leave-one-pose-out table: ``validation`` (rows; all of
    them up to ``listed`` poses, else the worst ``listed``), ``validation_listed`` (which)
    and ``validation_summary`` (pose count, folds not fitted, median and maximum RMS
    error / sigma, pooled RMS errors)."""
    if validation is None:
        return {"validation": None, "validation_listed": None, "validation_summary": None}
    norm = validation["rms_normalized"].to_numpy(dtype=float)
    n = validation["n_tests"].to_numpy(dtype=float)
    fitted = np.isfinite(norm)

    def pooled(col):  # RMS over the tests of the fitted folds (weights: tests per pose)
        v = validation[col].to_numpy(dtype=float)
        ok = fitted & np.isfinite(v)
        return float(np.sqrt(np.sum(n[ok] * v[ok] ** 2) / np.sum(n[ok]))) if ok.any() else None

    summary = {
        "n_poses": int(len(validation)),
        "folds_not_fitted": int((~fitted).sum()),
        "rms_normalized_median": float(np.median(norm[fitted])) if fitted.any() else None,
        "rms_normalized_max": float(np.max(norm[fitted])) if fitted.any() else None,
        "rms_translation_m_pooled": pooled("rms_translation_m"),
        "rms_rotation_rad_pooled": pooled("rms_rotation_rad"),
    }
    if "rms_normalized_total" in validation:
        from analysis.identification.validation.holdout_check import (
            HOLDOUT_FAMILY_LEVEL,
            LIMIT_TEXT,
        )

        tot = validation["rms_normalized_total"].to_numpy(dtype=float)
        ok = np.isfinite(tot)
        beyond = validation["beyond_limit"].to_numpy(dtype=bool)
        summary.update({
            "rms_normalized_total_median": float(np.median(tot[ok])) if ok.any() else None,
            "rms_normalized_total_max": float(np.max(tot[ok])) if ok.any() else None,
            "n_beyond_limit": int(beyond.sum()),
            "poses_beyond_limit": [str(v) for v in validation["held_out_pose"][beyond]][:100],
            "limit_family_level": HOLDOUT_FAMILY_LEVEL,
            "limit": LIMIT_TEXT,
        })
    rows = worst_poses(validation, listed)
    which = (f"all {len(validation)} held-out poses" if len(rows) == len(validation) else
             f"the {listed} of {len(validation)} held-out poses with the largest RMS error / "
             "total uncertainty (folds not fitted first); every pose is in validation.csv")
    return {"validation": _records(rows), "validation_listed": which,
            "validation_summary": summary}


#: results.json lists every residual up to this many rows; beyond, the largest
#: |studentized| ones and a histogram (all rows stay in residuals.csv)
RESIDUALS_LISTED = 1000
#: bin edges of the histogram of studentized residuals in results.json
HISTOGRAM_EDGES = np.array([-np.inf, -6, -5, -4, -3, -2, -1, 0, 1, 2, 3, 4, 5, 6, np.inf])


def _histogram(t: np.ndarray) -> dict:
    finite = np.isfinite(t)
    counts, _ = np.histogram(t[finite], HISTOGRAM_EDGES)
    edges = [None if not math.isfinite(e) else float(e) for e in HISTOGRAM_EDGES]
    return {"studentized_edges": edges, "counts": counts.tolist(),
            "not_finite": int((~finite).sum())}


def residual_summary(residuals: pd.DataFrame, listed: int = RESIDUALS_LISTED,
                     rows: ResidualRows | None = None) -> dict:
    """results.json entries for the residual table: ``residuals`` (rows), what they are,
    and a histogram of the studentized residuals.

    Up to ``listed`` rows every row is listed in table order; beyond, the
    ``listed`` rows of largest |studentized| (outliers first), largest first.
    ``rows``: the whole table when ``residuals`` holds only the rows of the worst tests
    (:class:`ResidualRows`); the histogram and the row count are then of every row.
    """
    t = residuals["studentized"].to_numpy(dtype=float)
    finite = np.isfinite(t)
    total = len(residuals) if rows is None else rows.n_rows
    out = {"residual_histogram": _histogram(t) if rows is None else rows.histogram()}
    if total <= listed:
        out["residuals_listed"] = f"all {len(residuals)} rows"
        out["residuals"] = _records(residuals)
        return out
    marked = residuals["outlier"].to_numpy(dtype=bool)
    if "set_aside" in residuals:
        marked = marked | residuals["set_aside"].to_numpy(dtype=bool)
    key = np.where(finite, np.abs(t), -1.0) + np.where(marked, np.inf, 0.0)
    top = np.argsort(-key, kind="stable")[:listed]
    out["residuals_listed"] = (f"the {listed} of {total} rows with the largest "
                               "|studentized| (outliers first); every row is in residuals.csv")
    out["residuals"] = _records(residuals.iloc[top])
    return out


def _records(frame: pd.DataFrame) -> list[dict]:
    out = []
    for rec in frame.to_dict(orient="records"):
        clean = {}
        for key, v in rec.items():
            if isinstance(v, (float, np.floating)):
                clean[key] = float(v) if math.isfinite(v) else None
            elif isinstance(v, (np.integer,)):
                clean[key] = int(v)
            elif isinstance(v, (np.bool_,)):
                clean[key] = bool(v)
            else:
                clean[key] = v
        out.append(clean)
    return out


def write_table(table, path: Path) -> None:
    """CSV of ``table`` (a DataFrame or a :class:`ResidualRows`): the bytes of pandas'
    ``to_csv(index=False)`` of the whole table (floats in numpy's shortest round-trip
    text, empty cells for NaN, True/False), written a block of rows at a time by
    :mod:`analysis.identification.io.table_csv` (a 1e6-test residual table, 6e6 rows,
    never exists as one DataFrame)."""
    from analysis.identification.io.table_csv import write_blocks, write_frame

    if isinstance(table, ResidualRows):
        write_blocks(path, table.names, table.blocks())
    else:
        write_frame(table, path)


def write_results(result: IdentificationResult, out_dir: str | Path) -> dict[str, Path]:
    """Write ``results.json``, ``residuals.csv`` (and ``validation.csv``) into ``out_dir``.

    Returns the paths written, by name.
    """
    from analysis.output_files import make_dir, write_text

    out = make_dir(out_dir)
    paths = {"results": out / "results.json", "residuals": out / "residuals.csv"}
    write_text(paths["results"], json.dumps(result.to_dict(), indent=2) + "\n")
    write_table(result.residuals if result.residual_rows is None else result.residual_rows,
                paths["residuals"])
    if result.validation is not None:
        paths["validation"] = out / "validation.csv"
        write_table(result.validation, paths["validation"])
    return paths
