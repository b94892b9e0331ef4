"""campaign place: recomputation of its outputs, a symmetric case, infeasibility, Dask."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.stiffness import deflection
from analysis.model.ik import ALL_FLAGS, IKSolver, fit_limits
from analysis.model.kinematics import jacobian, tool_pose
from analysis.model.robots import load_robot
from analysis.placement.evaluate import Problem
from analysis.placement.poses import placement_transforms, tool_rotations
from analysis.placement.search import run_dask, run_local
from campaign.cli import main

WRENCH = "400,250,-300,0,0,20"


def _write_path(path, n=8, radius=50.0):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    with path.open("w") as fh:
        fh.write("x_mm,y_mm,z_mm,ax,ay,az\n")
        for a in t:
            fh.write(f"{radius * np.cos(a):.6f},{radius * np.sin(a):.6f},0,0,0,-1\n")
    return path


def _place(tmp_path, *extra):
    path = _write_path(tmp_path / "part.csv")
    out = tmp_path / "out"
    code = main(["place", "--robot", "kr240-2", "--path", str(path), "--out", str(out),
                 "--x-mm", "1400..1800", "--y-mm", "-200..200", "--z-mm", "200",
                 "--x-step-mm", "200", "--y-step-mm", "200", "--tool-angle-step-deg", "30",
                 "--config", "-1,-1,-1", "--wrench", WRENCH, "--workers", "0", *extra])
    return code, out


def test_outputs_recomputed_from_path_joints(tmp_path, capsys):
    code, out = _place(tmp_path)
    assert code == 0
    summary = json.loads((out / "placement.json").read_text())
    for key in ("placement", "objective", "objective_name", "center_objective", "runner_ups",
                "search_space", "infeasible"):
        assert key in summary
    p = summary["placement"]
    rows = list(csv.DictReader((out / "path_joints.csv").open()))
    assert len(rows) == 8
    robot = load_robot("kr240-2")
    q = np.radians([[float(r[f"q{j}_deg"]) for j in range(1, 7)] for r in rows])
    assert np.all(robot.within_limits(q))
    # forward kinematics reaches each placed path point (placement convention of the docs)
    part = np.array([[50 * np.cos(a), 50 * np.sin(a), 0.0]
                     for a in np.linspace(0, 2 * np.pi, 8, endpoint=False)])
    yaw = np.radians(p["yaw_deg"])
    Rz = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    placed = np.array([p["x_mm"], p["y_mm"], p["z_mm"]]) + part @ Rz.T
    T = tool_pose(robot, q)
    assert np.max(np.linalg.norm(1e3 * T[:, :3, 3] - placed, axis=1)) < 0.01
    assert np.allclose(T[:, :3, 2], [0, 0, -1], atol=1e-9)  # the tool axis
    # deflection: `campaign stiffness` at those joints, wrench turned from tool to base axes
    w_tool = np.array([float(v) for v in WRENCH.split(",")])
    capsys.readouterr()
    dp = []
    for i in (0, 5):
        w = np.concatenate([T[i, :3, :3] @ w_tool[:3], T[i, :3, :3] @ w_tool[3:]])
        code = main(["stiffness", "--robot", "kr240-2", "--json",
                     "--q", ",".join(f"{v:.12f}" for v in np.degrees(q[i])),
                     "--wrench", ",".join(f"{v:.12f}" for v in w)])
        data = json.loads(capsys.readouterr().out)
        assert code == 0
        ref = np.array(data["deflection_without_K_C_m_rad"][:3]) * 1e3
        row = np.array([float(rows[i][c]) for c in ("dx_mm", "dy_mm", "dz_mm")])
        np.testing.assert_allclose(row, ref, rtol=1e-7, atol=1e-9)
        nl = np.array(data["deflection_nonlinear_m_rad"][:3]) * 1e3
        row_nl = np.array([float(rows[i][c]) for c in
                           ("dx_nonlinear_mm", "dy_nonlinear_mm", "dz_nonlinear_mm")])
        np.testing.assert_allclose(row_nl, nl, rtol=1e-7, atol=1e-9)
        dp.append(ref)
    d = np.array([float(r["d_mm"]) for r in rows])
    assert summary["objective"] == pytest.approx(d.max(), rel=1e-9)
    assert summary["objective_unit"] == "mm"
    for name in ("objective_xy.png", "path_deflection.png", "place_path.src", "place_path.dat"):
        assert (out / name).stat().st_size > 0


def _problem(robot, x, y, flags=ALL_FLAGS):
    """One path point at the part origin, tool straight down, axial force only."""
    return Problem(robot=robot, points=np.zeros((1, 3)), axes=np.array([[0, 0, -1.0]]),
                   wrench=np.array([[0, 0, -2000.0, 0, 0, 0]]),
                   angles=np.radians(np.arange(0, 360, 30.0)), k=robot.nominal_stiffness,
                   length=0.682, min_inv_kappa=0.05, margin=np.radians(2),
                   max_step=np.radians(10), objective="max", flags=flags)


def test_symmetric_case_finds_the_brute_force_optimum():
    robot = load_robot("kr240-2")
    xs, ys = np.arange(1.0, 2.61, 0.2), np.array([-0.6, -0.3, 0.0, 0.3, 0.6])
    G = np.array([[x, y, 0.3, 0.0] for x in xs for y in ys])
    problem = _problem(robot, xs, ys)
    res = run_local(problem, G, chunk=7)
    values = res.value.reshape(len(xs), len(ys))
    # the arm is symmetric about its vertical plane: y and -y give the same objective
    np.testing.assert_allclose(values, values[:, ::-1], rtol=1e-9)
    # brute force with the library's deflection, every configuration and tool angle
    solver = IKSolver.for_robot(robot)
    R = tool_rotations(problem.axes, problem.angles)[0]
    brute = np.full(len(G), np.inf)
    for i, pl in enumerate(G):
        Tp = placement_transforms(pl[None])[0]
        T = np.repeat(np.eye(4)[None], len(R), axis=0)
        T[:, :3, :3] = Tp[:3, :3] @ R
        T[:, :3, 3] = pl[:3]
        for flags in ALL_FLAGS:
            q, ok = solver.solve(T, flags)
            q, inside = fit_limits(robot, np.nan_to_num(q), np.radians(2))
            J = jacobian(robot, q)
            ok &= inside & (inverse_condition(normalized_jacobian(J, 0.682)) >= 0.05)
            w = np.concatenate([T[:, :3, :3] @ [0, 0, -2000.0], np.zeros((len(R), 3))], axis=1)
            d = np.linalg.norm(deflection(J, robot.nominal_stiffness, w)[:, :3], axis=1)
            brute[i] = min(brute[i], np.min(np.where(ok, d, np.inf)))
    np.testing.assert_allclose(res.value, brute, rtol=1e-9)
    assert np.isfinite(brute).sum() > 10
    assert np.argmin(res.value) == np.argmin(brute)


def test_infeasible_placements_are_reported(tmp_path, capsys):
    path = _write_path(tmp_path / "part.csv")
    out = tmp_path / "out"
    code = main(["place", "--robot", "kr240-2", "--path", str(path), "--out", str(out),
                 "--x-mm", "1600..4600", "--y-mm", "0", "--z-mm", "200", "--x-step-mm", "1500",
                 "--tool-angle-step-deg", "60", "--wrench", WRENCH, "--workers", "0"])
    assert code == 0
    inf = json.loads((out / "placement.json").read_text())["infeasible"]
    assert inf["count"] == 2 and len(inf["placements"]) == 2
    assert {p["x_mm"] for p in inf["placements"]} == {3100.0, 4600.0}
    assert all(p["reason"].startswith("unreachable") for p in inf["placements"])
    code = main(["place", "--robot", "kr240-2", "--path", str(path), "--out", str(out),
                 "--x-mm", "4000..5000", "--y-mm", "0", "--z-mm", "200", "--x-step-mm", "1000",
                 "--wrench", WRENCH, "--workers", "0", "--force"])
    err = capsys.readouterr().err
    assert code == 2 and "no feasible placement among 2" in err and "unreachable" in err


@pytest.mark.parametrize("content, message", [
    ("x_mm,y_mm,z_mm,ax,ay\n1,2,3,0,0\n", "missing column(s) az"),
    ("x_mm,y_mm,z_mm,ax,ay,az\n1,2,3,0,0,-1\n1,x,3,0,0,-1\n", "part.csv:3: column y_mm"),
    ("x_mm,y_mm,z_mm,ax,ay,az\n1,2,3,0,0,-2\n", "part.csv:2: tool axis"),
])
def test_bad_path_file(tmp_path, capsys, content, message):
    path = tmp_path / "part.csv"
    path.write_text(content)
    code = main(["place", "--robot", "kr240-2", "--path", str(path), "--out",
                 str(tmp_path / "o"), "--x-mm", "1500", "--y-mm", "0", "--z-mm", "0",
                 "--wrench", WRENCH, "--workers", "0"])
    assert code == 2 and message in capsys.readouterr().err


def test_missing_wrench_and_covariance_refused(tmp_path, capsys):
    path = _write_path(tmp_path / "part.csv")
    base = ["place", "--robot", "kr240-2", "--path", str(path), "--out", str(tmp_path / "o"),
            "--x-mm", "1500", "--y-mm", "0", "--z-mm", "0", "--workers", "0"]
    assert main(base) == 2 and "no process wrench" in capsys.readouterr().err
    assert main([*base, "--wrench", WRENCH, "--upper-bound"]) == 2
    assert "upper bound is unavailable" in capsys.readouterr().err


def test_dask_local_cluster_equals_local_run():
    from distributed import Client, LocalCluster

    robot = load_robot("kr240-2")
    G = np.array([[x, y, 0.3, yaw] for x in (1.2, 1.6, 2.0, 2.8) for y in (-0.3, 0.3)
                  for yaw in (0.0, 0.5)])
    problem = _problem(robot, None, None)
    local = run_local(problem, G, chunk=3)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster, Client(cluster) as client:
        remote = run_dask(problem, G, 3, client)
    for field in ("value", "config", "angle", "reason", "point"):
        np.testing.assert_array_equal(getattr(remote, field), getattr(local, field))
    assert np.isfinite(local.value).sum() > 0 and np.isinf(local.value).sum() > 0


def test_edge_of_the_box_is_warned_and_the_nonlinear_check_has_a_unit(tmp_path, capsys):
    from campaign.use.place_run import edge_warnings

    capsys.readouterr()
    code, out = _place(tmp_path)
    assert code == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "placement.json").read_text())
    p, space = summary["placement"], summary["search_space"]
    on_edge = [key for key in ("x_mm", "y_mm") if p[key] in (space[key][0], space[key][-1])]
    assert len(summary["warnings"]) == len(on_edge)
    flat = " ".join(printed.split())
    for key in on_edge:
        assert f"edge of --{key.replace('_', '-')}" in flat
    nl = summary["objective_nonlinear"]
    assert f"nonlinear equilibrium with K_C: {nl:.4g} mm" in flat
    assert repr(nl) not in printed  # no 16-digit float
    # the rule itself: x, y, z, yaw grids, C order; a full turn of yaw has no edge
    grids = {"x_mm": np.array([0.0, 100, 200]), "y_mm": np.array([0.0, 50]),
             "z_mm": np.array([300.0]), "yaw_deg": np.arange(0.0, 360, 90)}
    assert edge_warnings(grids, np.ravel_multi_index((1, 0, 0, 3), (3, 2, 1, 4))) == [
        "the best placement is on the lower edge of --y-mm (y = 0 mm, range 0..50 mm): a "
        "better one may lie outside the box; widen --y-mm"]
    assert edge_warnings(grids, np.ravel_multi_index((2, 1, 0, 0), (3, 2, 1, 4)))[0].startswith(
        "the best placement is on the upper edge of --x-mm (x = 200 mm")
    grids["yaw_deg"] = np.array([-30.0, 0, 30])
    assert "--yaw-deg" in edge_warnings(grids, np.ravel_multi_index((1, 0, 0, 2), (3, 2, 1, 3)))[1]
