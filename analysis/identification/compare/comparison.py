"""Compare two identifications of the same robot: did the joint stiffness change?

Per joint identified in both campaigns A and B (independent measurements), with m the
number of joints compared and the level ``1 - alpha / m`` (Bonferroni):

* a z score computed on the compliances x = 1/k, whose estimates are the
  (near-normal) least-squares ones, signed as the change of k:
  ``z = (x_A - x_B) / sqrt(var_A + var_B)`` (x falls when k rises, so z > 0 means
  B is stiffer);
* a verdict "changed" when ``|z|`` exceeds the two-sided critical value ``z_c`` at
  ``alpha / m``, so that for two campaigns of an unchanged robot the probability of any
  "changed" verdict (the false-alarm rate) is at most ``alpha`` (default 5 %);
  otherwise "no evidence of change";
* the difference ``k_B - k_A`` (N m/rad) with its interval at the verdict's level,
  ``+- z_c sqrt(se_A^2 + se_B^2)`` (standard errors of k by the delta method), so an
  interval that excludes 0 and a "changed" verdict go together (up to the delta
  method's approximation; a row where they part says so).

Campaigns that share tests are not independent: A and B are refused when their
results.json ``tests_data`` fingerprints (:mod:`analysis.identification.io.data_fingerprint`)
share any test, or when their results are identical to the last digit.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.identification.compare.load import Campaign, load_campaign  # noqa: F401 (API)
from analysis.identification.io.data_fingerprint import shared_rows

ALPHA = 0.05


def _geometry(model: dict) -> dict:
    keys = ("convention", "length_unit", "angle_unit", "limits_convention")
    joints = [{k: v for k, v in j.items() if k != "stiffness"} for j in model.get("joints", [])]
    return {**{k: model.get(k) for k in keys}, "joints": joints, "tool": model.get("tool")}


def check_independent(a: Campaign, b: Campaign) -> list[str]:
    """Refuses A and B that share their data; returns notes on what could not be checked."""
    if Path(a.source).resolve() == Path(b.source).resolve():
        raise InputError("A and B are the same results file: a comparison needs two "
                         "independent campaigns", where=a.source)
    where = f"{a.source} vs {b.source}"
    da, db = a.tests_data, b.tests_data
    if da is not None and db is not None:
        if da["sha256"] == db["sha256"]:
            raise InputError("A and B were identified from the same tests (equal tests_data "
                             "sha256): a copy of one campaign, or its tests imported again, "
                             "is not an independent campaign", where=where)
        shared = shared_rows(da, db)
        if shared:
            raise InputError(f"A and B share tests ({shared} test row(s) with the same "
                             "joint angles, wrench and displacement in their tests_data): "
                             "campaigns that share data are not independent; compare "
                             "campaigns measured separately", where=where)
    if np.array_equal(a.k, b.k, equal_nan=True) and np.array_equal(a.cov_x, b.cov_x):
        raise InputError("A and B have identical stiffness and covariance to the last digit: "
                         "the same data analysed twice is not two independent campaigns",
                         where=where)
    notes = [f"{name}'s results.json has no tests_data (an older version): tests shared "
             "by A and B cannot be ruled out"
             for name, c in (("A", a), ("B", b)) if c.tests_data is None]
    return notes


def check_comparable(a: Campaign, b: Campaign) -> tuple[list[int], list[str]]:
    """(joints (0-based) identified in both, notes); refuses different robots or
    conventions and campaigns that share data (:func:`check_independent`)."""
    notes = check_independent(a, b)
    if a.robot != b.robot:
        raise InputError(f"different robots: {a.robot!r} ({a.source}) and {b.robot!r} "
                         f"({b.source})", where="campaign compare")
    if a.model is not None and b.model is not None:
        ga, gb = _geometry(a.model), _geometry(b.model)
        for key in ga:
            if ga[key] != gb[key]:
                raise InputError(f"the model files differ in {key} (conventions, geometry or "
                                 "tool): the stiffness values are not comparable",
                                 where=f"{a.source} vs {b.source}")
    common = sorted(set(a.joints) & set(b.joints))
    if not common:
        raise InputError("no joint identified in both campaigns", where="campaign compare")
    for c in (a, b):
        bad = [j + 1 for j in common if not (np.isfinite(c.x[j]) and c.cov_x[j, j] > 0)]
        if bad:
            raise InputError(f"joint(s) {bad} have no usable estimate or variance "
                             "(covariance_of_compliance diagonal)", where=c.source)
    return common, notes + _caveats(a, b)


def _joint_list(joints) -> str:
    return ", ".join(str(j + 1) for j in joints)


def _caveats(a: Campaign, b: Campaign) -> list[str]:
    """Notes on what makes a 'changed' verdict less than a change of the robot: different
    joint sets (a joint taken as rigid in one fit moves the others' estimates), different
    estimators, a result kept despite a refusal."""
    out = []
    if set(a.joints) != set(b.joints):
        only = sorted(set(a.joints) ^ set(b.joints))
        out.append(f"A identified joints {_joint_list(a.joints)}, B joints "
                   f"{_joint_list(b.joints)}: joint(s) {_joint_list(only)} are taken as rigid "
                   "in one fit, which moves the other joints' estimates when they are not; "
                   "a 'changed' verdict may be that model difference, not a change of the "
                   "robot (compare fits of the same joints)")
    if a.method is not None and b.method is not None and a.method != b.method:
        out.append(f"the estimators differ (A {a.method}, B {b.method}): each campaign's "
                   "interval is its own method's")
    for name, c in (("A", a), ("B", b)):
        if c.accepted:
            out.append(f"{name} was kept despite a refusal (--accept-misfit: results.json "
                       "misfit_accepted): its k and intervals are not supported by its data")
    return out


def critical_z(alpha: float, m: int) -> float:
    """Two-sided normal critical value at alpha / m (Bonferroni over m joints)."""
    from scipy import special  # norm.isf, without importing scipy.stats

    return float(-special.ndtri(alpha / (2 * m)))


def z_scores(x_a, var_a, x_b, var_b) -> np.ndarray:
    """z = (x_A - x_B) / sqrt(var_A + var_B), batched: a test on the compliances,
    signed as k_B - k_A (independent campaigns)."""
    return (np.asarray(x_a) - np.asarray(x_b)) / np.sqrt(np.asarray(var_a) + np.asarray(var_b))


def difference_intervals(x_a, var_a, x_b, var_b, zc: float):
    """(diff, half): k_B - k_A (N m/rad) and the half-width of its interval at critical
    value ``zc``, ``zc sqrt(se_A^2 + se_B^2)`` with se = sqrt(var) / x^2 (delta method);
    batched over compliances ``x`` (rad/(N m)) and their variances."""
    x_a, x_b = np.asarray(x_a, float), np.asarray(x_b, float)
    se_a = np.sqrt(np.asarray(var_a, float)) / x_a ** 2
    se_b = np.sqrt(np.asarray(var_b, float)) / x_b ** 2
    return 1.0 / x_b - 1.0 / x_a, zc * np.hypot(se_a, se_b)


def compare(a: Campaign, b: Campaign, alpha: float = ALPHA) -> dict:
    """Per-joint difference, interval at the verdict's level, z score and verdict
    (see the module docstring)."""
    if not (math.isfinite(alpha) and 0 < alpha < 1):
        raise InputError(f"expected 0 < alpha < 1, got {alpha:g}", where="--alpha")
    common, notes = check_comparable(a, b)
    m = len(common)
    zc = critical_z(alpha, m)
    level = 1 - alpha / m
    rows = []
    for j in common:
        z = float(z_scores(a.x[j], a.cov_x[j, j], b.x[j], b.cov_x[j, j]))
        _, half = difference_intervals(a.x[j], a.cov_x[j, j], b.x[j], b.cov_x[j, j], zc)
        half = float(half)
        diff = float(b.k[j] - a.k[j])  # the reported k themselves, not 1/x
        changed = abs(z) > zc
        row = {
            "joint": j + 1, "k_A_Nm_per_rad": float(a.k[j]), "k_B_Nm_per_rad": float(b.k[j]),
            "se_A_Nm_per_rad": math.sqrt(a.cov_x[j, j]) * a.k[j] ** 2,
            "se_B_Nm_per_rad": math.sqrt(b.cov_x[j, j]) * b.k[j] ** 2,
            "difference_Nm_per_rad": diff, "relative_difference": diff / float(a.k[j]),
            "interval_difference_Nm_per_rad": [diff - half, diff + half],
            "z": z, "verdict": "changed" if changed else "no evidence of change",
        }
        if changed != (abs(diff) > half):
            row["note"] = ("the interval (delta method on k) and the z test (on the "
                           "compliances) disagree at this level: a borderline case")
        rows.append(row)
    return {
        "robot": a.robot, "A": a.source, "B": b.source, "alpha": alpha,
        "critical_z": zc, "interval_level": level,
        "interval_level_text": _level_text(level, alpha, m), "joints": rows, "notes": notes,
        "method": "z on the compliances x = 1/k, z = (x_A - x_B)/sqrt(var_A + var_B) (signed "
                  "as k_B - k_A), independent campaigns; verdict 'changed' when |z| > "
                  f"critical_z, the two-sided normal quantile at alpha/{m} (Bonferroni), so "
                  f"the chance of any false alarm for an unchanged robot is at most "
                  f"{alpha:g}; difference interval at the same level ({100 * level:.4g} % "
                  "per joint): k_B - k_A +- critical_z sqrt(se_A^2 + se_B^2), se by the "
                  "delta method",
    }


def _level_text(level: float, alpha: float, m: int) -> str:
    return f"{100 * level:.4g} % (Bonferroni: 1 - alpha/{m}, alpha {alpha:g} over {m} joints)"


def level_text(result: dict) -> str:
    """'99.17 % (Bonferroni: 1 - alpha/6, alpha 0.05 over 6 joints)': the intervals' level."""
    return result["interval_level_text"]
