"""Fleet study: false-alarm rate and detection power of ``campaign history check``.

Fleets of robots are simulated at the precision of a real campaign on the simulated
lab: each campaign's ln k is drawn from a normal law around the lab's true
stiffness with the covariance that campaign's results.json reports
(cov(ln k) = diag(k) cov(x) diag(k) for the compliance x = 1/k, full, with the
joints' correlations), independently per campaign. The ledger's own statistics
(:mod:`campaign.ledger.drift`, as :func:`campaign.jobs.history.check_robot` calls
them) then test each campaign against the first.

* False alarms: no joint changes. At min change 0 (the null's boundary for every
  joint) the share of campaigns with an alarm from the one-sided bounds (Holm) is
  the per-campaign false-alarm rate, to compare with alpha; per joint, each joint's
  share (alpha/6 under Holm with six joints far from each other's p-values). The EWMA
  chart's share is reported beside it (it is a separate test).
* Power: joint ``--joint`` loses ``--drop`` at campaign ``--drop-at``: the share of
  fleets whose check at that campaign (the first after the drop) raises the alarm on
  that joint, at the default min change (5 %), and the share raising any other alarm.

The premise, that a campaign's reported covariance is its spread from one campaign to
the next, is checked on the simulated lab itself with ``--lab RUN...``: campaigns of
the same lab (same true stiffness, other seeds); the ratio of the sample variance of
ln k across them to the mean reported variance, per joint and pooled, with the 95 %
range of that ratio under the premise (chi-square).

Run: ``python -m campaign.ledger.fleet_study RUN_OR_RESULTS [--fleets 2000]
[--campaigns 4] [--drop-at 4] [--joint 2] [--drop 0.10] [--seed 1] [--lab RUN...]``; the
last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from campaign.ledger.drift import Campaign, ewma_chart, one_sided_tests

JOINTS = (1, 2, 3, 4, 5, 6)


def precision(results: Path) -> tuple[np.ndarray, np.ndarray]:
    """(k (6,), cov of ln k (6, 6)) of a campaign whose six joints were identified."""
    from analysis.identification.compare.load import load_campaign

    c = load_campaign(results)
    if tuple(c.joints) != tuple(range(6)):
        raise SystemExit(f"{results}: the study needs a campaign of all six joints")
    return c.k.copy(), c.cov_x * np.outer(c.k, c.k)


def _campaign(rid: str, log_k: np.ndarray, var: np.ndarray) -> Campaign:
    return Campaign(rid, rid, np.exp(log_k), var, "exact", JOINTS, "m")


def simulate(k_true: np.ndarray, cov_log: np.ndarray, fleets: int, campaigns: int,
             drop_at: int | None, joint: int, drop: float, min_change: float, alpha: float,
             seed: int) -> dict:
    """Alarm shares over ``fleets`` robots of ``campaigns`` campaigns each (see module)."""
    rng = np.random.default_rng(seed)
    var = np.diag(cov_log).copy()
    chol = np.linalg.cholesky(cov_log)
    bound_alarm = np.zeros((fleets, campaigns, 6), bool)
    ewma_alarm = np.zeros((fleets, campaigns, 6), bool)
    for f in range(fleets):
        log_k = np.log(k_true) + (chol @ rng.standard_normal((6, campaigns))).T
        if drop_at is not None:
            log_k[drop_at - 1:, joint - 1] += math.log1p(-drop)
        series = [_campaign(f"c{i}", log_k[i], var) for i in range(campaigns)]
        ref = series[0]
        for i in range(1, campaigns):
            for t in one_sided_tests(series[i], ref, min_change, alpha):
                bound_alarm[f, i, t.joint - 1] = t.alarm
            for j in JOINTS:
                ewma_alarm[f, i, j - 1] = ewma_chart(series[1:i + 1], ref, j, min_change)["alarm"]
    return {"bound": bound_alarm[:, 1:], "ewma": ewma_alarm[:, 1:]}


def _share(a: np.ndarray) -> float:
    return float(np.mean(a))


def _binomial_se(p: float, n: int) -> float:
    return math.sqrt(max(p * (1 - p), 1e-12) / n)


def study(results: Path, fleets: int = 2000, campaigns: int = 4, drop_at: int = 4,
          joint: int = 2, drop: float = 0.10, min_change: float = 0.05, alpha: float = 0.05,
          seed: int = 1) -> dict:
    """The study's figures (fractions) with their binomial standard errors."""
    k, cov_log = precision(Path(results))
    rel_se = np.sqrt(np.diag(cov_log))
    null = simulate(k, cov_log, fleets, campaigns, None, joint, 0.0, 0.0, alpha, seed)
    n_checks = fleets * (campaigns - 1)
    any_bound = _share(null["bound"].any(axis=2))
    per_joint = [_share(null["bound"][:, :, j]) for j in range(6)]
    any_ewma = _share(null["ewma"].any(axis=2))
    any_check = _share((null["bound"] | null["ewma"]).any(axis=2))
    worn = simulate(k, cov_log, fleets, campaigns, drop_at, joint, drop, min_change, alpha,
                    seed + 1)
    at = drop_at - 2  # index of campaign drop_at among the campaigns after the reference
    hit = worn["bound"][:, at, joint - 1]
    others = np.delete(worn["bound"][:, at] | worn["ewma"][:, at], joint - 1, axis=1)
    nodrop_default = simulate(k, cov_log, fleets, campaigns, None, joint, 0.0, min_change,
                              alpha, seed + 2)
    return {
        "study": "fleet", "results": str(results), "fleets": fleets, "campaigns": campaigns,
        "alpha": alpha, "relative_se_of_k": [float(v) for v in rel_se],
        "false_alarm": {
            "min_change_percent": 0.0, "checks": n_checks,
            "per_campaign_bound_holm": any_bound,
            "per_campaign_bound_holm_se": _binomial_se(any_bound, n_checks),
            "per_joint_bound_holm": per_joint,
            "per_campaign_ewma": any_ewma, "per_campaign_check": any_check,
            "expected_per_campaign_holm_independent": 1 - (1 - alpha / 6) ** 6},
        "false_alarm_at_min_change": {
            "min_change_percent": 100 * min_change,
            "per_campaign_check": _share((nodrop_default["bound"]
                                          | nodrop_default["ewma"]).any(axis=2))},
        "power": {"joint": joint, "drop_percent": 100 * drop, "campaign": drop_at,
                  "min_change_percent": 100 * min_change,
                  "flagged_at_first_campaign_after": _share(hit),
                  "other_alarm_at_that_campaign": _share(others.any(axis=1))},
    }


def lab_calibration(results: list[Path]) -> dict:
    """Sample variance of ln k over campaigns of one lab / mean reported variance, per joint
    and pooled, with the 95 % range of the ratio when the reported variances are right."""
    from scipy.stats import chi2

    logs, reported = [], []
    for path in results:
        k, cov_log = precision(path)
        logs.append(np.log(k))
        reported.append(np.diag(cov_log))
    n = len(results) - 1
    if n < 2:
        raise SystemExit("--lab needs at least three campaigns of the same lab")
    ratio = np.var(np.array(logs), axis=0, ddof=1) / np.mean(np.array(reported), axis=0)
    return {"campaigns": len(results), "variance_ratio_per_joint": ratio.tolist(),
            "ratio_range_95_per_joint": [chi2.ppf(0.025, n) / n, chi2.ppf(0.975, n) / n],
            "variance_ratio_pooled": float(ratio.mean()),
            "ratio_range_95_pooled": [chi2.ppf(0.025, 6 * n) / (6 * n),
                                      chi2.ppf(0.975, 6 * n) / (6 * n)]}


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("results", type=Path, help="a demo's run directory, analysis directory "
                   "or results.json (the precision of the simulated fleet)")
    p.add_argument("--fleets", type=int, default=2000)
    p.add_argument("--campaigns", type=int, default=4)
    p.add_argument("--drop-at", type=int, default=4)
    p.add_argument("--joint", type=int, default=2)
    p.add_argument("--drop", type=float, default=0.10)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--lab", type=Path, nargs="*", default=[], help="campaigns of the same "
                   "simulated lab (other seeds): check the reported variances")
    a = p.parse_args(argv)
    from campaign.ledger.entry import locate

    results, _ = locate(a.results)
    out = study(results, a.fleets, a.campaigns, a.drop_at, a.joint, a.drop, seed=a.seed)
    if a.lab:
        cal = lab_calibration([locate(r)[0] for r in a.lab])
        out["lab_calibration"] = cal
        lo, hi = cal["ratio_range_95_pooled"]
        print(f"lab: {cal['campaigns']} campaigns, variance of ln k across them / reported: "
              + ", ".join(f"{v:.2f}" for v in cal["variance_ratio_per_joint"])
              + f" (pooled {cal['variance_ratio_pooled']:.2f}, 95 % range {lo:.2f}-{hi:.2f})")
    fa, pw = out["false_alarm"], out["power"]
    print(f"false alarms at min change 0: {100 * fa['per_campaign_bound_holm']:.2f} % of "
          f"campaigns (one-sided bounds, Holm; alpha {100 * out['alpha']:g} %, "
          f"+-{100 * fa['per_campaign_bound_holm_se']:.2f} %), per joint "
          + ", ".join(f"{100 * v:.2f}" for v in fa["per_joint_bound_holm"]) + " %; "
          f"EWMA {100 * fa['per_campaign_ewma']:.2f} %")
    print(f"detection: joint {pw['joint']} -{pw['drop_percent']:g} % flagged at campaign "
          f"{pw['campaign']} in {100 * pw['flagged_at_first_campaign_after']:.1f} % of fleets "
          f"(min change {pw['min_change_percent']:g} %); another alarm there in "
          f"{100 * pw['other_alarm_at_that_campaign']:.2f} %")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
