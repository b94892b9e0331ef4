"""A seven-joint arm (a URDF the project does not ship, Panda-like 7R) is refused in one line
by every command whose method needs a six-joint arm: before, `stiffness` raised numpy's
LinAlgError (J not square) and `robustness` and `maps` a reshape ValueError, as tracebacks."""

from __future__ import annotations

import pytest

from tests.refusal import assert_refused

#: seven revolute joints, axes alternating z and y, 0.3 m links, tool frame "tip"
_JOINT = """
  <link name="l{i}"/>
  <joint name="j{i}" type="revolute">
    <parent link="l{p}"/><child link="l{i}"/>
    <origin xyz="0 0 {z}" rpy="0 0 0"/><axis xyz="0 {ay} {az}"/>
    <limit lower="-2.9" upper="2.9" effort="100" velocity="2"/>
  </joint>"""


def _urdf(n: int) -> str:
    body = "".join(_JOINT.format(i=i, p=i - 1, z=0.3 if i > 1 else 0.1,
                                 ay=i % 2 == 0 and 1 or 0, az=i % 2 == 1 and 1 or 0)
                   for i in range(1, n + 1))
    return (f'<robot name="arm{n}"><link name="l0"/>{body}\n  <link name="tip"/>'
            f'<joint name="tip_joint" type="fixed"><parent link="l{n}"/><child link="tip"/>'
            '<origin xyz="0 0 0.1" rpy="0 0 0"/></joint></robot>')


K7 = ",".join(["1e4"] * 7)


@pytest.mark.parametrize("args", [
    ["stiffness", "--q", "0,30,0,-60,0,60,0", "--joint-stiffness", K7],
    ["robustness", "--tests", "5", "--trials", "10", "--joint-stiffness", K7,
     "--wrench", "0,20,20,2,2,0"],
    ["maps", "--joint-stiffness", K7, "--step", "30"],
])
def test_seven_joints_refused_in_one_line(tmp_path, capsys, args):
    urdf = tmp_path / "arm7.urdf"
    urdf.write_text(_urdf(7), encoding="utf-8")
    out = tmp_path / "out"
    extra = ["--out", str(out)] if args[0] in ("robustness", "maps") else []
    assert_refused(capsys, [args[0], "--robot", f"{urdf}#tip", *args[1:], *extra],
                   "--robot: arm7 has 7 joints: this method needs a six-joint arm",
                   watch=[tmp_path])


def test_analyze_refuses_before_printing_its_assumptions(tmp_path, capsys):
    """analyze names the joint count first (it printed the assumptions of a six-joint fit,
    "joints all six", before "the test format has 6")."""
    urdf = tmp_path / "arm7.urdf"
    urdf.write_text(_urdf(7), encoding="utf-8")
    csv = tmp_path / "tests.csv"
    csv.write_text("pose,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_N,fy_N,fz_N,mx_Nm,"
                   "my_Nm,mz_Nm,dx_mm,dy_mm,dz_mm,rx_mrad,ry_mrad,rz_mrad\n"
                   "1,0,30,0,-60,0,60,0,10,10,1,1,0,0.1,0.1,0.1,,,\n", encoding="utf-8")
    out = tmp_path / "out"
    assert_refused(capsys, ["analyze", "--measurements", str(csv), "--robot", f"{urdf}#tip",
                            "--out", str(out), "--no-report"],
                   "--robot: arm7 has 7 joints: this method needs a six-joint arm",
                   watch=[tmp_path])


def test_the_same_file_with_six_joints_is_accepted(tmp_path, capsys):
    """The refusal is about the joint count, not the hand-written URDF."""
    import json

    from campaign.cli import main

    urdf = tmp_path / "arm6.urdf"
    urdf.write_text(_urdf(6), encoding="utf-8")
    assert main(["stiffness", "--robot", f"{urdf}#tip", "--q", "0,30,-60,0,60,0",
                 "--joint-stiffness", ",".join(["1e4"] * 6), "--wrench", "10,0,0,0,0,0",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    J = doc["J_m_rad_per_rad"]
    assert len(J) == 6 and all(len(row) == 6 for row in J)


def test_sensitivity_job_refuses_seven_joints(tmp_path):
    """The GUI's sensitivity job (the paper's Fig. 6) loads its robot itself: the same
    refusal, naming its field, instead of a shape error deep in the simulated campaigns."""
    from analysis.errors import InputError
    from campaign.jobs.sensitivity import SensitivityOptions, run_sensitivity

    urdf = tmp_path / "arm7.urdf"
    urdf.write_text(_urdf(7), encoding="utf-8")
    with pytest.raises(InputError) as err:
        run_sensitivity(SensitivityOptions(robot=f"{urdf}#tip",
                                           joint_stiffness=[1e4] * 7))
    assert err.value.where == "robot"
    assert "arm7 has 7 joints: this method needs a six-joint arm" in str(err.value)
