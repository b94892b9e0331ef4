"""Checks of one measured test: repeatability, drift, wrench against the plan, tracker, saturation.

Each check compares a number with a limit derived from the protocol's
instrument noise; a failed check names a flag of ``tests.csv``
(``docs/run_format.md``). The runner retries a flagged test once and then
records it as ``failed`` with its flags, never as ``ok``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from campaign.protocol import Protocol

FLAGS = ("drift", "repeatability", "saturation", "wrench_mismatch", "tracker_uncertainty",
         "retried")


@dataclass(frozen=True)
class Limits:
    """Limits of the checks (SI).

    Attributes
    ----------
    repeatability : float
        Largest distance (m) between the unloaded poses before and after the load.
    drift : float
        Largest distance (m) between this repeat's unloaded pose and the first repeat's.
    wrench_abs, wrench_rel : float
        Largest force error (N) against the plan: ``wrench_abs + wrench_rel * |f_plan|``.
    tracker : float
        Largest RMS residual (m) of the rigid fit over the reflectors.
    force_range, moment_range : float or None
        Sensor range (N, N m); a reading at 98 % of it or more is saturated.
    """

    repeatability: float
    drift: float
    wrench_abs: float
    wrench_rel: float
    tracker: float
    force_range: float | None = None
    moment_range: float | None = None


def limits_for(protocol: Protocol) -> Limits:
    """Limits from the protocol's noise figures (one sigma per component).

    Repeatability: 12 sigma of a tracker coordinate (a difference of two
    poses, three components, rarely above 6 sigma from noise alone); drift:
    20 sigma; wrench: 5 % of the planned force plus 10 sigma of the sensor;
    tracker fit residual: 4 sigma. Sensor ranges come from the force sensor's
    ``options.range_N`` and ``options.range_N_m`` when given.
    """
    pose_noise = protocol.instruments["pose"].noise
    sigma_t = (pose_noise.translation_um or 30.0) * 1e-6
    ft = protocol.instruments.get("force_torque")
    sigma_f = (ft.noise.force_N if ft is not None and ft.noise.force_N else 1.0)
    opts = ft.options if ft is not None else {}
    return Limits(repeatability=max(12 * sigma_t, 10e-6), drift=max(20 * sigma_t, 20e-6),
                  wrench_abs=10 * sigma_f, wrench_rel=0.05, tracker=max(4 * sigma_t, 5e-6),
                  force_range=_opt(opts, "range_N"), moment_range=_opt(opts, "range_N_m"))


def _opt(options: dict, key: str) -> float | None:
    value = options.get(key)
    return float(value) if isinstance(value, (int, float)) and value > 0 else None


@dataclass(frozen=True)
class CheckResult:
    """Numbers and flags of one measured test (m, N)."""

    repeatability: float
    drift: float
    wrench_error: float
    tracker_sigma: float
    flags: tuple[str, ...]


def evaluate(limits: Limits, p_before: np.ndarray, p_after: np.ndarray,
             p_first: np.ndarray | None, wrench_base: np.ndarray, wrench_plan: np.ndarray,
             wrench_sensor: np.ndarray, residuals: list[float | None]) -> CheckResult:
    """Run every check on one test.

    Parameters
    ----------
    p_before, p_after : (3,) unloaded tool point before and after the load (m, tracker frame).
    p_first : (3,) unloaded tool point of the first repeat of this test, or None.
    wrench_base, wrench_plan : (6,) measured and planned wrench, base frame (N, N m).
    wrench_sensor : (6,) measured wrench in the sensor frame (N, N m), for saturation.
    residuals : RMS residuals (m) of the pose fits (None where the tracker gives none).
    """
    flags = []
    rep = float(np.linalg.norm(np.asarray(p_after) - np.asarray(p_before)))
    if not rep <= limits.repeatability:
        flags.append("repeatability")
    drift = float("nan")
    if p_first is not None:
        drift = float(np.linalg.norm(np.asarray(p_before) - np.asarray(p_first)))
        if not drift <= limits.drift:
            flags.append("drift")
    f_plan = float(np.linalg.norm(wrench_plan[:3]))
    err = float(np.linalg.norm(np.asarray(wrench_base[:3]) - np.asarray(wrench_plan[:3])))
    if not err <= limits.wrench_abs + limits.wrench_rel * f_plan:
        flags.append("wrench_mismatch")
    res = [r for r in residuals if r is not None]
    sigma = float(max(res)) if res else float("nan")
    if res and not sigma <= limits.tracker:
        flags.append("tracker_uncertainty")
    ws = np.abs(np.asarray(wrench_sensor, dtype=float))
    if (limits.force_range and np.any(ws[:3] >= 0.98 * limits.force_range)) or \
            (limits.moment_range and np.any(ws[3:] >= 0.98 * limits.moment_range)):
        flags.append("saturation")
    return CheckResult(rep, drift, err, sigma, tuple(flags))
