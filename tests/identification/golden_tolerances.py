"""How closely each number of the golden corpus must be reproduced: a tolerance by meaning.

The corpus's numbers come from floating-point arithmetic whose last digits depend on
the processor and the BLAS/LAPACK build (kernels, blocking, threads): on the KR240-2
cases k moves by up to ~1e-13 of itself between OpenBLAS's SkylakeX, Haswell (used on
AMD Zen), Sandybridge and Prescott kernels. A number that is a difference of nearly equal
ones (a bias, an errors-in-variables shift, a residual) keeps that absolute error, so its
*relative* change is much larger (6.8e-9 of a shift of 2.3e-8 of k). Each number is
therefore compared at 1e-9 of the scale of what it is computed from, in its own units:

* values (k, se, intervals, compliances, eigenvalues, inputs): relative 1e-9;
* differences expressed relative to k or in units of se (bias and shifts of k,
  relative changes): absolute 1e-9 in those units, i.e. 1e-9 of k or of the se;
* a bias of a compliance: absolute 1e-9 of that joint's compliance; an element of the
  compliance covariance: 1e-9 of sqrt(C_ii C_jj); an element of K_X (and of its se):
  1e-9 of sqrt(|K_ii K_jj|) of the same pose's matrix (the off-diagonal elements are
  differences of large terms, and their se can be zero in exact arithmetic);
* residuals and predictions (m, rad): absolute 1e-9 of the case's largest deflection D;
  residuals in units of their sigma (studentized, whitened, normalised rms, chi2,
  F, robust weights): absolute 1e-9 D / sigma (the row's sigma, else the case's
  smallest);
* lengths in mm (the tool-point check): absolute 1e-6 mm (1e-9 of the metre-scale links);
* probabilities: absolute 1e-9;
* counts, flags, indices, line numbers, iteration counts: exactly.

A key no rule names is an error (:func:`rule`): a new field of results.json gets its
meaning here before it is compared. A real change of the method moves k by far more
than the tolerance: the linearisation bias correction 0.01 % larger moves k by up to
1.5e-6 of itself on sim-ols (1500 times the tolerance, 1729 numbers fail), Huber's
weights of the down-weighted components 0.01 % larger by 1.9e-7 on glitch-exact-huber
(190 times, 1432 numbers fail); ``test_golden.py`` makes both changes.
"""

from __future__ import annotations

import math
import re

#: the tolerance of every value, relative; of every difference, in its own units
TOL = 1e-9
#: lengths in mm: 1e-9 of a metre
MM = 1e-6

EXACT = (
    r"n_tests|n_poses|n_equations|dof|iterations|joints_identified\[\]|confidence",
    r".*\.(n_tests|dof|clusters|steps|iterations|tests_used|not_finite|folds_not_fitted"
    r"|n_beyond_limit|n_poses|corrected|reliable|accepted|poses_held_out|beyond_limit"
    r"|line|test|outlier|set_aside)",
    r"residual_histogram\.counts\[\]",
    r"validation\[\]\.(n_tests|beyond_limit|poses_held_out)",
    r"residuals\[\]\.(line|test|outlier|set_aside)",
    r"robust\.down_weighted\[\]\.(line|test)",
    r"cartesian_stiffness\.poses\[\]\.line",
    r"assumptions\.misfit_causes\.(level|n_tests|outlier_components_set_aside"
    r"|ranked\[\]\.(dof\[\]|evidence_lines\[\]|significant|named)"
    r"|conventions\[\]\.(dof|explains))",
)
RELATIVE = (
    # the F/T noise factor that would make the fit pass (a root of chi2 in the factor)
    r"assumptions\.misfit_causes\.ft_noise_factor_that_passes",
    r"joint_stiffness_Nm_per_rad\[\]", r"standard_error_Nm_per_rad\[\]",
    r"ci95_Nm_per_rad\[\]\[\]", r"joint_compliance_rad_per_Nm\[\]",
    r"cartesian_stiffness\.joint_stiffness_Nm_per_rad\[\]",
    r"cartesian_stiffness\.poses\[\]\.(principal_rotational_Nm_per_rad|"
    r"principal_translational_N_per_m|q_rad|wrench_N_Nm)\[\]",
    r"linear_fits_Nm_per_rad\.(ols|wls)\[\]",
    r"linearisation_bias\.(corrected_joint_stiffness_Nm_per_rad|raw_joint_stiffness_Nm_per_rad"
    r"|raw_standard_error_Nm_per_rad|standard_error_ratio_corrected_to_raw)\[\]",
    r"linearisation_bias\.(contraction|contraction_limit)",
    r"(assumptions\.)?noise\.\w+", r"assumptions\.tool_point\.(rpy_deg|xyz_mm)\[\]",
    r"assumptions\.tool_point\.check\.k_moved_Nm_per_rad\[\]",
    r"assumptions\.tool_point\.check\.se_mm\[\]",
    r"condition_number(_weighted)?", r"outlier_threshold_studentized",
    r"encoder_errors_in_variables\.(joint_sigma_urad|added_to_interval)",
    r"wrench_errors_in_variables\.\w+_(sigma_N|sigma_Nm|percent)",
    r"residual_histogram\.studentized_edges\[\]", r"residuals\[\]\.(measured|sigma)",
    r"robust\.(constant|reported_below_weight|weight_tolerance)",
    r"robust\.covariance\.(degrees_of_freedom|se_over_fixed_weights"
    r"|se_over_uncorrected_sandwich)\[\]",
    r"validation\[\]\.limit_normalized_total", r"validation_summary\.limit_family_level",
)
#: differences relative to k, or in units of se: absolute TOL in those units
OWN_UNITS = (
    r"wrench_errors_in_variables\.(relative_shift_of_k\[\]|shift_of_k_in_se\[\]"
    r"|max_abs_shift_in_se)",
    r"encoder_errors_in_variables\.(bias_relative|bias_in_standard_errors)\[\]",
    r"linearisation_bias\.(relative_change_of_k|bias_in_standard_errors)\[\]",
    r"relative_change_vs_linear\.(ols|wls)\[\]",
)
PROBABILITY = (r"chi2_p_value", r"validation\[\]\.p_value_total",
               r"assumptions\.tool_point\.check\.p_value",
               r"assumptions\.misfit_causes\.ranked\[\]\.p_value(_given)?",
               r"assumptions\.misfit_causes\.conventions\[\]\.p_value_(alt|given)")
#: statistics of residuals in units of sigma: absolute TOL * D / (smallest sigma)
SIGMA_UNITS = (
    r"chi2_reduced", r"assumptions\.tool_point\.check\.F",
    # the cause tests' statistics: sums of squared whitened residuals and their
    # differences (F, the information criterion's change), in units of sigma
    r"assumptions\.misfit_causes\.ranked\[\]\.(F|bic_change|chi2|chi2_left)",
    r"assumptions\.misfit_causes\.conventions\[\]\.(chi2|chi2_alt)",
    r"validation\[\]\.(rms_normalized|rms_normalized_total)",
    r"validation_summary\.rms_normalized(_total)?_(max|median)",
    r"robust\.down_weighted\[\]\.(whitened_residual|weight)", r"residuals\[\]\.weight",
)
#: deflections (m, rad): absolute TOL * D
DEFLECTION = (r"residuals\[\]\.(predicted|residual)",
              r"validation\[\]\.rms_(translation_m|rotation_rad)",
              r"validation_summary\.rms_(translation_m|rotation_rad)_pooled")


def _any(patterns) -> re.Pattern:
    return re.compile("|".join(f"(?:{p})" for p in patterns))


_EXACT, _REL, _OWN = _any(EXACT), _any(RELATIVE), _any(OWN_UNITS)
_PROB, _SIGMA, _DEFL = _any(PROBABILITY), _any(SIGMA_UNITS), _any(DEFLECTION)
_INDEX = re.compile(r"\[(\d+)\]")


def scales(want: dict) -> dict:
    """The scales of a case, from its golden numbers (``want``, flattened): k and its
    compliance per joint, D (largest |measured| deflection of a residual row) and the
    smallest sigma of a row."""
    rows = [k for k in want if k.startswith("residuals[") and k.endswith(".measured")]
    if not rows:
        raise ValueError("golden case without residual rows: no deflection scale")
    deflection = max(abs(want[k]) for k in rows if want[k] is not None)
    sigma = min(want[k[: -len("measured")] + "sigma"] for k in rows)
    return {"D": deflection, "sigma": sigma}


def rule(key: str) -> str:
    """The name of the rule that compares ``key`` (a flattened results.json key)."""
    bare = _INDEX.sub("[]", key)
    for name, pattern in (("exact", _EXACT), ("relative", _REL), ("own-units", _OWN),
                          ("probability", _PROB), ("sigma-units", _SIGMA),
                          ("deflection", _DEFL)):
        if pattern.fullmatch(bare):
            return name
    if re.fullmatch(r"covariance_of_compliance\[\]\[\]", bare):
        return "covariance"
    if re.fullmatch(r"linearisation_bias\.bias_of_compliance_rad_per_Nm\[\]"
                    r"|encoder_errors_in_variables\.bias_of_compliance_rad_per_Nm\[\]", bare):
        return "compliance"
    if re.fullmatch(r"cartesian_stiffness\.poses\[\]\.K_X(_without_K_C)?(_se)?\[\]\[\]", bare):
        return "cartesian"
    if re.fullmatch(r"residuals\[\]\.studentized", bare):
        return "studentized"
    if re.fullmatch(r"assumptions\.tool_point\.check\.offset_mm\[\]", bare):
        return "length"
    raise KeyError(f"no tolerance for {key!r}: give it a rule in golden_tolerances.py")


def tolerance(key: str, want: dict, case_scales: dict) -> tuple[float, float] | None:
    """(relative, absolute) tolerance of ``key``; None: compared exactly. ``want`` the
    golden numbers of the case (the scales of an element are read from them)."""
    name = rule(key)
    idx = [int(i) for i in _INDEX.findall(key)]
    D, sigma = case_scales["D"], case_scales["sigma"]
    if name == "exact":
        return None
    if name == "relative":
        return TOL, 0.0
    if name in ("own-units", "probability"):
        return TOL, TOL
    if name == "sigma-units":
        return TOL, TOL * D / sigma
    if name == "deflection":
        return TOL, TOL * D
    if name == "studentized":
        return TOL, TOL * D / want[f"residuals[{idx[0]}].sigma"]
    if name == "length":
        return TOL, MM
    if name == "compliance":
        return TOL, TOL * abs(want[f"joint_compliance_rad_per_Nm[{idx[0]}]"])
    if name == "covariance":
        i, j = idx
        c = f"covariance_of_compliance[{i}][{i}]", f"covariance_of_compliance[{j}][{j}]"
        return TOL, TOL * math.sqrt(abs(want[c[0]] * want[c[1]]))
    if name == "cartesian":
        p, i, j = idx
        base = key.split("[")[0] + f"[{p}]." + key.split(".")[-1].split("[")[0]
        base = base.removesuffix("_se")  # the se of an element: in the matrix's units
        kk = want[f"{base}[{i}][{i}]"], want[f"{base}[{j}][{j}]"]
        return TOL, TOL * math.sqrt(abs(kk[0] * kk[1]))
    raise AssertionError(name)


def compare(want: dict, got: dict) -> list[str]:
    """Lines naming each number of ``got`` that differs from ``want`` (a golden case's
    flattened numbers) beyond its tolerance, or present on one side only."""
    case_scales = scales(want)
    out = []
    for key in sorted(set(want) | set(got)):
        if key not in got or key not in want:
            out.append(f"{key}: {'missing' if key not in got else 'new'}")
            continue
        a, b = want[key], got[key]
        if a is None or b is None or math.isnan(a) or math.isnan(b):
            same = (a is None and b is None) or (
                a is not None and b is not None and math.isnan(a) and math.isnan(b))
            if not same:
                out.append(f"{key}: golden {a}, now {b}")
            continue
        if a == b:
            continue
        tol = tolerance(key, want, case_scales)
        if tol is None:
            out.append(f"{key}: golden {a!r}, now {b!r} (compared exactly)")
            continue
        rtol, atol = tol
        if not abs(a - b) <= max(atol, rtol * max(abs(a), abs(b))):
            out.append(f"{key}: golden {a!r}, now {b!r} (|difference| {abs(a - b):.2e}, "
                       f"tolerance {max(atol, rtol * max(abs(a), abs(b))):.2e}, "
                       f"{rule(key)})")
    return out
