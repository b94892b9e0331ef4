"""campaign stiffness at a singular pose, with a tool point, and at a wrench too large."""

from __future__ import annotations

import json

import numpy as np

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
    rc = main(["stiffness", "--robot", "kr240-2", "--q", "10,-80,70,-30,60,20",
               "--wrench", "1e7,0,0,0,0,0"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err
    assert err.startswith("error: nonlinear equilibrium:") and "reduce the wrench" in err
