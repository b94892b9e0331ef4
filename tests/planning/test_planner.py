"""The planner: poses inside zones, limits and thresholds; plan files; determinism."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.identification.estimators.linear_model import design_matrix
from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.stiffness import kc_influence
from analysis.model.kinematics import jacobian
from campaign.planning.plan_output import COLUMNS
from campaign.planning.planner import make_plan, read_plan, write_plan
from campaign.protocol_robot import protocol_robot

DEG = np.pi / 180
#: Dumas et al. 2011, Table 4 (deg, the paper's convention = the model's)
TABLE4 = {"zone 1": ((0, 110), (-245, -170)), "zone 2": ((0, 25), (0, 29)),
          "zone 3": ((100, 146), (0, 29))}


def _check_rows(protocol, df):
    robot = protocol_robot(protocol)
    q = df[[f"q{j}_model_deg" for j in range(1, 7)]].to_numpy() * DEG
    margin = protocol.safety.joint_margin_deg * DEG
    assert robot.within_limits(q, margin - 1e-9).all()
    ctrl = df[[f"q{j}_ctrl_deg" for j in range(1, 7)]].to_numpy() * DEG
    assert np.allclose(robot.to_controller(q), ctrl, atol=1e-3 * DEG)
    L = protocol.campaign.characteristic_length_mm
    L = robot.characteristic_length if L is None else L * 1e-3
    inv_k = inverse_condition(normalized_jacobian(jacobian(robot, q), L))
    assert np.all(inv_k >= protocol.thresholds.min_inv_kappa_F)
    assert np.allclose(inv_k, df["inv_kappa_F"], atol=1e-6)
    k = np.array(protocol.campaign.prior_stiffness or robot.nominal_stiffness)
    w = df[["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m"]].to_numpy()
    for qi, wi, vp, vr in zip(q, w, df["v_p"], df["v_r_deg"], strict=True):
        v_p, v_r = kc_influence(robot, qi, k, wi)
        assert v_p <= protocol.thresholds.max_v_p and v_r / DEG <= protocol.thresholds.max_v_r_deg
        assert v_p == pytest.approx(vp, rel=1e-5) and v_r / DEG == pytest.approx(vr, rel=1e-5)
    names = {c.name: c.wrench() for c in protocol.load_cases}
    assert np.allclose([names[c] for c in df["load_case"]], w)
    return q


@pytest.mark.parametrize("strategy", ["d-optimal", "e-optimal", "zones-random"])
def test_kr240_poses_in_table4_zones_and_thresholds(kr_protocol, strategy):
    df = make_plan(kr_protocol, strategy, seed=1, candidates=4000).to_frame()
    assert list(df.columns) == COLUMNS
    assert len(df) == 5 and df["pose"].nunique() == 5
    q = _check_rows(kr_protocol, df) / DEG
    for zone, row in zip(df["zone"], q, strict=True):
        (a2, b2), (a3, b3) = TABLE4[zone]
        assert a2 <= row[1] <= b2 and a3 <= row[2] <= b3
        assert np.allclose(row[[0, 3, 4, 5]], [0, 45, 45, 45])  # as in the paper's Fig. 3


def test_ur10e_poses_in_user_zones(ur_protocol):
    plan = make_plan(ur_protocol, "d-optimal", seed=0, candidates=3000)
    df = plan.to_frame()
    assert len(df) == 8
    q = _check_rows(ur_protocol, df) / DEG
    zones = {z.name: z.ranges_deg for z in ur_protocol.zones}
    ranges = ur_protocol.sampling.ranges_deg
    for zone, row in zip(df["zone"], q, strict=True):
        for key, (lo, hi) in {**zones[zone], **ranges}.items():
            assert lo - 1e-9 <= row[int(key[1:]) - 1] <= hi + 1e-9
    assert plan.candidates.rejected["1/kappa_F below threshold"] > 0


def test_all_load_cases_per_pose(tmp_path, kr_protocol):
    proto = kr_protocol.model_copy(update={"loads": kr_protocol.loads.model_copy(
        update={"selection": "all"})})
    df = make_plan(proto, seed=0, candidates=1000).to_frame()
    assert len(df) == 5 * 4 and df["pose"].nunique() == 5
    assert (df.groupby("pose")["load_case"].nunique() == 4).all()


def test_predicted_se_independent(kr_plan):
    """se_k = k^2 sqrt(diag((A^T S^-1 A)^-1)) with S per row: tracker noise (x sqrt(1.5):
    loaded minus the mean of two unloaded readings), F/T noise through the compliance
    J K^-1 J^T, encoder noise through a finite-difference derivative of C(q) w; 3 rows a test."""
    df = kr_plan.to_frame()
    q = df[[f"q{j}_model_deg" for j in range(1, 7)]].to_numpy() * DEG
    w = df[["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m"]].to_numpy()
    k = np.array([1409800, 400760, 935280, 360000, 370000, 380000.0])
    robot = kr_plan.robot

    def disp(qq, ww):
        J = jacobian(robot, qq)
        return J @ np.diag(1 / k) @ J.T @ ww

    info = np.zeros((6, 6))
    sd = np.r_[[30e-6] * 3, [20e-6] * 3] * np.sqrt(1.5)
    sw = np.r_[[0.5] * 3, [0.05] * 3]
    sq = np.radians(0.001) / np.sqrt(12)
    for qi, wi in zip(q, w, strict=True):
        J = jacobian(robot, qi)
        A = design_matrix(robot, qi[None], wi)
        C = J @ np.diag(1 / k) @ J.T
        G = np.stack([(disp(qi + 1e-6 * e, wi) - disp(qi - 1e-6 * e, wi)) / 2e-6
                      for e in np.eye(6)], axis=1)
        S = np.diag(sd**2) + C @ np.diag(sw**2) @ C.T + sq**2 * G @ G.T
        info += 3 * A.T @ np.linalg.solve(S, A)
    se_x = np.sqrt(np.diag(np.linalg.inv(info)))
    assert np.allclose(kr_plan.chosen.se, k**2 * se_x, rtol=1e-5)


def test_plan_directory_round_trip(tmp_path, kr_plan):
    write_plan(kr_plan, tmp_path / "p")
    protocol, df = read_plan(tmp_path / "p")
    assert protocol.model_dump() == kr_plan.protocol.model_dump()
    expected = kr_plan.to_frame()
    pd.testing.assert_frame_equal(df, expected, check_exact=False, atol=1e-3, rtol=1e-6)
    for name in ("plan.csv", "protocol.toml", "plan_map.png", "summary.txt", "summary.json"):
        assert (tmp_path / "p" / name).stat().st_size > 0
    text = (tmp_path / "p" / "summary.txt").read_text()
    assert "predicted standard error of k" in text


def test_byte_identical_plan(tmp_path, kr_protocol):
    out = []
    for name in ("a", "b"):
        plan = make_plan(kr_protocol, "d-optimal", seed=5, candidates=2000)
        write_plan(plan, tmp_path / name, figure=False)
        out.append([(tmp_path / name / f).read_bytes() for f in ("plan.csv", "summary.json")])
    assert out[0] == out[1]
    other = make_plan(kr_protocol, "d-optimal", seed=6, candidates=2000)
    write_plan(other, tmp_path / "c", figure=False)
    assert (tmp_path / "c" / "plan.csv").read_bytes() != out[0][0]


def test_byte_identical_across_processes_and_thread_counts(tmp_path):
    """Two fresh processes, one and two BLAS threads: the same plan.csv bytes."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    proto = Path(__file__).resolve().parents[2] / "protocols" / "kr240-2.toml"
    out = []
    for threads in ("1", "2"):
        env = dict(os.environ, OPENBLAS_NUM_THREADS=threads, OMP_NUM_THREADS=threads,
                   MKL_NUM_THREADS=threads)
        d = tmp_path / f"t{threads}"
        subprocess.run([sys.executable, "-m", "campaign", "plan", "--protocol", str(proto),
                        "--out", str(d), "--candidates", "3000", "--no-figure"],
                       check=True, env=env, capture_output=True)
        out.append((d / "plan.csv").read_bytes())
    assert out[0] == out[1]
