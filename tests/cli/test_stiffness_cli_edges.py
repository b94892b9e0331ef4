"""campaign stiffness at a singular pose, with a tool point, and at a wrench too large."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.kinetostatics.stiffness import complementary_stiffness
from analysis.model.kinematics import chain_state, jacobian
from analysis.model.robots import load_robot
from campaign.cli import main


def _json(capsys, *args) -> dict:
    assert main(["stiffness", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_kuka_home_pose_reports_what_is_defined(capsys):
    """A5 = 0: J singular; J, K_C and the deflections are reported, K_X is undefined."""
    robot = load_robot("kr240-2")
    out = _json(capsys, "--robot", "kr240-2", "--q", "0,-90,90,0,0,0", "--controller-angles")
    assert out["K_X"] is None and out["K_X_without_K_C"] is None
    assert "J is singular" in out["undefined"]["K_X"] and "needs J^-1" in out["undefined"]["K_X"]
    q = np.array(out["q_rad"])
    J = np.array(out["J_m_rad_per_rad"])
    np.testing.assert_allclose(J, jacobian(robot, q), atol=1e-12)
    assert np.linalg.matrix_rank(J, tol=1e-9) == 5
    w = np.array(out["wrench_N_Nm"])
    K_C = complementary_stiffness(robot, q, w)
    np.testing.assert_allclose(out["K_C_Nm_per_rad"], K_C, atol=1e-9)
    # deflection cross-check: J (K_theta - K_C)^-1 J^T w, solved independently
    k = np.array(out["joint_stiffness_Nm_per_rad"])
    dq = np.linalg.lstsq(np.diag(k) - K_C, J.T @ w, rcond=None)[0]
    np.testing.assert_allclose(out["deflection_m_rad"], J @ dq, rtol=1e-9, atol=1e-15)
    assert np.all(np.isfinite(out["deflection_nonlinear_m_rad"]))
    assert main(["stiffness", "--robot", "kr240-2", "--q", "0,-90,90,0,0,0",
                 "--controller-angles"]) == 0
    text = capsys.readouterr().out
    assert "undefined" in text and "deflection of P" in text


def test_tool_options_move_P(capsys):
    """J at P = J at the flange with v_P = v_F + omega x r (r: flange-to-P, base frame)."""
    args = ["--robot", "ur10e", "--q", "10,-80,70,-30,60,20", "--joint-stiffness",
            "2e5,2e5,1e5,3e4,3e4,3e4"]
    flange = _json(capsys, *args)
    tool = _json(capsys, *args, "--tool-xyz-mm", "10,-20,120", "--tool-rpy-deg", "0,30,0")
    assert flange["tool"]["source"] == "none given: flange centre assumed"
    assert tool["tool"]["xyz_mm"] == [10.0, -20.0, 120.0]
    robot = load_robot("ur10e")
    R = chain_state(robot, np.array(flange["q_rad"])).tip[:3, :3]
    r = R @ np.array([0.010, -0.020, 0.120])
    Jf = np.array(flange["J_m_rad_per_rad"])
    expected = Jf.copy()
    expected[:3] = Jf[:3] + np.cross(Jf[3:].T, r).T
    np.testing.assert_allclose(tool["J_m_rad_per_rad"], expected, atol=1e-12)


def test_equilibrium_failure_is_one_line(capsys):
    rc = main(["stiffness", "--robot", "kr240-2", "--q", "10,-80,70,-30,60,20", "--ignore-limits",
               "--wrench", "1e7,0,0,0,0,0"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err
    assert err.startswith("error: nonlinear equilibrium:") and "reduce the wrench" in err


# --- bad-input corpus (issue 20, item 6): physically impossible inputs are refused ---

KR = ["stiffness", "--robot", "kr240-2"]


@pytest.mark.parametrize("args, message", [
    ([*KR, "--q", "999,30,-170,45,45,45"],
     "--q: q1 = 999 deg is outside the joint limits [-185, 185] deg of KUKA KR240-2"),
    ([*KR, "--q", "0,30,-170,45,130,45"], "q5 = 130 deg is outside the joint limits"),
    ([*KR, "--q", "999,-30,80,45,45,45", "--controller-angles"],
     "q1 = -999 deg (typed 999 deg in the pendant convention)"),
    ([*KR, "--q", "0,30,-170,45,45,45", "--wrench", "1e12,0,0,0,0,0"],
     "--wrench: deflection outside the small-displacement model's validity (joint 4"),
    ([*KR, "--q", "0,30,-170,45,45,45", "--wrench", "1e5,0,0,0,0,0"],
     "P rotates 140.9 mrad > 100 mrad"),
])
def test_impossible_inputs_refused(tmp_path, capsys, args, message):
    from tests.refusal import assert_refused

    assert_refused(capsys, args, message, watch=[tmp_path])


def test_ignore_limits_computes_at_the_wrapped_pose(capsys):
    """q1 = 999 deg is q1 = 279 deg, i.e. -81 deg: J equals J at -81 deg."""
    args = ["--q", "999,30,-170,45,45,45", "--ignore-limits"]
    out = _json(capsys, "--robot", "kr240-2", *args)
    ref = _json(capsys, "--robot", "kr240-2", "--q", "-81,30,-170,45,45,45")
    np.testing.assert_allclose(out["J_m_rad_per_rad"], ref["J_m_rad_per_rad"], atol=1e-12)
    np.testing.assert_allclose(out["deflection_nonlinear_m_rad"],
                               ref["deflection_nonlinear_m_rad"], rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("scale", [1.0, 3.0, 6.0, 10.0, 20.0])
def test_validity_refusal_follows_the_stated_criterion(capsys, scale):
    """Refused exactly when max |dq_j| > 0.1 rad, |rotation| > 0.1 rad or |dp| > 5 % of
    the chain length, each computed here from the library's equilibrium."""
    from analysis.kinetostatics.equilibrium import solve_deflection
    from analysis.model.kinematics import pose_difference

    robot = load_robot("kr240-2")
    q = np.radians([0, 30, -170, 45, 45, 45])
    w = scale * np.array([2200.0, 2200, 2200, 400, 400, 400])
    dq = solve_deflection(robot, q, robot.nominal_stiffness, w)
    screw = pose_difference(chain_state(robot, q).tip, chain_state(robot, q + dq).tip)
    chain = 0.350 + 1.150 + np.hypot(0.041, 1.200) + 0.215  # Table 1 lengths (m)
    assert robot.chain_length == pytest.approx(chain, rel=1e-12)
    bad = (np.max(np.abs(dq)) > 0.1 or np.linalg.norm(screw[3:]) > 0.1
           or np.linalg.norm(screw[:3]) > 0.05 * chain)
    rc = main(["stiffness", "--robot", "kr240-2", "--q", "0,30,-170,45,45,45", "--wrench",
               ",".join(f"{v:.17g}" for v in w), "--json"])
    err = capsys.readouterr().err
    assert rc == (2 if bad else 0), err
    assert ("small-displacement model's validity" in err) == bad
    if scale == 1.0:
        assert not bad  # the paper's worst-case wrench is well inside
    if scale == 20.0:
        assert bad


def test_robot_file_in_mm_under_metres_is_refused(tmp_path, capsys):
    """d = 1150 (mm) under length_unit = "m": a 1150 m link, named with the unit mix-up."""
    from tests.refusal import assert_refused

    src = load_robot("kr240-2").source_file
    text = open(src).read()
    assert "d = 1.150" in text
    bad = tmp_path / "arm.toml"
    bad.write_text(text.replace("d = 1.150", "d = 1150"))
    line = text.splitlines().index('length_unit = "m"') + 1
    err = assert_refused(capsys, [*KR[:2], bad, "--q", "0,30,-170,45,45,45"],
                         f"arm.toml:{line}: length_unit = \"m\": the chain's link lengths add up",
                         watch=[tmp_path])
    assert "joints[2].d = 1150: are the lengths in mm? (set length_unit = \"mm\")" in err
    # the other way round: metres under "mm"
    bad.write_text(text.replace('length_unit = "m"', 'length_unit = "mm"')
                   .replace("characteristic_length = 0.682", ""))
    err = assert_refused(capsys, [*KR[:2], bad, "--q", "0,30,-170,45,45,45"],
                         "implausible for an industrial arm (expected 0.05..10 m)",
                         watch=[tmp_path])
    assert "joints[3].r = 1.2: are the lengths in m? (set length_unit = \"m\")" in err


def test_robot_file_stiffness_unit_mix_up_is_refused(tmp_path, capsys):
    """N m/rad values under stiffness_unit = "kN m/rad": k1 = 1.41e9 N m/rad."""
    from tests.refusal import assert_refused

    text = open(load_robot("kr240-2").source_file).read()
    bad = tmp_path / "arm.toml"
    bad.write_text(text.replace('stiffness_unit = "N m/rad"', 'stiffness_unit = "kN m/rad"'))
    line = text.splitlines().index('stiffness_unit = "N m/rad"') + 1
    assert_refused(capsys, [*KR[:2], bad, "--q", "0,30,-170,45,45,45"],
                   f"arm.toml:{line}: joints[0].stiffness = 1.4098e+06 kN m/rad is 1.41e+09 "
                   "N m/rad, implausible for an industrial arm's joint (expected 10..1e+09 "
                   'N m/rad): are the values in N m/rad? (set stiffness_unit = "N m/rad")',
                   watch=[tmp_path])
