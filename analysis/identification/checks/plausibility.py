"""Checks that an identified stiffness is believable before anyone uses it.

Checks, each a refusal unless the user accepts the result anyway
(``campaign analyze --accept-misfit``):

* **misfit**: the reduced chi-square says the model does not explain the data,
  P(chi2 >= observed) < :data:`MISFIT_P` (the residuals are far larger than the
  noise figures);
* **too good**: P(chi2 <= observed) < :data:`MISFIT_P`, the residuals are far
  smaller than the noise figures allow: typically a consistent unit error
  (displacements typed in m instead of mm are 1000 x too small, and so is
  every residual) or noise figures far too large;
* **robust fit hiding a misfit**: a robust fit (``--robust``) down-weighted more
  than :data:`MAX_DOWN_WEIGHTED` of the components: that is not a few glitches
  but data the model does not explain, which down-weighting would hide from
  the chi-square;
* **robust interval without degrees of freedom**: a robust fit's covariance is
  estimated from its G tests' scores, and with no more tests than fitted joints
  (G - p <= 0) that estimate has no degrees of freedom left;
* **negative compliance**: an identified compliance x = 1/k is below zero by
  more than its interval half-width (the whole interval is negative): no
  joint pushes back, so the signs of the data disagree with the model, most
  often the wrench given as the reaction the sensor feels instead of the load
  applied to the robot;
* **linearisation bias not correctable** (``ols``, ``wls``): the correction of the
  linear model's bias is unreliable (:mod:`analysis.identification.corrections.linear_bias`), so
  the raw, biased estimate is all there is;
* **far from nominal**: an identified k differs from the robot model's nominal
  stiffness by more than :data:`NOMINAL_FACTOR` either way (only where the
  model has one): a unit error of the displacements or the wrench, or a
  wrong tool point, not a property of the robot.

Each message names the likely causes in order and the worst rows (input line
numbers), so the user can look at the data rather than at the code.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.result import IdentificationResult
from analysis.text_format import level

#: probability below which the chi-square test refuses (either tail)
MISFIT_P = 1e-6
#: largest believable ratio between an identified k and the model's nominal one
NOMINAL_FACTOR = 10.0
#: largest fraction of the components a robust fit may down-weight (Gaussian data: ~1 %)
MAX_DOWN_WEIGHTED = 0.1
#: number of rows named in a message
WORST_ROWS = 5

CAUSES_MISFIT = (
    "the tool point P (the displacements and wrench must be at the P given to the analysis: "
    "--tool-xyz-mm/--tool-rpy-deg or the protocol's [tool])",
    "units (q in deg, forces in N, moments in N m, displacements in mm, rotations in mrad)",
    "the pose sign convention (model vs controller joint angles, base-frame components)",
    "the noise figures (--translation-sigma-um, --rotation-sigma-urad, --force-sigma-N, "
    "--moment-sigma-Nm)",
)
#: first cause of a misfit of the translational-only variant (wrist taken as rigid)
CAUSE_RIGID_WRIST = (
    "the wrist joints 4-6 taken as rigid (no rotation measured: only k1..k3 are fitted); a "
    "compliant wrist under the loads' moments moves P too: identify it with --joints "
    "1,2,3,4,5 (joint 6 only if P is off its axis), measure rotations, or load with forces "
    "whose line passes near the wrist")
CAUSES_TOO_GOOD = (
    "units (displacements typed in m instead of mm, rotations in rad instead of mrad: "
    "1000 x too small)",
    "noise figures far larger than the instruments' (--translation-sigma-um, "
    "--rotation-sigma-urad, --force-sigma-N, --moment-sigma-Nm, protocol noise)",
    "data computed from a model rather than measured",
)
CAUSES_NEGATIVE = (
    "the sign of the wrench (it must be the load applied to the robot at P, not the reaction "
    "the F/T sensor feels: flip fx..mz if the sensor measures the reaction)",
    "the sign of the displacements (loaded minus unloaded, not the reverse)",
    "the tool point P or the frame of the wrench (base-frame components)",
)
CAUSES_NOMINAL = (
    "units (displacements in m instead of mm, forces in kN instead of N)",
    "the tool point P",
    "the robot model (another robot's file)",
)


def worst_rows(result: IdentificationResult, n: int = WORST_ROWS) -> str:
    """The n largest |studentized| residuals as 'line L (pose P) dz t = 5.1, ...'."""
    res = result.residuals
    if res is None or not len(res):
        return "no residuals"
    order = res["studentized"].abs().sort_values(ascending=False).index[:n]
    return ", ".join(f"line {int(r.line)} (pose {r.pose}) {r.component} t = {r.studentized:.2g}"
                     for r in res.loc[order].itertuples())


def _linear_bias_unreliable(result: IdentificationResult) -> bool:
    return result.linear_bias is not None and not result.linear_bias["reliable"]


def _misfit_causes(result: IdentificationResult, ranking=None) -> tuple[str, ...]:
    """CAUSES_MISFIT, led by the linear model when its bias correction was unreliable (the
    residuals are then the raw linear fit's) and by the rigid wrist when the fit is the
    translational-only variant, or by the joints taken as rigid when --joints left some out.
    With a :class:`~analysis.identification.checks.causes.CauseRanking` the tested causes
    replace CAUSES_MISFIT: the significant ones ranked by evidence, with their statistics
    (the tool point only when its own test is significant), then the untested ones."""
    first = []
    if _linear_bias_unreliable(result):
        first.append(f"the linear model of {result.method} at these loads (its residuals "
                     "hold the linearisation error: see the linearisation bias; --method "
                     "exact)")
    if any(w.startswith("translational-only variant") for w in result.warnings):
        first.append(CAUSE_RIGID_WRIST)
    elif len(result.joints) < len(result.k):
        rigid = ", ".join(str(j + 1) for j in range(len(result.k)) if j not in result.joints)
        first.append(
            f"joint(s) {rigid} taken as rigid (--joints): a compliant joint fitted as rigid "
            "moves P under load without the model seeing it; identify all of them (--joints "
            f"{','.join(str(j + 1) for j in range(len(result.k)))}) or the ones the data can")
    if ranking is not None:
        from analysis.identification.checks.misfit_causes import ranked_causes_text

        return (*first, *ranked_causes_text(ranking)[0])
    return (*first, *CAUSES_MISFIT)


def _untested_tail(ranking) -> str:
    """The cause tests that found nothing and those not run ('' without a ranking)."""
    if ranking is None:
        return ""
    from analysis.identification.checks.misfit_causes import ranked_causes_text

    return ranked_causes_text(ranking)[1]


def _causes(causes: tuple[str, ...]) -> str:
    return "; ".join(f"({i}) {c}" for i, c in enumerate(causes, start=1))


def chi2_lower_tail(result: IdentificationResult) -> float:
    """P(chi2 <= observed) of the fit (NaN without residual degrees of freedom)."""
    from scipy import special  # chi2.cdf, without importing scipy.stats

    if result.dof <= 0 or not np.isfinite(result.chi2_reduced):
        return float("nan")
    return float(special.chdtr(result.dof, result.chi2_reduced * result.dof))


def _negative_joints(result: IdentificationResult) -> list[str]:
    """'x3 = -1.1e-06 +- 2e-08 rad/(N m)' for each joint whose compliance interval is below 0,
    at the critical value of the result's own intervals (Student t for a robust fit or a
    residual-scaled covariance, as
    :func:`~analysis.identification.intervals.reported_intervals` chooses it)."""
    from analysis.identification.uncertainty import interval_critical_value

    robust_dof = ((result.robust or {}).get("covariance") or {}).get("degrees_of_freedom")
    crit = np.broadcast_to(interval_critical_value(result.confidence, result.covariance,
                                                   result.dof, robust_dof),
                           (len(result.joints),))
    se = np.sqrt(np.clip(np.diag(result.cov_x), 0.0, None))
    out = []
    for idx, j in enumerate(result.joints):
        x, half = float(result.x[j]), float(crit[idx] * se[idx])
        if x + half < 0.0:
            out.append(f"x{j + 1} = 1/k{j + 1} = {x:.3g} +- {half:.2g} rad/(N m)")
    return out


def problems(result: IdentificationResult, nominal: np.ndarray | None,
             nominal_label: str = "nominal stiffness of the robot model",
             causes=None) -> list[str]:
    """Messages of every failed check (empty when the result is believable).

    ``causes``: the cause tests of a misfit
    (:func:`analysis.identification.checks.misfit_causes.causes_of_misfit`), which then
    rank the misfit's likely causes by their evidence; None: the fixed list."""
    out = []
    chi2 = f"reduced chi-square {result.chi2_reduced:.3g} with {result.dof} degrees of freedom"
    if result.dof > 0 and np.isfinite(result.p_value) and result.p_value < MISFIT_P:
        out.append(
            f"misfit: the model does not explain the data ({chi2}, P(chi2 >= observed) = "
            f"{result.p_value:.2g} < {MISFIT_P:g}); likely causes, most likely first: "
            f"{_causes(_misfit_causes(result, causes))}{_untested_tail(causes)}; worst rows: "
            f"{worst_rows(result)}")
    rob = result.robust
    if rob is not None and len(rob["down_weighted"]) > MAX_DOWN_WEIGHTED * result.n_equations:
        out.append(
            f"misfit hidden by the robust fit: {rob['method']} down-weighted "
            f"{len(rob['down_weighted'])} of {result.n_equations} components below weight "
            f"{rob['reported_below_weight']:g} (more than {level(MAX_DOWN_WEIGHTED)}; glitches are "
            f"a few rows); likely causes, most likely first: "
            f"{_causes(CAUSES_MISFIT if causes is None else _misfit_causes(result, causes))}"
            f"{_untested_tail(causes)}; worst rows: {worst_rows(result)}")
    clusters = ((rob or {}).get("covariance") or {}).get("clusters")
    if clusters is not None:
        g, p = int(clusters), len(result.joints)
        if g <= p:
            out.append(
                f"too few tests for the robust fit's interval: its covariance scales each "
                f"test's noise by that test's own residuals, and G = {g} tests for p = {p} "
                f"fitted joints leave them too few degrees of freedom (G - p = {g - p}; at "
                f"least {p + 1} tests are needed, many more for a stable standard error); "
                "likely causes: (1) a campaign too small for "
                "--robust: measure more tests, or use the Gaussian fit (--robust none), "
                "whose interval rests on the noise figures")
    low = chi2_lower_tail(result)
    if np.isfinite(low) and low < MISFIT_P:
        out.append(
            f"too good to be true: the residuals are far smaller than the noise figures "
            f"({chi2}, P(chi2 <= observed) = {low:.2g} < {MISFIT_P:g}); likely causes: "
            f"{_causes(CAUSES_TOO_GOOD)}")
    if _linear_bias_unreliable(result):
        # first: the residuals of a raw linear fit carry the linearisation error, so this
        # also explains a misfit reported with it
        out.insert(0,
            f"linearisation bias: {result.method} is biased by the linear model at these "
            f"loads and the correction is unreliable ({result.linear_bias['reason']}); use "
            "--method exact (the nonlinear equilibrium fit)")
    negative = _negative_joints(result)
    if negative:
        out.append(
            f"negative stiffness: {'; '.join(negative)} (the whole {level(result.confidence)} "
            f"interval of the compliance is below zero); likely causes, most likely first: "
            f"{_causes(CAUSES_NEGATIVE)}")
    if nominal is not None:
        nominal = np.asarray(nominal, dtype=float)
        far = []
        for j in result.joints:
            k, k0 = result.k[j], nominal[j]
            if not (np.isfinite(k) and np.isfinite(k0) and k0 > 0 and k > 0):
                continue
            ratio = k / k0
            if ratio > NOMINAL_FACTOR or ratio < 1.0 / NOMINAL_FACTOR:
                far.append(f"k{j + 1} = {k:.3g} N m/rad is {ratio:.3g} x the {nominal_label} "
                           f"{k0:.3g}")
        if far:
            out.append(
                f"implausible stiffness: {'; '.join(far)} (more than {NOMINAL_FACTOR:g} x "
                f"either way); likely causes: {_causes(CAUSES_NOMINAL)}")
    return out
