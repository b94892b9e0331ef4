"""The exported MJCF checked by MuJoCo, an engine no one here wrote.

* Forward kinematics: MuJoCo's pose of the ``tool`` site equals the project's pose of P to
  1e-9 m (and 1e-9 in the rotation matrix) at 200 random poses, for every built-in robot,
  an identified model.toml and a URDF robot.
* Statics: with gravity off, the springs' reference at the pose and the test wrench applied
  at the tool site, MuJoCo's dynamics are let settle to rest (every joint velocity below
  1e-9 rad/s); the displacement of P then equals ``campaign stiffness``'s nonlinear
  deflection (the stiffness job's ``deflection_nonlinear_m_rad``) within 1 % or 1 um
  (rotation: 1 % or 1 urad) at 20 random dexterous poses (1/kappa_F of the normalized
  Jacobian >= 0.15) of the KR240-2, the UR10e and a model.toml identified by ``campaign
  analyze``; the KR240-2 with a spindle (P 0.29 m from the last body's origin, where its
  placeholder CoM is). The settling code is the example of docs/use.md, run from the
  document.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.maps import WORST_CASE_WRENCH
from analysis.model.kinematics import jacobian, rotation_vector, tool_pose
from analysis.model.robots import builtin_names, load_robot
from campaign.jobs.choices import SimFormat
from campaign.jobs.export import ExportOptions
from campaign.jobs.export import run as export
from campaign.jobs.stiffness import StiffnessOptions
from campaign.jobs.stiffness import run as stiffness
from tests.studies._z1 import URDF as Z1_URDF

mujoco = pytest.importorskip("mujoco")

DOC = Path(__file__).parents[2] / "docs" / "use.md"
#: spring-free robots (UR10e): test values of the order of a cobot's joints (N m/rad)
TEST_K = [90000.0, 90000.0, 40000.0, 12000.0, 12000.0, 12000.0]
#: a wrench a UR10e carries (N, N m at P, base frame)
UR_WRENCH = np.array([150.0, -120.0, 200.0, 15.0, -10.0, 12.0])
#: dexterous: 1/kappa_F of J normalized by the characteristic length (0.5 m without one)
MIN_INV_KAPPA = 0.15


def doc_example() -> dict:
    """The python block of docs/use.md's ``campaign export`` section, executed."""
    section = DOC.read_text().split("## `campaign export`", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    space: dict = {}
    exec(compile(code, str(DOC), "exec"), space)  # noqa: S102 (the document's own example)
    return space


def dexterous_poses(robot, count: int, seed: int) -> np.ndarray:
    lo, hi = robot.map_limits()
    rng = np.random.default_rng(seed)
    q = rng.uniform(lo, hi, size=(40 * count, robot.n))
    L = robot.characteristic_length or 0.5
    ok = inverse_condition(normalized_jacobian(jacobian(robot, q), L)) >= MIN_INV_KAPPA
    assert ok.sum() >= count
    return q[ok][:count]


@pytest.fixture(scope="module")
def example():
    return doc_example()["tool_deflection"]


#: a spindle on the KR240-2's flange (mm, deg): P away from the last body's origin, so that
#: the moment of xfrc_applied needs its correction from the body's CoM to P
SPINDLE = ([60.0, 0.0, 280.0], [0.0, 30.0, 0.0])


def _cases(identified: Path):
    """(robot, joint stiffness or None, wrench, tool xyz mm and rpy deg or None)."""
    return [("kr240-2", None, WORST_CASE_WRENCH, SPINDLE),
            ("ur10e", TEST_K, UR_WRENCH, None),
            (str(identified / "model.toml"), None, WORST_CASE_WRENCH, None)]


@pytest.mark.parametrize("case", [0, 1, 2], ids=["kr240-2", "ur10e", "model.toml"])
def test_mujoco_settles_at_campaign_stiffness_deflection(tmp_path, identified, example, case):
    spec, k, w, tool = _cases(identified)[case]
    xyz, rpy = tool or (None, None)
    path = export(ExportOptions(robot=spec, format=SimFormat.mjcf, out=tmp_path / "r.xml",
                                joint_stiffness_Nm_per_rad=k, tool_xyz_mm=xyz,
                                tool_rpy_deg=rpy)).file
    robot = load_robot(spec)
    worst_dp = worst_dr = 0.0
    sizes = []
    for q in dexterous_poses(robot, 20, seed=case):
        ours = np.array(stiffness(StiffnessOptions(
            robot=spec, q_rad=q.tolist(), joint_stiffness_Nm_per_rad=k, tool_xyz_mm=xyz,
            tool_rpy_deg=rpy, wrench_N_Nm=w.tolist())).deflection_nonlinear_m_rad)
        dp, dR, at_rest = example(path, q, w)
        assert at_rest
        err_p = np.linalg.norm(dp - ours[:3])
        err_r = np.linalg.norm(rotation_vector(dR) - ours[3:])
        assert err_p <= max(0.01 * np.linalg.norm(ours[:3]), 1e-6), (q, dp, ours)
        assert err_r <= max(0.01 * np.linalg.norm(ours[3:]), 1e-6), (q, dR, ours)
        worst_dp = max(worst_dp, err_p / np.linalg.norm(ours[:3]))
        worst_dr = max(worst_dr, err_r / np.linalg.norm(ours[3:]))
        sizes.append(np.linalg.norm(ours[:3]))
    # a real load: deflections of P from tenths of a mm up; the agreement is far inside 1 %
    assert min(sizes) > 1e-4
    assert worst_dp < 1e-6 and worst_dr < 1e-6, (worst_dp, worst_dr)


def test_a_wrong_sign_would_be_seen(tmp_path, example):
    """The comparison can fail: the opposite wrench moves P the other way by far more than 1 %."""
    path = export(ExportOptions(robot="kr240-2", format=SimFormat.mjcf,
                                out=tmp_path / "r.xml")).file
    q = dexterous_poses(load_robot("kr240-2"), 1, seed=7)[0]
    ours = np.array(stiffness(StiffnessOptions(
        robot="kr240-2", q_rad=q.tolist(), wrench_N_Nm=WORST_CASE_WRENCH.tolist()))
        .deflection_nonlinear_m_rad)
    dp, _, _ = example(path, q, -WORST_CASE_WRENCH)
    assert np.linalg.norm(dp - ours[:3]) > 1.5 * np.linalg.norm(ours[:3])


def _fk_specs():
    return builtin_names() + ["model.toml", f"{Z1_URDF}#gripperStator"]


@pytest.mark.parametrize("spec", _fk_specs())
def test_mujoco_forward_kinematics_equals_the_projects(tmp_path, identified, spec):
    spec = str(identified / "model.toml") if spec == "model.toml" else spec
    path = export(ExportOptions(robot=spec, format=SimFormat.mjcf, out=tmp_path / "r.xml",
                                no_springs=True)).file
    robot = load_robot(spec)
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    site = m.site("tool").id
    lo, hi = robot.map_limits()
    q = np.random.default_rng(5).uniform(lo, hi, size=(200, robot.n))
    ours = tool_pose(robot, q)
    worst_p = worst_r = 0.0
    for qi, T in zip(q, ours, strict=True):
        d.qpos[:] = qi
        mujoco.mj_kinematics(m, d)
        worst_p = max(worst_p, np.abs(d.site_xpos[site] - T[:3, 3]).max())
        worst_r = max(worst_r, np.abs(d.site_xmat[site].reshape(3, 3) - T[:3, :3]).max())
    assert worst_p < 1e-9 and worst_r < 1e-9
    assert np.allclose(m.jnt_range, np.column_stack([robot.lower, robot.upper]), rtol=0,
                       atol=0)
