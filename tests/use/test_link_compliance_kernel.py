"""A model file with link compliance: ``campaign stiffness``, the maps' kernel and the kernel
(analysis/kinetostatics/link_compliance.py) give the same deflection, and an independent
computation written here from the equations agrees to 1e-9:

    C_X = J (K_theta - K_C)^-1 J^T + sum_l J_l C_l J_l^T,  dX = C_X w,

with J from Pinocchio at P (LOCAL_WORLD_ALIGNED), K_C = d(J^T w)/dq by central
differences of Pinocchio's Jacobian, the distal frame of link l from Pinocchio's joint
placements (joint l's frame times joint l+1's placement), and J_l written from the
rigid-body velocity of P under the frame's six virtual motions."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import tomli_w

from analysis.kinetostatics.link_compliance import deflection_with_links, links_of
from analysis.kinetostatics.maps import pose_metrics
from analysis.model.robot_files import load_robot_file
from campaign.jobs.stiffness import StiffnessOptions, run

ROBOTS = Path(__file__).resolve().parents[2] / "analysis" / "data" / "robots"
Q = np.radians([10.0, 60.0, -100.0, 30.0, 40.0, 20.0])
W = np.array([300.0, -2200.0, 1800.0, 150.0, -200.0, 90.0])


def _beam(length: float, ei: float, gj: float, ea: float, turn: float) -> np.ndarray:
    """A cantilever's 6 x 6 tip compliance along x, turned by ``turn`` rad about z."""
    c = np.zeros((6, 6))
    c[0, 0] = length / ea
    c[3, 3] = length / gj
    for f, mo, s in ((1, 5, 1.0), (2, 4, -1.0)):
        c[f, f] = length**3 / (3 * ei)
        c[mo, mo] = length / ei
        c[f, mo] = c[mo, f] = s * length**2 / (2 * ei)
    ct, st = np.cos(turn), np.sin(turn)
    R = np.array([[ct, -st, 0.0], [st, ct, 0.0], [0.0, 0.0, 1.0]])
    T = np.zeros((6, 6))
    T[:3, :3] = T[3:, 3:] = R
    return T @ c @ T.T


LINKS = {2: _beam(1.15, 2.1e11 * 2.4e-4, 8e10 * 3e-4, 2.1e11 * 1.2e-2, 0.3),
         3: _beam(1.2, 2.1e11 * 1.2e-4, 8e10 * 1.5e-4, 2.1e11 * 8e-3, -0.2)}


def _model_file(tmp_path) -> Path:
    data = tomllib.loads((ROBOTS / "kr240-2.toml").read_text())
    data.pop("aliases", None)
    data["model_class"] = {"version": 2, "name": "links",
                           "links": [{"link": k, "compliance": C.tolist()}
                                     for k, C in LINKS.items()]}
    path = tmp_path / "model.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def _independent(robot, q, k, w) -> np.ndarray:
    model = robot.model
    data = model.createData()

    def jac(qq):
        pin.computeJointJacobians(model, data, qq)
        pin.updateFramePlacements(model, data)
        return pin.getFrameJacobian(model, data, robot.tip_frame, pin.LOCAL_WORLD_ALIGNED)

    J = jac(q)
    h = 1e-7
    KC = np.zeros((6, 6))
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        KC[:, j] = (jac(q + dq).T @ w - jac(q - dq).T @ w) / (2 * h)
    C = J @ np.linalg.solve(np.diag(k) - KC, J.T)
    return C @ w + _independent_links(robot, q, w)


def _independent_links(robot, q, w) -> np.ndarray:
    """sum_l J_l C_l J_l^T w from Pinocchio's frames and the rigid-body velocity of P."""
    model = robot.model
    data = model.createData()
    C = np.zeros((6, 6))
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    p = data.oMf[robot.tip_frame].translation
    for link, Cl in LINKS.items():
        D = data.oMi[link] * model.jointPlacements[link + 1]  # joint link+1 before turning
        R, o = D.rotation, D.translation
        Jl = np.zeros((6, 6))
        for a in range(3):
            u = R[:, a]
            Jl[:3, a] = u                        # translation along the frame's axis a
            Jl[:3, 3 + a] = np.cross(u, p - o)   # rotation about it moves P on a circle
            Jl[3:, 3 + a] = u
        C = C + Jl @ Cl @ Jl.T
    return C @ w


def test_model_file_with_links_same_deflection_everywhere(tmp_path):
    path = _model_file(tmp_path)
    robot = load_robot_file(path)
    links = links_of(robot)
    assert [lc.link for lc in links] == [2, 3]
    k = robot.nominal_stiffness
    kernel = deflection_with_links(robot, Q, k, W, links)[0]
    job = np.array(run(StiffnessOptions(robot=str(path), q_rad=Q, wrench_N_Nm=W))
                   .deflection_m_rad)
    maps = pose_metrics(robot, Q[None], k, W, 1.0, threads=1)["deflection"][0]
    ref = _independent(robot, Q, k, W)
    scale = np.abs(ref).max()
    assert np.abs(job - kernel).max() <= 1e-9 * scale
    assert np.abs(maps - kernel).max() <= 1e-9 * scale
    assert np.abs(kernel - ref).max() <= 1e-9 * scale
    # the links matter here: without them the deflection differs by far more than 1e-9
    joints_only = np.array(run(StiffnessOptions(robot=str(ROBOTS / "kr240-2.toml"), q_rad=Q,
                                                wrench_N_Nm=W)).deflection_m_rad)
    assert np.abs(joints_only - kernel).max() > 0.01 * scale  # 0.26 mm of 16 mm here


def test_files_without_model_class_read_as_joint_springs(tmp_path):
    robot = load_robot_file(ROBOTS / "kr240-2.toml")
    assert robot.model_class is None and links_of(robot) == ()


def test_predicted_deflection_and_compensation_use_the_links(tmp_path):
    from analysis.kinetostatics.compensation import compensate
    from analysis.kinetostatics.uncertainty import predict_deflection
    from analysis.model.kinematics import chain_state, pose_difference, tool_pose

    robot = load_robot_file(_model_file(tmp_path))
    plain = load_robot_file(ROBOTS / "kr240-2.toml")
    k = robot.nominal_stiffness
    links = _independent_links(robot, Q, W)
    scale = np.abs(links).max()
    # the predicted (nonlinear) deflection gains exactly the links' part
    extra = predict_deflection(robot, Q, k, W).screw - predict_deflection(plain, Q, k, W).screw
    assert np.abs(extra - links).max() <= 1e-9 * scale
    # compensated joints: the joints' loaded pose plus the links' displacement (computed
    # here independently, at the commanded joints) lands on the target
    comp = compensate(robot, Q[None], k, W)
    q_cmd = comp.q_cmd[0]
    loaded = chain_state(robot, q_cmd + comp.dq[0]).tip
    miss = pose_difference(tool_pose(robot, Q), loaded) + _independent_links(robot, q_cmd, W)
    assert np.abs(miss).max() <= 1e-9 * np.abs(links).max()
    # and it differs from the joint-only compensation by about the links' deflection
    q_plain = compensate(plain, Q[None], k, W).q_cmd[0]
    assert np.abs(q_cmd - q_plain).max() > 1e-5


def test_place_recheck_uses_the_links(tmp_path):
    """``campaign place``'s re-check of a placement (analysis/placement/details.py): the
    joints' nonlinear equilibrium plus the links' displacement computed independently."""
    from analysis.kinetostatics.equilibrium import displacement_screw
    from tests.use._place_recheck import recheck

    robot = load_robot_file(_model_file(tmp_path))
    plain = load_robot_file(ROBOTS / "kr240-2.toml")
    k = robot.nominal_stiffness
    got, w = recheck(robot, k)
    ref, _ = recheck(plain, k)
    joints = displacement_screw(plain, got.q, k, w)[:, :3]
    links = np.array([_independent_links(robot, qi, wi)[:3] for qi, wi in zip(got.q, w,
                                                                              strict=True)])
    scale = np.abs(joints + links).max()
    assert np.abs(got.dp_nonlinear - (joints + links)).max() <= 1e-9 * scale
    assert np.abs(ref.dp_nonlinear - joints).max() <= 1e-9 * scale
    assert np.abs(links).max() > 1e-3 * scale  # the links matter here


def test_robustness_says_it_simulates_the_joint_springs_only(tmp_path):
    from campaign.jobs.robustness import RobustnessOptions
    from campaign.jobs.robustness import run as robustness

    notes: list[str] = []
    robustness(RobustnessOptions(robot=str(_model_file(tmp_path)), tests=(6,), trials=2,
                                 pool_size=20, method="ols"), note=notes.append)
    said = [n for n in notes if n.startswith("model class")]
    assert len(said) == 1 and "links 2, 3" in said[0] and "joint springs only" in said[0]
    notes.clear()
    robustness(RobustnessOptions(robot=str(ROBOTS / "kr240-2.toml"), tests=(6,), trials=2,
                                 pool_size=20, method="ols"), note=notes.append)
    assert not [n for n in notes if n.startswith("model class")]


ENTRIES = ["C2[2,2]", "C2[2,6]", "C2[5,5]", "C3[1,1]", "C3[3,5]"]


def _model_file_with_covariance(tmp_path) -> tuple[Path, np.ndarray, np.ndarray, np.ndarray]:
    """The links' model file plus a link covariance over ENTRIES (SPD, made here), a
    joint-compliance covariance cov_x and their cross-covariance: (path, cov_x, C_ll,
    C_xl (6, L))."""
    rng = np.random.default_rng(7)
    (tmp_path / "cov").mkdir()
    path = _model_file(tmp_path / "cov")
    data = tomllib.loads(path.read_text())
    scale = np.array([abs(LINKS[int(n[1])][int(n[3]) - 1, int(n[5]) - 1]) for n in ENTRIES])
    x = 1.0 / load_robot_file(ROBOTS / "kr240-2.toml").nominal_stiffness
    sd = np.concatenate([0.03 * x, 0.5 * scale])
    A = rng.normal(size=(11, 11))
    corr = A @ A.T + 11 * np.eye(11)
    corr /= np.sqrt(np.outer(np.diag(corr), np.diag(corr)))
    full = corr * np.outer(sd, sd)
    cov_x, C_xl, C_ll = full[:6, :6], full[:6, 6:], full[6:, 6:]
    data["model_class"]["link_covariance"] = {"parameters": ENTRIES, "matrix": C_ll.tolist(),
                                              "joint_cross": C_xl.tolist()}
    data["identification"] = {
        "quantity": "compliance", "covariance_unit": "(rad/(N m))^2",
        "covariance": cov_x.tolist(), "joints_identified": [1, 2, 3, 4, 5, 6],
        "method": "exact", "n_tests": 36, "source_run": "test", "date": "2026-01-01"}
    path.write_text(tomli_w.dumps(data))
    return path, cov_x, C_ll, C_xl


def _independent_CX(robot, q, x, links: dict) -> np.ndarray:
    """C_X = J (K - K_C)^-1 J^T + sum_l J_l C_l J_l^T (6, 6) from Pinocchio (as
    :func:`_independent`), for compliances x and link matrices ``links``."""
    model = robot.model
    data = model.createData()

    def jac(qq):
        pin.computeJointJacobians(model, data, qq)
        pin.updateFramePlacements(model, data)
        return pin.getFrameJacobian(model, data, robot.tip_frame, pin.LOCAL_WORLD_ALIGNED)

    J = jac(q)
    h = 1e-7
    KC = np.zeros((6, 6))
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        KC[:, j] = (jac(q + dq).T @ W - jac(q - dq).T @ W) / (2 * h)
    C = J @ np.linalg.solve(np.diag(1.0 / x) - KC, J.T)
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    p = data.oMf[robot.tip_frame].translation
    for link, Cl in links.items():
        D = data.oMi[link] * model.jointPlacements[link + 1]
        R, o = D.rotation, D.translation
        Jl = np.zeros((6, 6))
        for a in range(3):
            u = R[:, a]
            Jl[:3, a] = u
            Jl[:3, 3 + a] = np.cross(u, p - o)
            Jl[3:, 3 + a] = u
        C = C + Jl @ Cl @ Jl.T
    return C


def _perturbed(name: str, h: float) -> dict:
    out = {link: C.copy() for link, C in LINKS.items()}
    link, a, b = int(name[1]), int(name[3]) - 1, int(name[5]) - 1
    out[link][a, b] += h
    if a != b:
        out[link][b, a] += h
    return out


def test_link_covariance_propagated_into_deflection_and_K_X(tmp_path):
    """The deflection's covariance gains G C_ll G^T + S C_xl G^T + its transpose, G the
    derivative of the links' displacement in each entry (here by differences of the
    independent computation: exact, it is linear); diag(K_X)'s se equals the delta method
    on the independent C_X^-1 by central differences in every parameter."""
    from analysis.kinetostatics.uncertainty import predict_deflection

    path, cov_x, C_ll, C_xl = _model_file_with_covariance(tmp_path)
    robot = load_robot_file(path)
    k = robot.nominal_stiffness
    x = 1.0 / k
    base = _independent_CX(robot, Q, x, LINKS) @ W
    G = np.stack([(_independent_CX(robot, Q, x, _perturbed(n, 1.0)) @ W - base)
                  for n in ENTRIES], axis=-1)
    pred = predict_deflection(robot, Q, k, W, cov_x)
    plain = load_robot_file(_model_file(tmp_path))
    pred0 = predict_deflection(plain, Q, k, W, cov_x)  # the links, no covariance
    S = pred.sensitivity
    expect = G @ C_ll @ G.T + S @ C_xl @ G.T + G @ C_xl.T @ S.T
    got = pred.cov - pred0.cov
    assert np.abs(got - expect).max() <= 1e-9 * np.abs(expect).max()
    assert np.abs(expect).max() > 1e-3 * np.abs(pred0.cov).max()  # far above round-off
    # diag(K_X): the stiffness job's se against central differences of the independent
    # C_X^-1 in x_j and in each entry, with the full covariance
    job = run(StiffnessOptions(robot=str(path), q_rad=Q, wrench_N_Nm=W))
    full = np.block([[cov_x, C_xl], [C_xl.T, C_ll]])
    cols = []
    for j in range(6):
        hx = 1e-4 * x[j]
        up, dn = x.copy(), x.copy()
        up[j] += hx
        dn[j] -= hx
        cols.append((np.diag(np.linalg.inv(_independent_CX(robot, Q, up, LINKS)))
                     - np.diag(np.linalg.inv(_independent_CX(robot, Q, dn, LINKS)))) / (2 * hx))
    for n in ENTRIES:
        hl = 1e-4 * abs(LINKS[int(n[1])][int(n[3]) - 1, int(n[5]) - 1])
        cols.append((np.diag(np.linalg.inv(_independent_CX(robot, Q, x, _perturbed(n, hl))))
                     - np.diag(np.linalg.inv(_independent_CX(robot, Q, x, _perturbed(n, -hl)))))
                    / (2 * hl))
    D = np.stack(cols, axis=-1)
    se_ref = np.sqrt(np.einsum("ap,pr,ar->a", D, full, D))
    se = np.array(job.uncertainty["K_X_diag_se"])
    # rtol 1e-6: K_C is not symmetric (M^-1 used on both sides was 4e-5 off)
    assert np.allclose(se, se_ref, rtol=1e-6), (se, se_ref)
    K_X = np.diag(np.linalg.inv(_independent_CX(robot, Q, x, LINKS)))
    assert np.allclose(np.array(job.uncertainty["K_X_diag_lo95"]), K_X - 1.959963984540054 * se,
                       rtol=1e-7)


def test_maps_upper_bound_has_the_links_and_their_covariance(tmp_path):
    """``campaign maps --deflection-upper-bound``'s kernel: |dp| + 1.96 sd along dp, dp the
    linear deflection with K_C plus the links' (independent C_X w), sd by the delta method
    with the full covariance of (x, link entries), the derivatives here by central
    differences of the independent C_X w (the links' part is linear: exact)."""
    from analysis.kinetostatics.uncertainty import linear_deflection_upper_bound

    path, cov_x, C_ll, C_xl = _model_file_with_covariance(tmp_path)
    robot = load_robot_file(path)
    x = 1.0 / robot.nominal_stiffness
    base = _independent_CX(robot, Q, x, LINKS) @ W
    cols = []
    for j in range(6):
        h = 1e-4 * x[j]
        up, dn = x.copy(), x.copy()
        up[j] += h
        dn[j] -= h
        cols.append((_independent_CX(robot, Q, up, LINKS) @ W
                     - _independent_CX(robot, Q, dn, LINKS) @ W)[:3] / (2 * h))
    cols += [(_independent_CX(robot, Q, x, _perturbed(n, 1.0)) @ W - base)[:3]
             for n in ENTRIES]
    D = np.stack(cols, axis=-1)
    full = np.block([[cov_x, C_xl], [C_xl.T, C_ll]])
    dp = base[:3]
    u = dp / np.linalg.norm(dp)
    expect = np.linalg.norm(dp) + 1.959963984540054 * np.sqrt(u @ D @ full @ D.T @ u)
    got = linear_deflection_upper_bound(robot, Q, robot.nominal_stiffness, W, cov_x)
    assert abs(got - expect) <= 1e-7 * expect
    plain = linear_deflection_upper_bound(load_robot_file(ROBOTS / "kr240-2.toml"), Q,
                                          robot.nominal_stiffness, W, cov_x)
    assert abs(got - plain) > 1e-3 * expect  # the links and their covariance count


def test_compensation_applies_the_lost_motion_flank_offsets_and_names_unknown_ones(tmp_path):
    """A model file with lost motion: the compensated command is shifted by the flank
    offset so that the output (motor side plus the simulated lab's offset, its own flank
    rule with gravity deciding the flanks) lands on the joint-only compensation; joint 1
    (vertical axis) under a vertical force at P carries no torque: its offset is unknown,
    not applied, and named with the CSV line."""
    from analysis.kinetostatics.path_compensation import compensate_path
    from analysis.kinetostatics.realistic import RealisticLab, lost_motion_offset
    from campaign.use.compensate_output import lost_motion_text

    band = np.array([2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4])
    data = tomllib.loads((ROBOTS / "kr240-2.toml").read_text())
    data.pop("aliases", None)
    data["model_class"] = {"version": 2, "name": "lost-motion",
                           "lost_motion_rad": band.tolist()}
    path = tmp_path / "model.toml"
    path.write_text(tomli_w.dumps(data))
    robot = load_robot_file(path)
    plain = load_robot_file(ROBOTS / "kr240-2.toml")
    k = robot.nominal_stiffness
    q = np.stack([Q, Q + np.radians([5.0, -3.0, 4.0, 10.0, -8.0, 6.0]), Q])
    w = np.stack([W, -W, [0.0, 0.0, -1500.0, 0.0, 0.0, 0.0]])
    lines = np.array([2, 3, 4])
    got = compensate_path(robot, q, k, w, None, lines, "path.csv")
    ref = compensate_path(plain, q, k, w, None, lines, "path.csv")
    lab = RealisticLab(lost_motion=band, gravity="flanks")
    out = got.comp.q_cmd + lost_motion_offset(robot, lab, got.comp.q_cmd, w)
    known = ~got.flanks.unknown
    assert np.abs((out - ref.comp.q_cmd)[known]).max() <= 1e-12
    assert np.all(np.abs(got.comp.q_cmd - ref.comp.q_cmd)[known] >= 0.5 * np.broadcast_to(
        band, q.shape)[known] * (1 - 1e-9))
    # joint 6 too here: no moment and its axis meets the force's line through P
    assert got.flanks.unknown[2, 0] and not got.flanks.unknown[:2].any()
    assert got.comp.q_cmd[2, 0] == ref.comp.q_cmd[2, 0]
    text = lost_motion_text(got.flanks, lines)
    assert "NOT applied" in text and "line 4 (joint 1" in text
    assert not np.any(compensate_path(plain, q, k, w, None, lines, "p").flanks.offset)
