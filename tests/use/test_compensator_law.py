"""A model file with the axis-2 compensator law (``[model_class] compensator = {c1, c2,
q2ref_rad}``): ``campaign stiffness``, the maps' kernel, the predicted deflection and
``campaign compensate`` (and the GUI's API, which calls the stiffness job) take joint 2's
compliance x2(q2) = 1/k2 + c1 t + c2 t^2, t = q2 - q2ref, and agree to 1e-9 with an
independent computation written here from the equations:

    dX = J (K_theta(q) - K_C)^-1 J^T w,   K_theta(q) = diag(k1, 1/x2(q2), k3, ..., k6),

J from Pinocchio at P (LOCAL_WORLD_ALIGNED), K_C = d(J^T w)/dq by central differences of
Pinocchio's Jacobian; the compensated joints checked by solving the equilibrium
K_theta(q_cmd) dq = J(q_cmd + dq)^T w here by fixed-point iteration."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import tomli_w

from analysis.errors import InputError
from analysis.kinetostatics.compensator_law import (
    compensator_law_of,
    pose_stiffness,
)
from analysis.kinetostatics.maps import pose_metrics
from analysis.model.robot_files import load_robot_file
from campaign.jobs.stiffness import StiffnessOptions, run

ROBOTS = Path(__file__).resolve().parents[2] / "analysis" / "data" / "robots"
W = np.array([300.0, -2200.0, 1800.0, 150.0, -200.0, 90.0])
Q2REF = np.radians(40.0)
#: several q2 (deg) across the joint range [0, 146] deg, q2ref among them
Q2_DEG = (5.0, 25.0, 40.0, 75.0, 120.0)


def _q(q2_deg: float) -> np.ndarray:
    return np.radians([10.0, q2_deg, -100.0, 30.0, 40.0, 20.0])


def _model_file(tmp_path: Path, c1_rel: float = 0.4, c2_rel: float = 0.3) -> Path:
    """kr240-2 with a compensator law: c1 = c1_rel x2 per rad, c2 = c2_rel x2 per rad^2
    (x2 = 1/k2 of the file), q2ref = 40 deg."""
    data = tomllib.loads((ROBOTS / "kr240-2.toml").read_text())
    data.pop("aliases", None)
    x2 = 1.0 / load_robot_file(ROBOTS / "kr240-2.toml").nominal_stiffness[1]
    data["model_class"] = {"version": 2, "name": "compensator",
                           "compensator": {"c1": c1_rel * x2, "c2": c2_rel * x2,
                                           "q2ref_rad": float(Q2REF)}}
    path = tmp_path / "model.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def _law_k(k: np.ndarray, q: np.ndarray, c1: float, c2: float) -> np.ndarray:
    """K_theta's diagonal at q from the equations: 1/x with x2 = 1/k2 + c1 t + c2 t^2."""
    t = q[1] - Q2REF
    x = 1.0 / k
    x[1] = x[1] + c1 * t + c2 * t * t
    return 1.0 / x


def _jac(robot, q):
    model = robot.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    return pin.getFrameJacobian(model, data, robot.tip_frame, pin.LOCAL_WORLD_ALIGNED)


def _independent(robot, q, kq, w) -> np.ndarray:
    J = _jac(robot, q)
    h = 1e-7
    KC = np.zeros((6, 6))
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        KC[:, j] = (_jac(robot, q + dq).T @ w - _jac(robot, q - dq).T @ w) / (2 * h)
    return J @ np.linalg.solve(np.diag(kq) - KC, J.T @ w)


def _tip(robot, q) -> pin.SE3:
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    return data.oMf[robot.tip_frame].copy()


def test_same_deflection_everywhere_and_as_the_equations(tmp_path):
    path = _model_file(tmp_path)
    robot = load_robot_file(path)
    law = compensator_law_of(robot)
    assert law is not None and law.q2ref == pytest.approx(Q2REF, abs=0)
    k = robot.nominal_stiffness
    plain = load_robot_file(ROBOTS / "kr240-2.toml")
    from analysis.kinetostatics.uncertainty import predict_deflection

    qs = np.array([_q(a) for a in Q2_DEG])
    maps = pose_metrics(robot, qs, k, W, 1.0, threads=1)["deflection"]
    pred = predict_deflection(robot, qs, k, W).screw  # what compensate/path use
    moved = 0.0
    for i, q in enumerate(qs):
        kq = _law_k(k.copy(), q, law.c1, law.c2)
        ref = _independent(robot, q, kq, W)
        scale = np.abs(ref).max()
        doc = run(StiffnessOptions(robot=str(path), q_rad=q, wrench_N_Nm=W))
        job = np.array(doc.deflection_m_rad)
        assert np.abs(job - ref).max() <= 1e-9 * scale
        assert np.abs(maps[i] - job).max() <= 1e-9 * scale
        # the nonlinear deflection: the stiffness job's and the predicted one's agree
        assert np.abs(np.array(doc.deflection_nonlinear_m_rad) - pred[i]).max() <= 1e-9 * scale
        assert doc.compensator["k2_at_q2_Nm_per_rad"] == pytest.approx(kq[1], rel=1e-12)
        assert np.abs(1.0 / pose_stiffness(robot, q, k) - 1.0 / kq).max() <= 1e-15
        base = np.array(run(StiffnessOptions(robot=str(ROBOTS / "kr240-2.toml"), q_rad=q,
                                             wrench_N_Nm=W)).deflection_m_rad)
        moved = max(moved, np.abs(base - job).max() / scale)
    # the law matters here: away from q2ref the deflection moves by far more than 1e-9
    assert moved > 0.01
    assert plain.model_class is None and compensator_law_of(plain) is None


def test_k2_at_q2ref_is_the_files_exactly_and_no_law_is_bit_for_bit(tmp_path):
    path = _model_file(tmp_path)
    robot = load_robot_file(path)
    k = robot.nominal_stiffness
    q = _q(float(np.degrees(Q2REF)))
    q[1] = Q2REF
    assert pose_stiffness(robot, q, k)[1] == k[1]
    got = run(StiffnessOptions(robot=str(path), q_rad=q, wrench_N_Nm=W)).to_json()
    plain = run(StiffnessOptions(robot=str(ROBOTS / "kr240-2.toml"), q_rad=q,
                                 wrench_N_Nm=W)).to_json()
    assert got["compensator"]["k2_at_q2_Nm_per_rad"] == k[1]
    for key in ("deflection_m_rad", "deflection_nonlinear_m_rad", "K_X"):
        assert got[key] == plain[key]  # bit for bit: k2(q2ref) is k2
    # a file without the law: the very same k, no new arithmetic
    plain_robot = load_robot_file(ROBOTS / "kr240-2.toml")
    assert pose_stiffness(plain_robot, np.array([_q(0.0)]), k) is k
    assert "compensator" not in plain


def test_compensation_lands_on_target_with_the_law(tmp_path):
    from analysis.kinetostatics.compensation import compensate

    robot = load_robot_file(_model_file(tmp_path))
    plain = load_robot_file(ROBOTS / "kr240-2.toml")
    law = compensator_law_of(robot)
    k = robot.nominal_stiffness
    qs = np.array([_q(a) for a in (10.0, 75.0)])
    comp = compensate(robot, qs, k, W)
    for i, q in enumerate(qs):
        q_cmd = comp.q_cmd[i]
        kq = _law_k(k.copy(), q_cmd, law.c1, law.c2)  # at the commanded q2
        dq = np.zeros(6)
        for _ in range(200):  # K dq = J(q_cmd + dq)^T w by fixed-point iteration
            new = _jac(robot, q_cmd + dq).T @ W / kq
            if np.abs(new - dq).max() < 1e-16:
                break
            dq = new
        miss = pin.log6(_tip(robot, q).actInv(_tip(robot, q_cmd + dq))).vector
        assert np.abs(miss).max() <= 1e-9
        assert np.abs(dq - comp.dq[i]).max() <= 1e-12
    q_plain = compensate(plain, qs, k, W).q_cmd
    assert np.abs(comp.q_cmd - q_plain).max() > 1e-5


def test_a_law_leaving_its_range_is_refused_in_one_line(tmp_path):
    # c1 = -2 x2 per rad: x2(q2) = x2 (1 - 2 t) <= 0 from t = 0.5 rad (q2 >= 68.6 deg)
    path = _model_file(tmp_path, c1_rel=-2.0, c2_rel=0.0)
    robot = load_robot_file(path)
    k = robot.nominal_stiffness
    with pytest.raises(InputError) as e:
        run(StiffnessOptions(robot=str(path), q_rad=_q(90.0), wrench_N_Nm=W))
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg and "q2 = 90.0000 deg" in msg
    assert "leaves its range" in msg
    with pytest.raises(InputError, match=r"pose \(1,\) q2 = 80.0000 deg"):
        pose_metrics(robot, np.array([_q(20.0), _q(80.0)]), k, W, 1.0, threads=1)
    # inside its range the same file computes
    assert run(StiffnessOptions(robot=str(path), q_rad=_q(50.0), wrench_N_Nm=W)).K_X


def _loaded_translation(robot, q, kq, w) -> np.ndarray:
    """p(q + dq) - p(q) (3,) (m), K_theta dq = J(q + dq)^T w solved by fixed-point
    iteration (the nonlinear deflection from the equations)."""
    dq = np.zeros(6)
    for _ in range(200):
        new = _jac(robot, q + dq).T @ w / kq
        if np.abs(new - dq).max() < 1e-16:
            break
        dq = new
    return _tip(robot, q + dq).translation - _tip(robot, q).translation


def test_compensate_and_maps_jobs_with_the_law(tmp_path):
    """The ``compensate`` job's predicted deflection (and so the GUI's, which queues the
    same job) and the ``maps`` job's deflection column against the equations; both say
    the law and that its c1, c2 are taken as exact in the intervals."""
    import json

    import pandas as pd

    from campaign.jobs.compensate import CompensateOptions
    from campaign.jobs.compensate import run as compensate_job
    from campaign.jobs.maps import MapsOptions
    from campaign.jobs.maps import run as maps_job
    from campaign.use.path_file import Q_COLS, W_COLS

    path = _model_file(tmp_path)
    data = tomllib.loads(path.read_text())
    x = 1.0 / load_robot_file(ROBOTS / "kr240-2.toml").nominal_stiffness
    data["identification"] = {
        "quantity": "compliance", "covariance_unit": "(rad/(N m))^2",
        "covariance": np.diag((0.03 * x) ** 2).tolist(), "joints_identified": [1, 2, 3, 4, 5, 6],
        "method": "exact", "n_tests": 36, "source_run": "test", "date": "2026-01-01"}
    path.write_text(tomli_w.dumps(data))
    robot = load_robot_file(path)
    law = compensator_law_of(robot)
    k = robot.nominal_stiffness
    qs = np.array([_q(a) for a in (15.0, 40.0, 70.0, 100.0)])
    frame = pd.DataFrame(np.degrees(qs), columns=Q_COLS)
    frame.insert(0, "label", [f"p{i}" for i in range(len(qs))])
    for j, c in enumerate(W_COLS):
        frame[c] = W[j]
    csv = tmp_path / "path.csv"
    frame.to_csv(csv, index=False)
    res = compensate_job(CompensateOptions(robot=str(path), path=str(csv),
                                           out=tmp_path / "comp"))
    table = pd.read_csv(tmp_path / "comp" / "compensated.csv")
    got = 1e-3 * table[["dx_mm", "dy_mm", "dz_mm"]].to_numpy()
    for i, q in enumerate(qs):
        ref = _loaded_translation(robot, q, _law_k(k.copy(), q, law.c1, law.c2), W)
        assert np.abs(got[i] - ref).max() <= 1e-9 * np.abs(ref).max()
    said = json.dumps(res.summary["assumptions"])
    assert "compensator law" in said and "taken as exact" in said
    # maps: one node per q2 of Q2_DEG's grid (q3 at -100 deg), the deflection's norm
    out = maps_job(MapsOptions(robot=str(path), out=tmp_path / "maps", step_rad=np.radians(35.0),
                               fixed_rad=_q(0.0).tolist(), wrench_N_Nm=W.tolist(),
                               length_m=1.0, format="csv", upper_bound=True))
    grid = pd.read_csv(out.data_file)
    assert "compensator law" in out.summary["compensator_law"]
    assert "taken as exact" in out.summary["deflection_upper95_method"]
    for _, row in grid.iloc[::7].iterrows():
        q = _q(row["theta2_deg"])
        q[2] = np.radians(row["theta3_deg"])
        ref = _independent(robot, q, _law_k(k.copy(), q, law.c1, law.c2), W)
        assert abs(row["deflection_mm"] - 1e3 * np.linalg.norm(ref[:3])) <= (
            1e-9 * 1e3 * np.abs(ref).max())


def _file_with_law_covariance(tmp_path: Path, links: bool) -> tuple[Path, np.ndarray]:
    """The law's model file plus [identification] cov_x, the law's covariance (c1, c2) and,
    with ``links``, the links and link entries of tests/use/test_link_compliance_kernel.py
    with their covariance and the law's link_cross: (path, the full covariance over
    (x1..x6, link entries..., c1, c2), SPD, made here)."""
    from tests.use.test_link_compliance_kernel import ENTRIES, LINKS

    path = _model_file(tmp_path)
    data = tomllib.loads(path.read_text())
    x = 1.0 / load_robot_file(ROBOTS / "kr240-2.toml").nominal_stiffness
    comp = data["model_class"]["compensator"]
    ent = ENTRIES if links else []
    lsd = [0.5 * abs(LINKS[int(n[1])][int(n[3]) - 1, int(n[5]) - 1]) for n in ent]
    sd = np.concatenate([0.03 * x, lsd, [0.2 * abs(comp["c1"]), 0.2 * abs(comp["c2"])]])
    m = sd.size
    A = np.random.default_rng(11).normal(size=(m, m))
    corr = A @ A.T + m * np.eye(m)
    corr /= np.sqrt(np.outer(np.diag(corr), np.diag(corr)))
    full = corr * np.outer(sd, sd)
    L = len(ent)
    data["identification"] = {
        "quantity": "compliance", "covariance_unit": "(rad/(N m))^2",
        "covariance": full[:6, :6].tolist(), "joints_identified": [1, 2, 3, 4, 5, 6],
        "method": "exact", "n_tests": 36, "source_run": "test", "date": "2026-01-01"}
    cc = {"parameters": ["c1", "c2"], "matrix": full[6 + L:, 6 + L:].tolist(),
          "joint_cross": full[:6, 6 + L:].tolist()}
    if links:
        data["model_class"]["links"] = [{"link": k, "compliance": C.tolist()}
                                        for k, C in LINKS.items()]
        data["model_class"]["link_covariance"] = {
            "parameters": ent, "matrix": full[6:6 + L, 6:6 + L].tolist(),
            "joint_cross": full[:6, 6:6 + L].tolist()}
        cc["link_cross"] = full[6:6 + L, 6 + L:].tolist()
    data["model_class"]["compensator_covariance"] = cc
    path.write_text(tomli_w.dumps(data))
    return path, full


def test_law_covariance_propagated_into_the_intervals(tmp_path):
    """The maps' upper bound and the predicted deflection's covariance with the law's
    (c1, c2) covariance: the delta method on the equations, derivatives by central
    differences of the independent computation in (x1..x6, c1, c2)."""
    from analysis.kinetostatics.uncertainty import linear_deflection_upper_bound, predict_deflection

    path, full = _file_with_law_covariance(tmp_path, links=False)
    robot = load_robot_file(path)
    law = compensator_law_of(robot)
    k = robot.nominal_stiffness
    cov_x = robot.compliance_covariance
    q = _q(110.0)
    p0 = np.concatenate([1.0 / k, [law.c1, law.c2]])

    def kq(p):
        return _law_k(1.0 / p[:6], q, p[6], p[7])

    def diff(f):
        cols = []
        for j in range(8):
            h = 1e-4 * abs(p0[j])
            up, dn = p0.copy(), p0.copy()
            up[j] += h
            dn[j] -= h
            cols.append((f(up) - f(dn)) / (2 * h))
        return np.stack(cols, axis=-1)

    dp = _independent(robot, q, kq(p0), W)[:3]
    D = diff(lambda p: _independent(robot, q, kq(p), W)[:3])
    u = dp / np.linalg.norm(dp)
    expect = np.linalg.norm(dp) + 1.959963984540054 * np.sqrt(u @ D @ full @ D.T @ u)
    got = linear_deflection_upper_bound(robot, q, k, W, cov_x)
    assert abs(got - expect) <= 1e-7 * expect
    # the nonlinear deflection's covariance (translation block)
    Dn = diff(lambda p: _loaded_translation(robot, q, kq(p), W))
    pred = predict_deflection(robot, q, k, W, cov_x)
    ref = Dn @ full @ Dn.T
    assert np.abs(pred.cov[:3, :3] - ref).max() <= 1e-6 * np.abs(ref).max()
    # c1, c2's covariance counts here (the same file without it: c1, c2 exact)
    data = tomllib.loads(path.read_text())
    del data["model_class"]["compensator_covariance"]
    (tmp_path / "exact").mkdir()
    exact = tmp_path / "exact" / "model.toml"
    exact.write_text(tomli_w.dumps(data))
    plain = linear_deflection_upper_bound(load_robot_file(exact), q, k, W, cov_x)
    assert got - plain > 1e-3 * (got - np.linalg.norm(dp))
    doc = run(StiffnessOptions(robot=str(exact), q_rad=q, wrench_N_Nm=W)).uncertainty
    assert "taken as exact" in doc["method"]
    doc = run(StiffnessOptions(robot=str(path), q_rad=q, wrench_N_Nm=W)).uncertainty
    assert "compensator_covariance" in doc["method"]


def test_law_and_link_covariance_in_the_stiffness_se(tmp_path):
    """diag(K_X)'s se of the stiffness job with links and the law, both with covariance
    (and their cross terms): the delta method on the independent C_X^-1 by central
    differences in every parameter (x1..x6, link entries, c1, c2)."""
    from tests.use.test_link_compliance_kernel import (
        ENTRIES,
        LINKS,
        _independent_CX,
        _perturbed,
    )
    from tests.use.test_link_compliance_kernel import W as W_LINKS

    assert np.array_equal(W, W_LINKS)  # _independent_CX's K_C is under this wrench
    path, full = _file_with_law_covariance(tmp_path, links=True)
    robot = load_robot_file(path)
    law = compensator_law_of(robot)
    q = _q(100.0)
    x = 1.0 / robot.nominal_stiffness
    t = q[1] - Q2REF

    def kx(xx, c1, c2, links):
        xq = xx.copy()
        xq[1] += c1 * t + c2 * t * t
        return np.diag(np.linalg.inv(_independent_CX(robot, q, xq, links)))

    cols = []
    for j in range(6):
        h = 1e-4 * x[j]
        up, dn = x.copy(), x.copy()
        up[j] += h
        dn[j] -= h
        cols.append((kx(up, law.c1, law.c2, LINKS) - kx(dn, law.c1, law.c2, LINKS)) / (2 * h))
    for n in ENTRIES:
        h = 1e-4 * abs(LINKS[int(n[1])][int(n[3]) - 1, int(n[5]) - 1])
        cols.append((kx(x, law.c1, law.c2, _perturbed(n, h))
                     - kx(x, law.c1, law.c2, _perturbed(n, -h))) / (2 * h))
    h1, h2 = 1e-4 * abs(law.c1), 1e-4 * abs(law.c2)
    cols.append((kx(x, law.c1 + h1, law.c2, LINKS) - kx(x, law.c1 - h1, law.c2, LINKS))
                / (2 * h1))
    cols.append((kx(x, law.c1, law.c2 + h2, LINKS) - kx(x, law.c1, law.c2 - h2, LINKS))
                / (2 * h2))
    D = np.stack(cols, axis=-1)
    se_ref = np.sqrt(np.einsum("ap,pr,ar->a", D, full, D))
    job = run(StiffnessOptions(robot=str(path), q_rad=q, wrench_N_Nm=W))
    se = np.array(job.uncertainty["K_X_diag_se"])
    assert np.allclose(se, se_ref, rtol=1e-6), (se, se_ref)
    # both the law's covariance and its cross terms with the links count here (1e-2 of se)
    data = tomllib.loads(path.read_text())
    data["model_class"]["compensator_covariance"].pop("link_cross")
    path.write_text(tomli_w.dumps(data))
    no_cross = np.array(run(StiffnessOptions(robot=str(path), q_rad=q, wrench_N_Nm=W))
                        .uncertainty["K_X_diag_se"])
    assert np.abs(se / no_cross - 1).max() > 1e-3


def test_model_file_keeps_the_laws_covariance(tmp_path):
    """``model_class_table`` writes [model_class.compensator_covariance] from the chosen
    candidate's covariance (its c1, c2 block, their rows against x1..x6 and the link
    entries, scaled by prediction_sigma_scale^2 when the misfit was accepted), and the
    written file reads back with the law and its covariance."""
    from types import SimpleNamespace

    from analysis.identification.io.model_export import model_class_table
    from analysis.kinetostatics.compensator_law import law_covariance_of

    names = ["x1", "x2", "x3", "x5", "C2[1,1]", "c1", "c2"]  # x4, x6 not fitted
    A = np.random.default_rng(3).normal(size=(7, 7))
    M = A @ A.T * 1e-14
    cand = {"model": "compensator+links", "covariance": {"parameters": names,
                                                         "matrix": M.tolist()},
            "parameters": [{"name": "c1", "value": 2e-8}, {"name": "c2", "value": -1e-8},
                           {"name": "C2[1,1]", "value": 1e-9}],
            "compensator_q2ref_rad": 0.7, "link_compliance": {"2": np.eye(6).tolist()}}
    for accepted, s in ((False, 1.0), (True, 1.5)):
        result = SimpleNamespace(misfit_accepted=accepted, assumptions={"model_classes": {
            "chosen": "compensator+links", "asked": "auto", "rule": "test",
            "prediction_sigma_scale": 1.5, "candidates": [cand]}})
        table = model_class_table(result)
        cc = table["compensator_covariance"]
        assert cc["parameters"] == ["c1", "c2"]
        assert np.array_equal(cc["matrix"], s**2 * M[5:, 5:])
        cross = np.array(cc["joint_cross"])
        assert np.array_equal(cross[[0, 1, 2, 4]], s**2 * M[:4, 5:])
        assert not cross[[3, 5]].any()
        assert np.array_equal(cc["link_cross"], s**2 * M[4:5, 5:])
    assert table["compensator"] == {"c1": 2e-8, "c2": -1e-8, "q2ref_rad": 0.7}
    data = tomllib.loads((ROBOTS / "kr240-2.toml").read_text())
    data.pop("aliases", None)
    table["links"][0]["compliance"] = (1e-9 * np.eye(6)).tolist()
    data["model_class"] = table
    path = tmp_path / "model.toml"
    path.write_text(tomli_w.dumps(data))
    robot = load_robot_file(path)
    got = law_covariance_of(robot)
    assert got[0] == ("c1", "c2") and np.array_equal(got[1], 1.5**2 * M[5:, 5:])
    assert compensator_law_of(robot).q2ref == 0.7


def test_a_path_point_beyond_the_law_is_refused_with_its_line(tmp_path):
    from analysis.kinetostatics.path_compensation import compensate_path, predict_path

    robot = load_robot_file(_model_file(tmp_path, c1_rel=-2.0, c2_rel=0.0))
    q = np.array([_q(20.0), _q(50.0), _q(85.0)])
    lines = np.array([2, 3, 4])
    for fn in (predict_path, compensate_path):
        with pytest.raises(InputError) as e:
            fn(robot, q, robot.nominal_stiffness, W, None, lines, "path.csv")
        msg = str(e.value)
        assert msg.startswith("path.csv:4 (point 3)") and "\n" not in msg
        assert "q2 = 85.0000 deg" in msg and "model.toml" in msg
    doc = run(StiffnessOptions(robot=str(_model_file(tmp_path)), q_rad=_q(75.0),
                               wrench_N_Nm=W))
    assert "compensator law at q2 = 75 deg" in doc.joint_stiffness_source


def test_a_law_covariance_not_matching_the_links_is_refused(tmp_path):
    path, _ = _file_with_law_covariance(tmp_path, links=True)
    data = tomllib.loads(path.read_text())
    data["model_class"]["compensator_covariance"]["link_cross"].pop()
    path.write_text(tomli_w.dumps(data))
    with pytest.raises(Exception, match="link_cross has 4 rows, link_covariance 5"):
        load_robot_file(path)


def test_place_recheck_takes_k2_of_the_law(tmp_path):
    """``campaign place``'s re-check of a placement (analysis/placement/details.py) takes
    k2(q2) of the law at each point: the joints' equilibrium with K_theta from the
    equations here (:func:`_law_k`), not the file's constant k2."""
    from analysis.kinetostatics.equilibrium import displacement_screw
    from tests.use._place_recheck import recheck

    robot = load_robot_file(_model_file(tmp_path))
    plain = load_robot_file(ROBOTS / "kr240-2.toml")
    k = robot.nominal_stiffness
    law = robot.model_class["compensator"]
    got, w = recheck(robot, k)
    ref, _ = recheck(plain, k)
    kq = np.array([_law_k(k, qi, law["c1"], law["c2"]) for qi in got.q])
    expected = displacement_screw(plain, got.q, kq, w)[:, :3]
    scale = np.abs(expected).max()
    assert np.abs(got.dp_nonlinear - expected).max() <= 1e-9 * scale
    # the law matters at these points (q2 away from q2ref), and the plain file is unchanged
    assert np.abs(got.dp_nonlinear - ref.dp_nonlinear).max() > 1e-3 * scale
    assert np.abs(np.degrees(got.q[:, 1] - law["q2ref_rad"])).min() > 1.0
