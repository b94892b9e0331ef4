"""The foundation commands end to end: output, JSON keys, exit codes, no tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from analysis.kinetostatics.stiffness import cartesian_stiffness, complementary_stiffness
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot
from campaign.cli import main


def run(args, capsys):
    code = main(args)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_stiffness_json_matches_library(capsys):
    code, out, _ = run(["stiffness", "--robot", "kr240-2", "--q", "0,30,10,45,45,45",
                        "--wrench", "0,2200,2200,200,200,0", "--json"], capsys)
    assert code == 0
    data = json.loads(out)
    assert {"J_m_rad_per_rad", "K_C_Nm_per_rad", "K_X", "deflection_m_rad"} <= data.keys()
    assert data["wrench_source"] == "--wrench"
    r = load_robot("kr240-2")
    q = np.radians([0, 30, 10, 45, 45, 45])
    w = np.array([0, 2200, 2200, 200, 200, 0.0])
    K_X = cartesian_stiffness(jacobian(r, q), r.nominal_stiffness,
                              complementary_stiffness(r, q, w))
    np.testing.assert_allclose(np.array(data["K_X"]), K_X, rtol=1e-12)
    np.testing.assert_allclose(np.array(data["J_m_rad_per_rad"]), jacobian(r, q), atol=1e-15)
    # deflection is K_X^-1 w
    np.testing.assert_allclose(np.array(data["deflection_m_rad"]), np.linalg.solve(K_X, w),
                               rtol=1e-9)


def test_controller_angles_option(capsys):
    code, out, _ = run(["stiffness", "--robot", "kr240-2", "--q", "0,-90,90,0,30,0",
                        "--controller-angles", "--json"], capsys)
    assert code == 0
    assert np.allclose(np.degrees(json.loads(out)["q_rad"]), [0, 90, -180, 0, -30, 0])


@pytest.mark.parametrize(
    "args, message",
    [
        (["stiffness", "--robot", "nope", "--q", "0,0,0,0,0,0"], "unknown robot"),
        (["stiffness", "--robot", "kr240-2", "--q", "0,0,0"], "--q: expected 6"),
        (["stiffness", "--robot", "kr240-2", "--q", "0,0,x,0,0,0"], "item 3 ('x')"),
        (["stiffness", "--robot", "kr240-2", "--q", "0,0,inf,0,0,0"], "finite"),
        (["stiffness", "--robot", "ur5e", "--q", "0,0,0,0,0,0"], "--joint-stiffness"),
        (["stiffness", "--robot", "kr240-2", "--q", "10,-80,70,-30,60,20", "--ignore-limits",
          "--wrench", "1e7,0,0,0,0,0"], "nonlinear equilibrium"),
        (["maps", "--robot", "kr240-2", "--out", "/tmp/x", "--step", "0"], "--step"),
    ],
)
def test_bad_input_exits_2_with_message(capsys, args, message):
    code, _, err = run(args, capsys)
    assert code == 2
    assert message in err
    assert "Traceback" not in err


def test_console_script_no_traceback():
    proc = subprocess.run([sys.executable, "-m", "campaign", "stiffness", "--robot", "kr240-2",
                           "--q", "1,2"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "expected 6" in proc.stderr


def test_maps_writes_data_and_plots(tmp_path, capsys):
    code, out, _ = run(["maps", "--robot", "kr240-2", "--out", str(tmp_path), "--step", "5",
                        "--format", "csv"], capsys)
    assert code == 0
    table = pd.read_csv(tmp_path / "map_joint_space.csv")
    assert len(table) == 30 * 56  # theta2 0..146 (30 nodes), theta3 -245..30 (56 nodes)
    assert table["inv_kappa_F"].between(0, 1).all()
    summary = json.loads((tmp_path / "map_summary.json").read_text())
    assert 0.01 < summary["max_v_p"] < 0.02
    for name in ("inv_kappa_F_joint.png", "v_p_joint.png", "v_r_cartesian.png"):
        png = (tmp_path / name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_maps_on_robot_without_length_computes_it(tmp_path, capsys):
    code, out, _ = run(["maps", "--robot", "ur10e", "--out", str(tmp_path), "--step", "20",
                        "--joint-stiffness", "1e5,1e5,1e5,1e4,1e4,1e4"], capsys)
    assert code == 0
    assert "computed" in out
    table = pd.read_parquet(tmp_path / "map_joint_space.parquet")
    assert table["singular"].any()  # UR at theta3 = 0 is stretched: elbow singular
    assert not table[["v_p", "v_r_deg", "inv_kappa_F"]].isna().any().any()


STIFF = ["stiffness", "--robot", "kr240-2"]
Q = ["--q", "0,30,-170,45,45,45"]


@pytest.mark.parametrize("args, message", [
    ([*STIFF, *Q, "--wrench", ""], "--wrench: empty value: expected 6 comma-separated"),
    ([*STIFF, *Q, "--wrench", " "], "--wrench: empty value"),
    ([*STIFF, *Q, "--joint-stiffness", ""], "--joint-stiffness: empty value"),
    ([*STIFF, "--q", "0,,30,-170,45,45,45"], "--q: item 2 is empty"),
    ([*STIFF, "--q", "0,30,-170,45,45,45,"], "--q: item 7 is empty"),
    ([*STIFF, *Q, "--wrench", "1,2,,3,4,5"], "--wrench: item 3 is empty"),
    (["maps", "--robot", "kr240-2", "--out", "OUT", "--wrench", ""], "--wrench: empty value"),
    (["maps", "--robot", "kr240-2", "--out", "OUT", "--joint-stiffness", ""],
     "--joint-stiffness: empty value"),
])
def test_empty_items_are_refused(tmp_path, capsys, args, message):
    """An empty option or item is a typo: refused, never a default or a dropped item."""
    from tests.refusal import assert_refused

    args = [str(tmp_path / "out") if a == "OUT" else a for a in args]
    assert_refused(capsys, args, message, watch=[tmp_path])
