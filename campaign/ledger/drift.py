"""The drift statistics of a robot's campaigns: pure functions of numbers (no database).

Per joint j, campaign i against the reference r (the first comparable campaign,
or one chosen):

* d = ln k_i - ln k_r, with var(ln k) = var(x)/x^2 for the compliance x = 1/k
  (the delta method on the recorded covariance of x) and the two campaigns
  independent: s^2 = var_i + var_r;
* "dropped by more than m" (m = min change, a fraction): the one-sided test of
  H0: d >= ln(1 - m) against d < ln(1 - m), p = Phi((d - ln(1 - m)) / s); the
  six joints' p-values are Holm-adjusted, so the chance of any false alarm on a
  campaign is at most alpha; the alarm's upper bound of the change is
  exp(d + z s) - 1 at that joint's Holm level;
* the EWMA chart (NIST/SEMATECH e-Handbook 6.3.2.4) of the standardised changes
  z_i = (d_i - ln(1 - m)) / s_i of the comparable campaigns after the reference:
  E_i = lam z_i + (1 - lam) E_{i-1}, E_0 = 0. The z_i share the reference, so they
  are correlated (corr = var_r / (s_i s_j)); the control limit uses the exact
  variance of E_n, w^T C w, rather than the independent-case formula.

A campaign is comparable to the reference when it has the same estimator, joints
identified and model class, and was not accepted despite a refusal; the others
are marked with the reason and left out of both tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: EWMA smoothing constant and control-limit width (NIST e-Handbook 6.3.2.4's example)
EWMA_LAMBDA = 0.2
EWMA_L = 3.0


@dataclass(frozen=True)
class Campaign:
    """What the statistics need of one campaign (SI): six stiffnesses (N m/rad, NaN when
    not identified) and six variances of ln k (NaN when not identified)."""

    report_id: str
    date: str
    k: np.ndarray
    var_log_k: np.ndarray
    estimator: str
    joints: tuple[int, ...]
    model_class: str
    accepted_despite_refusal: bool = False


@dataclass(frozen=True)
class JointTest:
    """The one-sided test of one joint of one campaign against the reference.

    change: k_i/k_r - 1 (fraction); se_log: s; p: one-sided p-value; p_holm: the
    Holm-adjusted p-value; bound: the upper bound of the change (fraction) at the
    joint's Holm level; interval: (lo, hi) of the change at that level (two-sided
    with the same critical value, hi = bound); alarm: p_holm <= alpha."""

    joint: int
    change: float
    se_log: float
    z: float
    p: float
    p_holm: float
    bound: float
    interval: tuple[float, float]
    alarm: bool


def log_variance(k: np.ndarray, cov_x: np.ndarray, joints: tuple[int, ...]) -> np.ndarray:
    """var(ln k_j) = var(x_j) / x_j^2 for the identified (1-based) joints, NaN elsewhere;
    ``cov_x`` is over ``joints`` in their order."""
    out = np.full(6, np.nan)
    for pos, j in enumerate(joints):
        x = 1.0 / k[j - 1]
        out[j - 1] = cov_x[pos][pos] / x**2
    return out


def comparable_reason(c: Campaign, ref: Campaign) -> str | None:
    """Why ``c`` cannot be compared with the reference (None: it can)."""
    if c.accepted_despite_refusal:
        return "accepted despite a refusal (misfit_accepted)"
    if c.estimator != ref.estimator:
        return f"other estimator ({c.estimator!r}, reference {ref.estimator!r})"
    if tuple(c.joints) != tuple(ref.joints):
        return (f"other joints identified ({list(c.joints)}, reference "
                f"{list(ref.joints)})")
    if c.model_class != ref.model_class:
        return f"other model class ({c.model_class!r}, reference {ref.model_class!r})"
    return None


def holm(p: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values (monotone, capped at 1)."""
    p = np.asarray(p, float)
    order = np.argsort(p)
    m = len(p)
    adj = np.empty(m)
    running = 0.0
    for rank, idx in enumerate(order):
        running = max(running, (m - rank) * p[idx])
        adj[idx] = min(1.0, running)
    return adj


def one_sided_tests(c: Campaign, ref: Campaign, min_change: float,
                    alpha: float) -> list[JointTest]:
    """The joints of ``c`` tested against ``ref`` (see the module docstring)."""
    from scipy.stats import norm

    joints = [j for j in c.joints if j in ref.joints]
    d = np.array([math.log(c.k[j - 1] / ref.k[j - 1]) for j in joints])
    s = np.sqrt([c.var_log_k[j - 1] + ref.var_log_k[j - 1] for j in joints])
    t = math.log1p(-min_change)
    z = (d - t) / s
    p = norm.cdf(z)
    p_holm = holm(p)
    order = np.argsort(p)
    level = np.empty(len(joints))
    for rank, idx in enumerate(order):  # the Holm step's level of each joint
        level[idx] = alpha / (len(joints) - rank)
    out = []
    for i, j in enumerate(joints):
        zc = float(norm.isf(level[i]))
        lo, hi = math.expm1(d[i] - zc * s[i]), math.expm1(d[i] + zc * s[i])
        out.append(JointTest(j, math.expm1(d[i]), float(s[i]), float(z[i]), float(p[i]),
                             float(p_holm[i]), hi, (lo, hi), bool(p_holm[i] <= alpha)))
    return out


def ewma(z: np.ndarray, rho: np.ndarray, lam: float = EWMA_LAMBDA) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """(E_i, sd(E_i)) of the standardised changes ``z`` whose correlation matrix is ``rho``."""
    n = len(z)
    e = np.empty(n)
    sd = np.empty(n)
    prev = 0.0
    for i in range(n):
        prev = lam * z[i] + (1 - lam) * prev
        e[i] = prev
        w = lam * (1 - lam) ** (i - np.arange(i + 1))
        sd[i] = math.sqrt(float(w @ rho[: i + 1, : i + 1] @ w))
    return e, sd


def ewma_chart(series: list[Campaign], ref: Campaign, joint: int, min_change: float,
               lam: float = EWMA_LAMBDA, width: float = EWMA_L) -> dict:
    """The EWMA chart of one joint over ``series`` (comparable campaigns after the
    reference, oldest first): z, E, its lower control limit and whether the last point
    is below it."""
    j = joint - 1
    t = math.log1p(-min_change)
    d = np.array([math.log(c.k[j] / ref.k[j]) for c in series])
    v = np.array([c.var_log_k[j] for c in series])
    s = np.sqrt(v + ref.var_log_k[j])
    z = (d - t) / s
    rho = ref.var_log_k[j] / np.outer(s, s)
    np.fill_diagonal(rho, 1.0)
    e, sd = ewma(z, rho, lam)
    lcl = -width * sd
    return {"joint": joint, "z": z.tolist(), "ewma": e.tolist(), "lower_limit": lcl.tolist(),
            "alarm": bool(len(e) and e[-1] < lcl[-1])}
