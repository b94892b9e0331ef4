"""``campaign export``: MJCF, URDF and SDF of every built-in robot and of an identified model.toml.

Checked by readers no one here wrote and by the project's own: the URDF read back by the
project's URDF reader and by yourdfpy gives the model's forward kinematics to 1e-9 m;
the SDF parses with xml.etree, uses only SDFormat 1.9 element names where the
specification allows them, and its poses composed give the same forward kinematics; the
springs hold the model's stiffness in each format. The MuJoCo checks (FK, static
deflection) are in test_export_mujoco.py.
"""

from __future__ import annotations

import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.model.kinematics import tool_pose
from analysis.model.robot_files import load_urdf
from analysis.model.robots import builtin_names, load_robot
from campaign.jobs.choices import SimFormat
from campaign.jobs.export import ExportOptions, run
from tests.jobs.conftest import cli_error
from tests.studies._z1 import URDF as Z1_URDF

FORMATS = {"mjcf": "xml", "urdf": "urdf", "sdf": "sdf"}

#: SDFormat 1.9 (sdformat's sdf/1.9/*.sdf): the children each element used here may have
SDF_19_CHILDREN = {
    "sdf": {"model", "world", "light", "actor"},
    "model": {"static", "self_collide", "allow_auto_disable", "include", "model",
              "enable_wind", "frame", "pose", "link", "joint", "plugin", "gripper"},
    "link": {"gravity", "enable_wind", "self_collide", "kinematic", "must_be_base_link",
             "velocity_decay", "frame", "pose", "inertial", "collision", "visual", "sensor",
             "projector", "audio_sink", "audio_source", "battery", "light", "particle_emitter"},
    "inertial": {"mass", "pose", "inertia"},
    "inertia": {"ixx", "ixy", "ixz", "iyy", "iyz", "izz"},
    "joint": {"parent", "child", "gearbox_ratio", "gearbox_reference_body", "thread_pitch",
              "axis", "axis2", "physics", "pose", "sensor"},
    "axis": {"initial_position", "xyz", "dynamics", "limit"},
    "dynamics": {"damping", "friction", "spring_reference", "spring_stiffness"},
    "limit": {"lower", "upper", "effort", "velocity", "stiffness", "dissipation"},
    "frame": {"pose"},
}
#: children the specification requires (required="1") of the elements written here
SDF_19_REQUIRED = {"joint": {"parent", "child"}, "axis": {"xyz", "limit"},
                   "limit": {"lower", "upper"},
                   "dynamics": {"spring_reference", "spring_stiffness"}}
#: spring-free robots get these (test values of the order of a cobot's joints, N m/rad)
TEST_K = [90000.0, 90000.0, 40000.0, 12000.0, 12000.0, 12000.0]


def export(out: Path, robot: str, fmt: str, **kw):
    return run(ExportOptions(robot=robot, format=SimFormat(fmt), out=out, **kw))


def random_q(robot, count: int, seed: int) -> np.ndarray:
    lo, hi = robot.map_limits()
    return np.random.default_rng(seed).uniform(lo, hi, size=(count, robot.n))


def rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    """R = Rz(y) Ry(p) Rx(r), written out (independent of the writer's Pinocchio call)."""
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation about a unit axis."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def sdf_tool_pose(root: ET.Element, q: np.ndarray) -> np.ndarray:
    """P (4, 4) in the base at joint angles q, composed from the SDF's own poses and axes."""
    model = root.find("model")

    def pose(el) -> np.ndarray:
        v = [float(s) for s in el.find("pose").text.split()]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = rpy_matrix(*v[3:]), v[:3]
        return T

    joints = {j.find("child").text: j for j in model.findall("joint")}
    T = np.eye(4)
    for i, qi in enumerate(q):
        link = model.find(f"link[@name='link{i + 1}']")
        assert link.find("pose").get("relative_to") == ("base" if i == 0 else f"link{i}")
        axis = [float(s) for s in joints[f"link{i + 1}"].find("axis/xyz").text.split()]
        R = np.eye(4)
        R[:3, :3] = axis_rotation(np.array(axis), qi)
        T = T @ pose(link) @ R
    tool = model.find("frame[@name='tool']")
    assert tool.get("attached_to") == f"link{len(q)}"
    return T @ pose(tool)


def check_sdf_names(el: ET.Element) -> None:
    allowed = SDF_19_CHILDREN.get(el.tag)
    tags = {c.tag for c in el}
    if allowed is not None:
        assert tags <= allowed, (el.tag, tags - allowed)
    assert SDF_19_REQUIRED.get(el.tag, set()) <= tags, (el.tag, tags)
    for child in el:
        check_sdf_names(child)


@pytest.mark.parametrize("key", builtin_names())
def test_every_builtin_robot_in_every_format(tmp_path, key):
    robot = load_robot(key)
    springs = {} if robot.nominal_stiffness is not None else {"joint_stiffness_Nm_per_rad":
                                                             TEST_K}
    k = robot.nominal_stiffness if robot.nominal_stiffness is not None else np.array(TEST_K)
    for fmt, suffix in FORMATS.items():
        res = export(tmp_path / f"{key}.{suffix}", key, fmt, **springs)
        root = ET.parse(res.file).getroot()
        assert root.tag == {"mjcf": "mujoco", "urdf": "robot", "sdf": "sdf"}[fmt]
        assert np.allclose(res.stiffness_Nm_per_rad, k, rtol=0, atol=0)
    # the springs, as each format spells them
    mjcf = ET.parse(tmp_path / f"{key}.xml").getroot()
    got = [float(j.get("stiffness")) for j in mjcf.iter("joint")]
    assert got == list(k) and all(j.get("springref") == "0" for j in mjcf.iter("joint"))
    sdf = ET.parse(tmp_path / f"{key}.sdf").getroot()
    assert [float(e.text) for e in sdf.iter("spring_stiffness")] == list(k)
    urdf = ET.parse(tmp_path / f"{key}.urdf").getroot()
    ext = {g.get("reference"): float(g.find("springStiffness").text)
           for g in urdf.findall("gazebo")}
    assert ext == {f"joint{i + 1}": k[i] for i in range(6)}
    assert "Plain URDF readers" in (tmp_path / f"{key}.urdf").read_text()


@pytest.mark.parametrize("key", [*builtin_names(), f"{Z1_URDF}#gripperStator"])
def test_urdf_read_back_gives_the_same_forward_kinematics(tmp_path, key):
    robot = load_robot(key)
    path = export(tmp_path / "r.urdf", key, "urdf", no_springs=True).file
    back = load_urdf(path, "tool")
    q = random_q(robot, 200, seed=1)
    err = np.abs(tool_pose(back, q) - tool_pose(robot, q))
    assert err[:, :3, 3].max() < 1e-9 and err[:, :3, :3].max() < 1e-9
    assert np.array_equal(back.lower, robot.lower) and np.array_equal(back.upper, robot.upper)
    # a second reader: yourdfpy (its own XML parser and transform chain)
    import yourdfpy

    u = yourdfpy.URDF.load(str(path), load_meshes=False, build_collision_scene_graph=False,
                           load_collision_meshes=False)
    assert u.validate()  # yourdfpy's own check of the URDF's structure
    assert u.actuated_joint_names == [f"joint{i}" for i in range(1, 7)]
    worst = 0.0
    for qi in q[:50]:
        u.update_cfg(qi)
        worst = max(worst, np.abs(u.get_transform("tool", "base") - tool_pose(robot, qi)).max())
    assert worst < 1e-9


@pytest.mark.parametrize("key", [*builtin_names(), f"{Z1_URDF}#gripperStator"])
def test_sdf_is_sdformat_19_and_gives_the_same_forward_kinematics(tmp_path, key):
    robot = load_robot(key)
    res = export(tmp_path / "r.sdf", key, "sdf", joint_stiffness_Nm_per_rad=TEST_K)
    root = ET.parse(res.file).getroot()
    assert root.tag == "sdf" and root.get("version") == "1.9"
    check_sdf_names(root)
    joints = root.find("model").findall("joint")
    assert [j.get("type") for j in joints] == ["fixed"] + ["revolute"] * 6
    lower = [float(j.find("axis/limit/lower").text) for j in joints[1:]]
    assert np.array_equal(lower, robot.lower)
    worst = 0.0
    for qi in random_q(robot, 200, seed=2):
        worst = max(worst, np.abs(sdf_tool_pose(root, qi) - tool_pose(robot, qi)).max())
    assert worst < 1e-9


def test_identified_model_carries_its_stiffness_report_id_and_says_what_it_leaves_out(
        tmp_path, identified):
    model = identified / "model.toml"
    robot = load_robot(str(model))
    results = json.loads((identified / "results.json").read_text())
    for fmt, suffix in FORMATS.items():
        res = export(tmp_path / f"m.{suffix}", str(model), fmt)
        text = res.file.read_text()
        assert res.report_id == results["report_id"] and results["report_id"] in text
        assert str(model) in text and "identified" in res.stiffness_source
        assert "covariance of the identified compliances" in text
        assert res.stiffness_Nm_per_rad == robot.nominal_stiffness.tolist()
    # the tool point of the run is the file's P
    back = load_urdf(tmp_path / "m.urdf", "tool")
    q = random_q(robot, 50, seed=3)
    assert np.abs(tool_pose(back, q) - tool_pose(robot, q)).max() < 1e-9


def test_urdf_robot_keeps_its_inertials(tmp_path):
    """A URDF's link masses reach the export (placeholders only where there are none)."""
    robot = load_robot(f"{Z1_URDF}#gripperStator")
    res = export(tmp_path / "z1.xml", f"{Z1_URDF}#gripperStator", "mjcf", no_springs=True)
    assert not res.placeholder_inertials
    masses = [float(b.find("inertial").get("mass")) for b in
              ET.parse(res.file).getroot().iter("body")]
    assert masses == pytest.approx([robot.model.inertias[i].mass for i in range(1, 7)],
                                   rel=1e-15)
    kr = export(tmp_path / "kr.xml", "kr240-2", "mjcf")
    assert kr.placeholder_inertials and "placeholder" in kr.file.read_text()


def test_tool_option_moves_the_tool_site(tmp_path):
    robot = load_robot("kr240-2")
    path = export(tmp_path / "t.urdf", "kr240-2", "urdf", tool_xyz_mm=[10, 20, 300],
                  tool_rpy_deg=[0, 90, 0]).file
    back = load_urdf(path, "tool")
    flange = load_urdf(path, "flange")
    q = random_q(robot, 20, seed=4)
    rel = np.linalg.inv(tool_pose(flange, q)) @ tool_pose(back, q)
    assert np.allclose(rel[:, :3, 3], [0.010, 0.020, 0.300], atol=1e-12)
    assert np.allclose(rel[:, :3, 2], [1, 0, 0], atol=1e-12)  # Ry(90 deg) turns z onto +x


def test_refusals_are_one_line(tmp_path):
    assert "has no joint stiffness" in cli_error(
        tmp_path, "export", "--robot", "ur10e", "--format", "mjcf", "--out", "u.xml")
    assert "contradict" in cli_error(
        tmp_path, "export", "--robot", "kr240-2", "--format", "mjcf", "--out", "u.xml",
        "--no-springs", "--joint-stiffness", ",".join(map(str, TEST_K)))
    assert "a .urdf name for a sdf file" in cli_error(
        tmp_path, "export", "--robot", "kr240-2", "--format", "sdf", "--out", "k.urdf")
    (tmp_path / "k.sdf").write_text("mine")
    assert "--force" in cli_error(
        tmp_path, "export", "--robot", "kr240-2", "--format", "sdf", "--out", "k.sdf")
    assert (tmp_path / "k.sdf").read_text() == "mine"
    os.symlink(tmp_path / "elsewhere.sdf", tmp_path / "link.sdf")
    assert "symbolic link" in cli_error(
        tmp_path, "export", "--robot", "kr240-2", "--format", "sdf", "--out", "link.sdf",
        "--force")
    assert not (tmp_path / "elsewhere.sdf").exists()
    with pytest.raises(InputError, match="expected 6"):
        export(tmp_path / "x.xml", "kr240-2", "mjcf", joint_stiffness_Nm_per_rad=[1e5] * 5)


def test_command_line_writes_and_reports(tmp_path):
    """``campaign export ... --json``: the job's record, SI units; the file is written."""
    import contextlib
    import io

    from campaign.cli import main

    out = io.StringIO()
    with contextlib.chdir(tmp_path), contextlib.redirect_stdout(out):
        assert main(["export", "--robot", "kr240-2", "--format", "mjcf", "--out", "k.xml",
                     "--json"]) == 0
    doc = json.loads(out.getvalue())
    assert doc["file"] == "k.xml" and doc["format"] == "mjcf" and doc["report_id"] is None
    assert doc["stiffness_Nm_per_rad"] == load_robot("kr240-2").nominal_stiffness.tolist()
    assert any("pendant" in item for item in doc["left_out"])
    assert ET.parse(tmp_path / "k.xml").getroot().tag == "mujoco"


def test_report_id_only_from_the_results_that_wrote_the_model(tmp_path, identified):
    """A model file copied under another name beside results.json is not the one it names."""
    import shutil

    shutil.copytree(identified, tmp_path / "an")
    shutil.copy(tmp_path / "an" / "model.toml", tmp_path / "an" / "edited.toml")
    assert export(tmp_path / "a.xml", str(tmp_path / "an" / "model.toml"), "mjcf").report_id
    res = export(tmp_path / "b.xml", str(tmp_path / "an" / "edited.toml"), "mjcf")
    assert res.report_id is None and "report_id: none" in res.file.read_text()
