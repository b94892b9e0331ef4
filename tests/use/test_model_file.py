"""model.toml written by campaign analyze: a robot file that every --robot reads back."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.estimate import analyze_table
from analysis.identification.io.csv_reader import read_csv
from analysis.identification.io.model_export import model_file_data, write_model_file
from analysis.model.kinematics import pin_tool_pose, tool_pose
from analysis.model.robot_files import load_robot_file
from analysis.model.robots import load_robot, with_tool
from campaign.cli import main
from tests.use.conftest import analyze, write_tests_csv


def test_round_trip_values_identical(identified):
    res = json.loads((identified / "results.json").read_text())
    model = load_robot_file(identified / "model.toml")
    assert model.nominal_stiffness.tolist() == res["joint_stiffness_Nm_per_rad"]
    assert np.array_equal(model.compliance_covariance,
                          np.asarray(res["covariance_of_compliance"]))
    ident = model.identification
    assert ident["quantity"] == "compliance" and ident["method"] == res["method"]
    assert ident["n_tests"] == 15 and ident["joints_nominal"] == []
    base = load_robot("kr240-2")
    q = np.random.default_rng(0).uniform(base.lower, base.upper, (20, 6))
    assert np.allclose(tool_pose(model, q), tool_pose(base, q), atol=1e-12)
    assert np.array_equal(model.lower, base.lower) and model.name == base.name
    assert np.array_equal(model.controller_offset, base.controller_offset)


def test_stiffness_command_reads_the_model_and_reports_intervals(identified, capsys):
    q = "15,50,-195,30,40,20"
    assert main(["stiffness", "--robot", str(identified / "model.toml"), "--q", q,
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    res = json.loads((identified / "results.json").read_text())
    assert out["joint_stiffness_Nm_per_rad"] == res["joint_stiffness_Nm_per_rad"]
    u = out["uncertainty"]
    d = np.array(out["deflection_nonlinear_m_rad"])
    lo = np.array(u["deflection_nonlinear_lo95_m_rad"])
    hi = np.array(u["deflection_nonlinear_hi95_m_rad"])
    assert np.all(lo < d) and np.all(d < hi)
    assert np.allclose((lo + hi) / 2, d, rtol=1e-12, atol=1e-15)
    kx = np.diag(np.array(out["K_X"]))
    assert np.allclose((np.array(u["K_X_diag_lo95"]) + u["K_X_diag_hi95"]) / 2, kx)
    # the nominal built-in model has no covariance: no intervals
    assert main(["stiffness", "--robot", "kr240-2", "--q", q, "--json"]) == 0
    assert "uncertainty" not in json.loads(capsys.readouterr().out)


def test_maps_reads_the_model_and_maps_the_upper_bound(identified, tmp_path, capsys,
                                                       monkeypatch):
    out = tmp_path / "maps"
    monkeypatch.setenv("COLUMNS", "80")
    capsys.readouterr()
    assert main(["maps", "--robot", str(identified / "model.toml"), "--out", str(out),
                 "--step", "10", "--format", "csv", "--deflection-upper-bound"]) == 0
    import pandas as pd

    table = pd.read_csv(out / "map_joint_space.csv")
    ok = ~table["singular"]
    assert np.all(table.loc[ok, "deflection_upper95_mm"] > table.loc[ok, "deflection_mm"])
    assert (out / "deflection_upper95_joint.png").is_file()
    # said aloud: the wrench used (the default worst case) and what the bound is, with its
    # largest value over the grid
    printed = " ".join(capsys.readouterr().out.split())
    assert "wrench w = [2200, 2200, 2200] N, [400, 400, 400] N m at P, base frame " \
           "(default: the paper's worst case" in printed
    assert "|dp| + 1.96 sd(|dp|)" in printed
    top = table.loc[ok, "deflection_upper95_mm"].max()
    assert f"at most {top:.4g} mm over the grid" in printed
    summary = json.loads((out / "map_summary.json").read_text())
    assert summary["max_deflection_upper95_mm"] == pytest.approx(top, rel=1e-9)
    assert summary["wrench_source"].startswith("default: the paper's worst case")
    assert main(["maps", "--robot", "kr240-2", "--out", str(out), "--step", "10",
                 "--deflection-upper-bound"]) == 2


def test_results_json_has_cartesian_stiffness_with_standard_errors(identified):
    from analysis.kinetostatics.stiffness import cartesian_stiffness
    from analysis.model.kinematics import jacobian

    res = json.loads((identified / "results.json").read_text())
    cs = res["cartesian_stiffness"]
    assert len(cs["poses"]) == 5 and res["model_file"] == "model.toml"
    robot = load_robot("kr240-2")
    k = np.array(res["joint_stiffness_Nm_per_rad"])
    cov_k = np.array(res["covariance_of_compliance"]) * np.outer(k**2, k**2)
    rng = np.random.default_rng(5)
    draws = rng.multivariate_normal(k, cov_k, 4000)
    p = cs["poses"][0]
    J = jacobian(robot, np.array(p["q_rad"]))
    assert np.allclose(p["K_X_without_K_C"], cartesian_stiffness(J, k), rtol=1e-12)
    sampled = np.std(cartesian_stiffness(np.broadcast_to(J, (4000, 6, 6)), draws), axis=0)
    se = np.array(p["K_X_se"])
    big = se > 1e-3 * np.abs(np.array(p["K_X"])).max()
    assert np.allclose(sampled[big], se[big], rtol=0.08)
    # principal translational stiffness: under a pure force along the principal
    # direction P moves along it by f / k_principal
    C = np.linalg.inv(np.array(p["K_X"]))[:3, :3]
    C = (C + C.T) / 2
    ev, vec = np.linalg.eigh(C)
    assert np.allclose(sorted(p["principal_translational_N_per_m"]), sorted(1 / ev), rtol=1e-9)


def test_joints_not_identified_keep_nominal_and_are_marked(tmp_path):
    # the data come from a compliant wrist, so a rigid-wrist fit is a misfit: accepted here,
    # the test is about how the model file marks the joints that were not identified
    out = analyze(tmp_path, "partial", ["--joints", "1,2,3", "--accept-misfit"])
    model = load_robot_file(out / "model.toml")
    nominal = load_robot("kr240-2").nominal_stiffness
    assert model.identification["joints_nominal"] == [4, 5, 6]
    assert np.array_equal(model.nominal_stiffness[3:], nominal[3:])
    assert np.all(model.compliance_covariance[3:] == 0)
    assert np.all(np.diag(model.compliance_covariance)[:3] > 0)


def test_tool_of_the_run_is_composed_into_the_model(tmp_path):
    csv = tmp_path / "t.csv"
    write_tests_csv(csv)
    robot = with_tool(load_robot("kr240-2"), np.array([0.05, -0.02, 0.3]),
                      np.radians([10.0, -20.0, 30.0]))
    result = analyze_table(read_csv(csv), robot)
    data = model_file_data(result, robot, source_run="x", protocol_sha256="y", date="z")
    path = write_model_file(data, tmp_path / "model.toml")
    model = load_robot_file(path)
    q = np.random.default_rng(1).uniform(robot.lower, robot.upper, (10, 6))
    assert np.allclose(tool_pose(model, q), tool_pose(robot, q), atol=1e-12)
    assert np.allclose(pin_tool_pose(model, q[0]), tool_pose(robot, q[0]), atol=1e-12)
    assert "reference_poses" not in data
    # that model carries the tool: a second tool point in the flange frame is refused (it would
    # be composed on the first), the same one again is accepted, none reports the file's
    xyz, rpy = "50,-20,300", "10,-20,30"
    with pytest.raises(InputError, match=r"already places P with its \[tool\].*50\.0, -20\.0, 300"):
        with_tool(model, np.array([0.0, 0.0, 0.1]), np.zeros(3))
    assert with_tool(model, np.array([0.05, -0.02, 0.3]), np.radians([10.0, -20.0, 30.0])) is model
    from campaign.options import robot_and_tool

    same, tool = robot_and_tool(str(path), None, xyz, rpy)
    assert np.allclose(tool_pose(same, q), tool_pose(robot, q), atol=1e-12)
    _, tool = robot_and_tool(str(path), None)
    assert np.allclose(tool.xyz_mm, [50, -20, 300]) and np.allclose(tool.rpy_deg, [10, -20, 30])
    assert "tool of the robot file" in tool.source
    assert main(["stiffness", "--robot", str(path), "--q", "15,50,-195,30,40,20",
                 "--tool-xyz-mm", "0,0,100"]) == 2


def test_bad_identification_table_is_refused_with_its_line(identified, tmp_path):
    text = (identified / "model.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('quantity = "compliance"', 'quantity = "stiffness"'))
    with pytest.raises(InputError, match=r"bad.toml:\d+: identification.quantity"):
        load_robot_file(bad)
    one_two = "joints_identified = [\n    1,\n    2,"
    bad.write_text(text.replace("joints_nominal = []", "joints_nominal = [2]")
                   .replace(one_two, "joints_identified = [\n    1,"))
    with pytest.raises(InputError, match="joint 2 is nominal but has a non-zero covariance"):
        load_robot_file(bad)


def _with_identification(tmp_path, cov: np.ndarray):
    """The built-in KR240-2 file with an [identification] table holding ``cov``."""
    from analysis.model.robots import builtin_files

    text = builtin_files()["kr240-2"].read_text()
    rows = ",\n  ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in cov)
    text += ('\n[identification]\nquantity = "compliance"\n'
             'covariance_unit = "(rad/(N m))^2"\n'
             f"covariance = [\n  {rows}\n]\n"
             "joints_identified = [1, 2, 3, 4, 5, 6]\nmethod = \"exact\"\nn_tests = 15\n"
             'source_run = "hand-made"\ndate = "2026-12-01T00:00:00Z"\n')
    path = tmp_path / "model.toml"
    path.write_text(text)
    return path


def test_indefinite_covariance_is_refused(tmp_path, capsys):
    """C = 2b I - b 11^T: symmetric, diagonal b > 0, eigenvalues 2b (x5) and -4b."""
    from tests.refusal import assert_refused

    b = 1e-15
    cov = 2 * b * np.eye(6) - b * np.ones((6, 6))
    assert np.allclose(np.diag(cov), b) and np.isclose(np.linalg.eigvalsh(cov)[0], -4 * b)
    path = _with_identification(tmp_path, cov)
    err = assert_refused(capsys, ["stiffness", "--robot", path, "--q", "15,50,-195,30,40,20",
                                  "--json"],
                         "identification.covariance: Value error, covariance is not positive "
                         "semi-definite", watch=[tmp_path])
    line = next(i for i, t in enumerate(path.read_text().splitlines(), 1)
                if t.startswith("covariance = "))
    assert f"model.toml:{line}: " in err and "-4e-15 (rad/(N m))^2" in err
    assert "correlation matrix: -4" in err
    # the same matrix made positive semi-definite (b 11^T + b I) is accepted, and so is
    # a singular one (b 11^T: rank 1, eigenvalues 6b and 0 up to round-off)
    for ok in (b * np.ones((6, 6)) + b * np.eye(6), b * np.ones((6, 6))):
        _with_identification(tmp_path, ok)
        assert np.array_equal(load_robot_file(path).compliance_covariance, ok)
    # a joint with zero variance and a non-zero covariance is indefinite too
    bad = b * np.eye(6)
    bad[0, 0], bad[0, 1], bad[1, 0] = 0.0, b / 2, b / 2
    _with_identification(tmp_path, bad)
    with pytest.raises(InputError, match="joint 1 has zero variance but a non-zero"):
        load_robot_file(path)
