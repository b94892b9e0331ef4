"""Why an identification is refused: the reasons the data do not support its stiffness,
gathered in one place (misfit and its causes, implausible values, a tool point the
residuals contradict), and the result that records the checks.

The reasons are sentences; the caller raises them as
:class:`analysis.errors.Refused` (or writes the result with them, when told to accept a
misfit).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from analysis.identification.checks import tool_check
from analysis.identification.checks.misfit_causes import causes_of_misfit
from analysis.identification.checks.plausibility import problems
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.text_format import k_kNm


def refusal_reasons(result, robot, tests: TestArrays, noise: NoiseModel, method: str,
                    tool_source: str, release=lambda: None) -> tuple[list[str], object]:
    """(the reasons to refuse ``result``, the result with the checks recorded): the misfit's
    ranked causes (:mod:`~analysis.identification.checks.misfit_causes`), the plausibility
    problems against ``robot``'s nominal stiffness (N m/rad), then the tool-point F-test.
    ``method``: the estimator whose model the residuals are of; ``tool_source``: where the
    tool point comes from ("none given ..." when assumed at the flange); ``release()`` is
    called between the checks (the caller's freed-heap release)."""
    causes, result = causes_of_misfit(result, robot, tests, noise, method)
    refused = problems(result, robot.nominal_stiffness, causes=causes)
    release()
    tool_refusals, result = _tool_point(result, robot, tests, noise, method, tool_source)
    return [*refused, *tool_refusals], result


def _tool_point(result, robot, tests, noise, method: str, tool_source: str):
    """(refusals, result): the tool-point F-test
    (:mod:`analysis.identification.checks.tool_check`) as a refusal, if any, and the result
    that records it.

    Stored in ``assumptions.tool_point.check``; refused at P < 1e-3 when P was assumed
    (no tool point given anywhere), at P < 1e-6 when one was given; a warning below 0.01.
    """
    def checked(description: dict):
        tool_point = {**result.assumptions.get("tool_point", {}), "check": description}
        return replace(result, assumptions={**result.assumptions, "tool_point": tool_point})

    if len(result.joints) < 6:
        # joints taken rigid leave a misfit of their own (the wrist absorbed by k1..k3), which
        # the offset columns would partly explain: the test would accuse a right tool
        return [], checked({
            "skipped": "not all six joints identified: the rigid joints' own misfit would "
                       "show as a tool offset"})
    # the tests analysed (TestArrays: the text table is let go by then); the check takes
    # its own evenly spaced subset of a large campaign
    check = tool_check.tool_point_check(robot, tests, result.joints, result.x, noise, method)
    if check is None:
        return [], result
    result = checked(check.describe())
    assumed = tool_source.startswith("none given")
    limit = tool_check.P_ASSUMED if assumed else tool_check.P_GIVEN
    if check.p_value < limit:
        k = ", ".join("-" if not np.isfinite(v) else k_kNm(v) for v in check.k_moved)
        if assumed:
            return [f"a missing tool point: no tool point was given, P was taken at the flange "
                    f"centre, and {check.text()}; with P there k would be about [{k}] kN m/rad. "
                    "Give --tool-xyz-mm/--tool-rpy-deg (--tool-xyz-mm 0,0,0 if P really is "
                    "the flange centre)"], result
        return [f"wrong tool point? {check.text()}; with P there k would be about [{k}] kN m/rad. "
                f"Check the tool point ({tool_source})"], result
    if check.p_value < tool_check.P_WARN:
        result = replace(result, warnings=(
            *result.warnings, f"tool point: {check.text()} (not significant enough to refuse)"))
    return [], result
