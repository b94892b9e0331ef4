"""The ``robustness`` job: Monte-Carlo spread of the identified k against the number of tests
(the paper's Fig. 7); optionally writes robustness.csv/.png/.json."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.choices import LINEARISED_METHODS, METHODS
from analysis.errors import InputError
from campaign.jobs.analyze import DEFAULT_METHOD
from campaign.jobs.choices import Method, RotationSource
from campaign.jobs.option_checks import joint_stiffness, robot_and_tool, wrench

#: a mean further than this many Monte-Carlo standard errors from the truth is a bias
BIAS_SIGMAS = 4.0
#: most tests per simulated campaign
MAX_TESTS = 200


@dataclass(frozen=True)
class RobustnessOptions:
    """robot, tip, tool_xyz_mm / tool_rpy_deg: as the stiffness job's;
    joint_stiffness_Nm_per_rad: the true k (None: nominal); wrench_N_Nm: at P, base frame
    (None: the paper's w_eff); tests: numbers of tests; trials per number of tests;
    method: ols, wls or exact; seed; pool_size: poses drawn from the zones;
    min_dexterity: smallest 1/kappa_F of a drawn pose; noise overrides in SI (None: the
    defaults): translation_sigma_m, rotation_sigma_rad, rotation_source,
    reflector_radius_m, tracker_distance_m, force_sigma_N, moment_sigma_Nm,
    encoder_resolution_rad; out: directory of robustness.csv/.png/.json (None: none)."""

    robot: str
    tip: str | None = None
    tool_xyz_mm: Sequence[float] | None = None
    tool_rpy_deg: Sequence[float] | None = None
    joint_stiffness_Nm_per_rad: Sequence[float] | None = None
    wrench_N_Nm: Sequence[float] | None = None
    tests: Sequence[int] = tuple(range(1, 21))
    trials: int = 1000
    method: Method = Method(DEFAULT_METHOD)
    seed: int = 0
    pool_size: int = 2000
    min_dexterity: float = 0.2
    translation_sigma_m: float | None = None
    rotation_sigma_rad: float | None = None
    rotation_source: RotationSource | None = None
    reflector_radius_m: float | None = None
    tracker_distance_m: float | None = None
    force_sigma_N: float | None = None
    moment_sigma_Nm: float | None = None
    encoder_resolution_rad: float | None = None
    out: Path | None = None


#: the most poses drawn and simulated by one study (a pool holds about 100 bytes per pose
#: per number of tests: 1e6 poses stay within a few hundred MB)
MAX_POOL_SIZE = 1_000_000


def check(o: RobustnessOptions) -> list[int]:
    """The study's numbers of tests; InputError (naming the option) for trials, method or
    pool size out of their bounds (the command line's and the GUI's one check)."""
    counts = check_tests(o.tests)
    if o.trials < 2:
        raise InputError("need at least 2 trials", where="--trials")
    if str(o.method) not in METHODS:
        raise InputError(f"expected {', '.join(METHODS[:-1])} or {METHODS[-1]}, got "
                         f"{str(o.method)!r}", where="--method")
    if o.pool_size < 10:
        raise InputError("need at least 10 poses", where="--pool-size")
    if o.pool_size > MAX_POOL_SIZE:
        raise InputError(f"expected at most {MAX_POOL_SIZE} poses, got {o.pool_size}",
                         where="--pool-size")
    return counts


@dataclass
class RobustnessResult:
    """settings: robustness.json's document (SI units, noise in report units as labelled);
    table: one row per number of tests and joint (pandas DataFrame); files written."""

    settings: dict
    table: Any
    files: list[Path] = field(default_factory=list)

    def to_json(self) -> dict:
        """The document ``campaign robustness --json`` prints."""
        return {**self.settings, "results": self.table.to_dict(orient="records"),
                "files": [str(p) for p in self.files]}


def check_tests(counts: Sequence[int]) -> list[int]:
    """The numbers of tests, sorted and unique; refuse none, < 1 or > MAX_TESTS."""
    out = sorted({int(n) for n in counts})
    if not out or min(out) < 1:
        raise InputError("numbers of tests must be >= 1", where="--tests")
    if max(out) > MAX_TESTS:
        raise InputError(f"at most {MAX_TESTS} tests per campaign", where="--tests")
    return out


def noise_model(o: RobustnessOptions):
    """The default NoiseModel with the options' overrides (SI)."""
    from analysis.identification.noise import NoiseModel

    return NoiseModel().with_overrides(
        translation_sigma_override=o.translation_sigma_m,
        rotation_sigma_override=o.rotation_sigma_rad,
        rotation_source=None if o.rotation_source is None else str(o.rotation_source),
        reflector_radius=o.reflector_radius_m,
        tracker_distance=o.tracker_distance_m,
        force_sigma=o.force_sigma_N,
        moment_sigma=o.moment_sigma_Nm,
        encoder_resolution=o.encoder_resolution_rad,
    )


def bias_notes(summary, method: str) -> list[str]:
    """One sentence per joint whose Monte-Carlo mean is off the truth beyond its spread.

    Beyond its spread: ``|mean - k_true| > BIAS_SIGMAS * std / sqrt(trials)`` (the
    Monte-Carlo standard error of the mean) at every number of tests. The 1/x
    transformation explains a bias of about +(std/k)^2 (Jensen, second order);
    what is left is the estimator's own bias (for ols/wls: the linear model
    fitted to data from the nonlinear equilibrium).
    """
    notes = []
    for j, s in summary.groupby("joint"):
        good = s[s["trials"] - s["trials_rejected"] > 1]
        if good.empty:
            continue
        rel = good["mean_Nm_per_rad"] / good["k_true_Nm_per_rad"] - 1.0
        se = good["std_Nm_per_rad"] / np.sqrt(good["trials"] - good["trials_rejected"]) \
            / good["k_true_Nm_per_rad"]
        if not np.all(np.abs(rel) > BIAS_SIGMAS * se):
            continue
        jensen = float(np.median(good["relative_std"] ** 2))
        lo, hi = 100 * float(rel.min()), 100 * float(rel.max())
        cause = ("the linear model (eqs. 16-21) fitted to displacements from the nonlinear "
                 "equilibrium; --method exact removes it" if method in LINEARISED_METHODS
                 else "the nonlinear estimator at this noise (finite-sample bias)")
        span = f"{lo:+.2f} %" if f"{lo:+.2f}" == f"{hi:+.2f}" else f"{lo:+.2f} to {hi:+.2f} %"
        notes.append(
            f"k{j}: the mean is {span} from the true value at every number "
            f"of tests, beyond {BIAS_SIGMAS:g} Monte-Carlo standard errors; the 1/x "
            f"transformation explains about {100 * jensen:+.3f} % ((std/k)^2), the rest is "
            f"the bias of {cause}.")
    return notes


def method_note(method: str) -> str:
    """Which estimator the study uses, and whether that is the default of ``analyze``."""
    if method == "exact":
        return ("method: exact (Gauss-Newton on the nonlinear equilibrium), the default, as "
                "in campaign analyze")
    return (f"method: {method} (the linear model of the paper's eqs. 16-21"
            + (", its Fig. 7 study" if method == "ols" else "")
            + "), raw: without the linearisation-bias correction campaign analyze makes; "
            f"the default is {DEFAULT_METHOD}")


def linear_bias_note(summary, method: str) -> str | None:
    """For ols/wls: how far the mean is biased by the linear model, per joint, and why.

    The size is the mean over noise-free campaigns of the study's designs
    (``linearisation_bias_relative``), the median over the numbers of tests."""
    if method not in LINEARISED_METHODS:
        return None
    parts = []
    for j, s in summary.groupby("joint"):
        v = s["linearisation_bias_relative"].dropna()
        if len(v):
            parts.append(f"k{j} {100 * float(np.median(v)):+.2f} %")
    return (f"{method}: the mean is biased by the linearisation, the linear model A x fitted to "
            "finite displacements of the nonlinear equilibrium at this wrench (noise-free "
            f"campaigns of the same designs: {', '.join(parts)}); campaign analyze corrects "
            "this bias, --method exact has none")


def run(o: RobustnessOptions, progress: Callable[[int, int], None] | None = None,
        started: Callable[[int], Any] | None = None,
        note: Callable[[str], None] = lambda text: None) -> RobustnessResult:
    """Simulate and identify ``trials`` campaigns per number of tests; write ``out``.

    ``note(line)`` gets the wrench and true stiffness used, before the simulation.

    ``started(total)`` is called once with the number of identifications; it may
    return a context manager (e.g. the command line's progress bar) that stays open
    while they run, and ``progress(done, total)`` after each batch.
    """
    from contextlib import nullcontext

    from analysis.identification.studies.robustness import W_EFF, robustness_study
    from analysis.identification.studies.robustness_plot import plot_study

    method = str(o.method)
    r, _ = robot_and_tool(o.robot, o.tip, o.tool_xyz_mm, o.tool_rpy_deg)
    k = joint_stiffness(r, o.joint_stiffness_Nm_per_rad)
    w = wrench(o.wrench_N_Nm, W_EFF)
    counts = check(o)
    noise = noise_model(o)
    from analysis.report.formatting import k_kNm
    from campaign.numbers_text import vector_text

    w_source = "--wrench" if o.wrench_N_Nm is not None else (
        "default: the paper's w_eff (eq. 22); --wrench to choose another")
    note(f"wrench w = {vector_text(w[:3], 6, False)} N, "
         f"{vector_text(w[3:], 6, False)} N m at P, base frame ({w_source})")
    note(f"true joint stiffness [{', '.join(k_kNm(v) for v in k)}] kN "
         "m/rad (" + ("--joint-stiffness" if o.joint_stiffness_Nm_per_rad is not None else
                      "the robot model's") + ")")
    from analysis.kinetostatics.link_compliance import links_of

    if links_of(r):
        note("model class: the robot file carries link compliance (links "
             + ", ".join(str(lc.link) for lc in links_of(r)) + "); this study simulates "
             "and identifies the joint springs only (its spread is the joint fit's, not the "
             "class's)")
    total = o.trials * len(counts)
    done = [0]

    def advance(t: int) -> None:
        done[0] += t
        if progress is not None:
            progress(done[0], total)

    with (started(total) if started is not None else None) or nullcontext():
        summary = robustness_study(
            r, k, w, counts, o.trials, noise, method=method, seed=o.seed,
            pool_size=o.pool_size, min_inverse_condition=o.min_dexterity, progress=advance)
    notes = bias_notes(summary, method)
    lin = linear_bias_note(summary, method)
    if lin is not None:
        notes.insert(0, lin)
    settings = {
        "robot": r.name, "joint_stiffness_Nm_per_rad": k.tolist(),
        "wrench_N_Nm": w.tolist(), "wrench_source": w_source, "tests": counts,
        "trials": o.trials, "method": method, "method_note": method_note(method),
        "seed": o.seed, "pool_size": o.pool_size,
        "min_inverse_condition": o.min_dexterity, "noise": noise.describe(),
        "notes": notes,
    }
    written = []
    if o.out is not None:
        from analysis.output_files import make_dir, replacing, write_text

        out = Path(o.out)
        make_dir(out)
        with replacing(out / "robustness.csv") as tmp:
            summary.to_csv(tmp, index=False)
        nz = noise.describe()
        plot_study(summary, out / "robustness.png",
                   f"{r.name}: identified k against the number of tests ({method}, "
                   f"{o.trials} trials per point)",
                   f"noise per component: translation {nz['translation_sigma_um']:.3g} "
                   f"\u00b5m, rotation {nz['rotation_sigma_urad']:.3g} \u00b5rad, force "
                   f"{nz['force_sigma_N']:.3g} N, moment {nz['moment_sigma_Nm']:.3g} N m; "
                   "x at the top: not identifiable")
        write_text(out / "robustness.json", json.dumps(settings, indent=2) + "\n")
        written = [out / "robustness.csv", out / "robustness.png", out / "robustness.json"]
    return RobustnessResult(settings, summary, written)
