"""The identification's results on the golden corpus are those committed in ``golden/``.

Every case of :data:`tests.identification.golden.CASES` (the walk-through run, each
method, each robust mode, outliers, a tool point, translations only, residual-scaled
covariance, poses held out together, the streamed 1200-test campaign) is analysed by the
analyze job, and every number of its results.json is compared to the golden file's.

Tolerance: relative 1e-12 of the larger magnitude, absolute 1e-300 near zero (a
restructuring keeps the order of the arithmetic; 1e-12 leaves room only for rounding).
A deliberate change of the numbers regenerates the files
(``python -m tests.identification.golden --write tests/identification/golden``, from the
tree that made the change) and says so in its commit message.
"""

from __future__ import annotations

import pytest

from tests.identification import golden

RTOL = 1e-12
ATOL = 1e-300


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("golden")


def test_every_case_has_a_golden_file():
    names = {c.name for c in golden.CASES}
    files = {p.stem for p in golden.GOLDEN_DIR.glob("*.json")}
    assert names == files


@pytest.mark.parametrize("case", golden.CASES, ids=[c.name for c in golden.CASES])
def test_results_equal_the_golden_files(case, workdir):
    want = golden.golden_numbers(case)
    got = golden.case_numbers(case, workdir)
    assert len(want) > 500  # the whole results.json, not a stub
    diff = golden.differences(want, got, RTOL, ATOL)
    assert not diff, f"{len(diff)} of {len(want)} numbers differ:\n" + "\n".join(diff[:20])


def test_the_comparison_fails_on_a_changed_number():
    want = {"k[0]": 1.0e6, "k[1]": 2.0e-300, "n": None}
    assert golden.differences(want, dict(want), RTOL, ATOL) == []
    assert golden.differences(want, {**want, "k[0]": 1.0e6 * (1 + 3e-12)}, RTOL, ATOL)
    assert not golden.differences(want, {**want, "k[0]": 1.0e6 * (1 + 3e-13)}, RTOL, ATOL)
    assert golden.differences(want, {**want, "n": 0.0}, RTOL, ATOL)
    assert golden.differences(want, {"k[0]": 1.0e6, "n": None}, RTOL, ATOL)
