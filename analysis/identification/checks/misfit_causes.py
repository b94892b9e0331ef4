"""The cause tests (:mod:`analysis.identification.checks.causes`) of a result that misfits.

Runs the tests only when the joint-spring fit misfits (the chi-square test, or a robust
fit that down-weighted too much), on the components the outlier test did not flag when
they are a few glitches, records them in the result's ``assumptions["misfit_causes"]``
(results.json, the report) and, when no factor on the
F/T noise up to :data:`~analysis.identification.checks.causes.FT_FACTORS`' largest would
make the fit pass, replaces the noise check's advice to raise it.

The gear torques that decide each joint's flank come from the robot's mass model
(:mod:`analysis.model.gravity`) at the reference wrench (``w_ref`` of the tests when
the import gave one, else zero) and at the loaded one (``w + w_ref``: ``TestArrays.w``
is the wrench difference); the exact model's residuals and columns are those between the
two equilibria, as the fit's. Without a mass model the lost-motion alternative is
reported as not tested.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from analysis.identification.checks.causes import FT_FACTORS, LEVEL, CauseRanking, rank_causes
from analysis.identification.checks.plausibility import MAX_DOWN_WEIGHTED, MISFIT_P

#: the noise check's advice to raise the F/T noise (:mod:`.noise_check`) starts a note so
FT_ADVICE = "the F/T noise (it dominates the declared sigma"


def gear_torque_pair(robot, tests) -> tuple[np.ndarray, np.ndarray] | None:
    """(tau_ref, tau_load) (m, 6) (N m) each joint's transmitted torque at the reference
    reading (wrench ``tests.w_ref``, zero when None) and at the loaded one (``tests.w``
    is the wrench difference: w + w_ref), or None when the robot has no mass model."""
    if getattr(robot, "inertials", None) is None:
        return None
    from analysis.model.gravity import gear_torques

    w_ref = tests.w_ref
    w_ref = np.zeros_like(tests.w) if w_ref is None else np.nan_to_num(np.asarray(w_ref))
    return gear_torques(robot, tests.q, w_ref), gear_torques(robot, tests.q, tests.w + w_ref)


#: flagged components set aside only when they are few: at most this many, or this share
MAX_GLITCHES, GLITCH_SHARE = 3, 0.02


def without_outliers(result, tests):
    """``tests`` with the components the outlier test flagged (the residual table's
    ``outlier`` column) taken as not measured, when they are a few glitches (at most
    :data:`MAX_GLITCHES` or :data:`GLITCH_SHARE` of the components): a glitch is not
    evidence for any alternative (one 1 mm glitch in 1200 tests made the 35 link columns
    significant), while many flags are the systematic misfit itself."""
    res = result.residuals
    if res is None or not len(res) or "outlier" not in res or not res["outlier"].any():
        return tests
    from analysis.identification.io.columns import COMPONENTS

    flagged = res[res["outlier"].to_numpy(dtype=bool)]
    if len(flagged) > max(MAX_GLITCHES, GLITCH_SHARE * int(tests.measured.sum())):
        return tests  # not a few glitches: the misfit itself, which the causes must explain
    measured = tests.measured.copy()
    measured[flagged["test"].to_numpy(dtype=int),
             [COMPONENTS.index(str(c)) for c in flagged["component"]]] = False
    return replace(tests, measured=measured)


def misfits(result) -> bool:
    """Does the result fail the misfit test (or hide a misfit by a robust fit)?"""
    if result.dof > 0 and np.isfinite(result.p_value) and result.p_value < MISFIT_P:
        return True
    rob = result.robust
    return rob is not None and len(rob["down_weighted"]) > MAX_DOWN_WEIGHTED * result.n_equations


def causes_of_misfit(result, robot, tests, noise, method: str):
    """(ranking or None, result): the cause tests of a misfitting ``result`` recorded in it
    (``method``: the model whose residuals are the chi-square's, "exact" for a linear fit
    whose bias was corrected). None, and the result unchanged, when it fits; when joints
    were left out (their own misfit would be read as any alternative) the skip is recorded."""
    if not misfits(result):
        return None, result
    if len(result.joints) < 6:
        return None, replace(result, assumptions={
            **result.assumptions, "misfit_causes": {
                "skipped": "not all six joints identified: the rigid joints' own misfit would "
                           "show in every alternative"}})
    kept = without_outliers(result, tests)
    set_aside = int(tests.measured.sum() - kept.measured.sum())
    tests = kept
    torques = gear_torque_pair(robot, tests)
    why = "no mass model in the robot file (link masses and centres of mass): the gear " \
          "torques, and so each joint's flank, are unknown"
    ranking = rank_causes(robot, tests, result.joints, result.x, noise, method,
                          gear_torques=torques, no_torques_reason=why)
    ranking = replace(ranking, set_aside=set_aside)
    warnings = result.warnings
    if ranking.ft_factor is None:
        warnings = tuple(
            w.split(": " + FT_ADVICE)[0] + f": a larger F/T noise (up to {FT_FACTORS[-1]:g} x) "
            "would not make the fit pass, so it is not the cause; see the misfit's causes"
            if FT_ADVICE in w and "looks too small" in w else w for w in warnings)
    return ranking, replace(result, warnings=warnings, assumptions={
        **result.assumptions, "misfit_causes": ranking.describe()})


def ranked_causes_text(ranking: CauseRanking) -> tuple[list[str], str]:
    """(causes, tail): the significant tested causes, best first, each with its statistic,
    then the untestable ones; and a sentence on the tests that found nothing and the
    alternatives not tested."""
    named = [t.text() for t in ranking.named]
    fits = ranking.ft_factor
    noise = ("the noise figures (--translation-sigma-um, --rotation-sigma-urad, "
             "--force-sigma-N, --moment-sigma-Nm)"
             + (f": {fits:g} x the F/T noise would make the fit pass" if fits is not None
                else f": no F/T noise up to {FT_FACTORS[-1]:g} x the declared would make the "
                     "fit pass"))
    rest = ["a common units error of the wrench or the displacements, or the base-frame "
            "components' convention: not tested on the residuals"]
    conv = ranking.convention
    if conv is not None:
        named = [conv.text(), *named]
    else:
        rest.append("the pose sign convention (model vs controller joint angles): no "
                    "variant tried (the controller's angles, each joint reversed) makes "
                    "the fit pass")
    glitches = ([f"the {ranking.set_aside} outlier component(s) the outlier test flagged "
                 "(glitches: see its warning; the causes were tested without them)"]
                if ranking.set_aside else [])
    causes = [*named, *glitches, noise, *rest] if named else [*glitches, noise, *rest]
    quiet = [f"{t.cause.replace('_', ' ')} p = {t.p_value:.2g}" for t in ranking.tests
             if not t.significant]
    mimic = [f"{t.cause.replace('_', ' ')} p = {t.p_value:.2g} alone, p = {t.p_given:.2g} "
             f"beside {t.given.replace('_', ' ')}"
             + (" (the tool point is named only when it explains more than every other "
                "cause)" if t.cause == "tool_point" and t.p_given < LEVEL else "")
             for t in ranking.tests if t.significant and not t.beyond]
    tail = ""
    if mimic:
        tail += ("; significant alone but not named (no more than the first cause "
                 f"explains): {', '.join(mimic)}")
    if quiet:
        tail += f"; tested and not significant at {ranking_level()}: {', '.join(quiet)}"
    if ranking.not_tested:
        tail += "; not tested: " + "; ".join(f"{c.replace('_', ' ')} ({why})"
                                             for c, why in ranking.not_tested)
    return causes, tail


def ranking_level() -> str:
    from analysis.identification.checks.causes import LEVEL

    return f"the {LEVEL:g} level"
