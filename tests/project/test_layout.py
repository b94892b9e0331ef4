"""One Newton solver for the equilibrium, and no import circle in the identification."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from analysis.identification.estimators.exact_model import (
    solve_deflection_compliance,
    solve_deflection_masked,
)
from analysis.kinetostatics.equilibrium import (
    EquilibriumError,
    newton_deflection,
    solve_deflection,
)
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot

ROOT = Path(__file__).resolve().parents[2]


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def test_crossval_does_not_import_estimate():
    assert "analysis.identification.estimate" not in _imports(
        ROOT / "analysis/identification/validation/crossval.py")


def test_one_newton_loop():
    """Only equilibrium.newton_deflection iterates complementary stiffness Newton steps."""
    hits = []
    for path in (ROOT / "analysis").rglob("*.py"):
        text = path.read_text()
        newton = ("complementary_stiffness_from_state(state, w)" in text
                  or "complementary_stiffness_from_jacobian(J, w)" in text
                  or "complementary_stiffness_em(J, w" in text)
        if newton and ("for _ in range" in text or "in range(max_iter)" in text):
            hits.append(path.relative_to(ROOT).as_posix())
    assert hits == ["analysis/kinetostatics/equilibrium.py"]


@pytest.fixture(scope="module")
def batch():
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.lower, robot.upper, (200, 6)) * 0.5
    w = rng.normal(size=(200, 6)) * np.r_[[3000.0] * 3, [300.0] * 3]
    return robot, q, robot.nominal_stiffness, w


def test_entry_points_agree_and_solve_the_equilibrium(batch):
    robot, q, k, w = batch
    dq = solve_deflection(robot, q, k, w)
    # independent check: K dq = J(q + dq)^T w
    resid = k * dq - np.einsum("nji,nj->ni", jacobian(robot, q + dq), w)
    assert np.max(np.abs(resid)) < 1e-6  # N m, against torques of ~1e3 N m
    np.testing.assert_allclose(solve_deflection_compliance(robot, q, 1 / k, w), dq,
                               rtol=0, atol=1e-15)
    masked, ok = solve_deflection_masked(robot, q, 1 / k, w)
    assert ok.all()
    np.testing.assert_allclose(masked, dq, rtol=0, atol=1e-15)
    # a start near the solution (campaign compensate) lands on the same solution
    np.testing.assert_allclose(solve_deflection(robot, q, k, w, dq0=0.9 * dq), dq,
                               rtol=0, atol=1e-15)


def test_unconverged_mask_names_the_failing_poses(batch):
    robot, q, k, w = batch
    w = w.copy()
    w[::7] *= 1e4  # loads that buckle the model
    with pytest.raises(EquilibriumError) as err:
        solve_deflection(robot, q, k, w)
    mask = err.value.unconverged
    assert mask.shape == (200,)
    good = np.ones(200, bool)
    good[::7] = False
    assert not mask[good].any() and mask[~good].any()
    dq, failed, last = newton_deflection(robot, q, 1 / k, w, max_deflection=1.0)
    assert failed[~good].any() and not failed[good].any()
    assert np.all(last[good] <= 1e-14)
