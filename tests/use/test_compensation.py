"""campaign compensate: equilibrium compensation, refusals, programs, the fake-lab check."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from analysis.errors import InputError
from analysis.export.robot_programs import write_krl, write_urscript
from analysis.kinetostatics.compensation import compensate
from analysis.kinetostatics.equilibrium import solve_deflection
from analysis.kinetostatics.path_compensation import compensate_path
from analysis.kinetostatics.uncertainty import predict_deflection
from analysis.model.kinematics import pin_tool_pose, pose_difference, tool_pose
from analysis.model.robots import builtin_names, load_robot
from campaign.cli import main
from campaign.use.path_file import Q_COLS, W_COLS

PROTOCOL = "protocols/kr240-2.toml"


def _path_points(robot, count: int, seed: int, span: float = 1.0) -> np.ndarray:
    """A smooth joint-space path between two well-conditioned poses (model rad).

    The end poses are drawn from ``seed``; draws whose straight joint-space path passes
    near a singularity (1/kappa_F < 0.05 anywhere) are skipped, deterministically.
    """
    from analysis.identification.studies.robustness import sample_poses
    from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
    from analysis.model.kinematics import jacobian

    length = robot.characteristic_length or 1.0
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, count)[:, None]
    for _ in range(50):
        ends = sample_poses(robot, 2, rng, min_inverse_condition=0.25, length=length)
        q = ends[0] + span * (ends[1] - ends[0]) * t
        if inverse_condition(normalized_jacobian(jacobian(robot, q), length)).min() >= 0.05:
            return q
    raise AssertionError("no well-conditioned path in 50 draws")


@pytest.mark.parametrize("key", builtin_names())
def test_residual_below_1um_on_every_point_for_every_builtin_robot(key):
    robot = load_robot(key)
    k = robot.nominal_stiffness if robot.nominal_stiffness is not None else np.full(6, 2e5)
    q = _path_points(robot, 25, seed=3)
    reach = np.linalg.norm(tool_pose(robot, q)[:, :3, 3], axis=1).max()
    w = np.array([300.0, -500.0, 400.0, 20.0, 10.0, -15.0]) * min(1.0, reach)
    comp = compensate(robot, q, k, w)
    # independent check: Pinocchio's FK at q_cmd + dq against the unloaded target
    dq = solve_deflection(robot, comp.q_cmd, k, w)
    for i in range(len(q)):
        e = pose_difference(pin_tool_pose(robot, q[i]), pin_tool_pose(robot, comp.q_cmd[i] + dq[i]))
        assert np.linalg.norm(e[:3]) < 1e-6 and np.linalg.norm(e[3:]) < 1e-6
    # the correction is not the first-order one: q_cmd differs from q - dq(q)
    first = q - solve_deflection(robot, q, k, w)
    assert np.abs(comp.q_cmd - q).max() > 0
    assert np.abs(first - comp.q_cmd).max() > 1e-3 * np.abs(comp.q_cmd - q).max()


def _write_path(path, q_deg, w=None):
    frame = pd.DataFrame(q_deg, columns=Q_COLS)
    frame.insert(0, "label", [f"p{i}" for i in range(len(q_deg))])
    if w is not None:
        for j, c in enumerate(W_COLS):
            frame[c] = w[:, j]
    frame.to_csv(path, index=False)


def test_refusals_name_the_line(tmp_path):
    robot = load_robot("kr240-2")
    q = _path_points(robot, 6, seed=4)
    w = np.array([0, 1000.0, -1000, 50, 0, 0])
    lines = np.arange(6) + 2
    bad = q.copy()
    bad[3, 1] = robot.upper[1] + 0.01
    with pytest.raises(InputError, match=r"p.csv:5 \(point 4\).*outside the joint limits"):
        compensate_path(robot, bad, robot.nominal_stiffness, w, None, lines, "p.csv")
    sing = q.copy()
    sing[2, 4] = 0.0  # wrist singularity of the KR240-2: q5 = 0
    with pytest.raises(InputError, match=r"p.csv:4 \(point 3\).*singularity"):
        compensate_path(robot, sing, robot.nominal_stiffness, w, None, lines, "p.csv")
    csv = tmp_path / "p.csv"
    _write_path(csv, np.degrees(q))
    frame = pd.read_csv(csv).astype({"q3_deg": object})
    frame.loc[1, "q3_deg"] = "abc"
    frame.to_csv(csv, index=False)
    assert main(["compensate", "--robot", "kr240-2", "--path", str(csv), "--out",
                 str(tmp_path / "o"), "--wrench", "0,1000,0,0,0,0"]) == 2
    _write_path(csv, np.degrees(q))
    assert main(["compensate", "--robot", "kr240-2", "--path", str(csv), "--out",
                 str(tmp_path / "o")]) == 2  # no wrench at all


def test_cli_outputs_and_wrench_frames(tmp_path):
    robot = load_robot("kr240-2")
    q = _path_points(robot, 12, seed=5)
    w_tool = np.array([100.0, -400.0, 900.0, 10.0, -20.0, 5.0])
    R = tool_pose(robot, q)[:, :3, :3]
    w_base = np.concatenate([R @ w_tool[:3], R @ w_tool[3:]], axis=1)
    q_ctrl = np.degrees(robot.to_controller(q))
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    _write_path(a, q_ctrl, w_base)
    _write_path(b, q_ctrl)
    common = ["--robot", "kr240-2", "--controller-angles"]
    assert main(["compensate", *common, "--path", str(a), "--out", str(tmp_path / "A")]) == 0
    assert main(["compensate", *common, "--path", str(b), "--out", str(tmp_path / "B"),
                 "--wrench", ",".join(map(str, w_tool)), "--wrench-frame", "tool"]) == 0
    ta = pd.read_csv(tmp_path / "A" / "compensated.csv")
    tb = pd.read_csv(tmp_path / "B" / "compensated.csv")
    cmd = [f"q{j}_cmd_deg" for j in range(1, 7)]
    assert np.allclose(ta[cmd], tb[cmd], atol=1e-9)
    assert list(ta["label"]) == [f"p{i}" for i in range(12)]
    # pendant convention out: back to the model, and compare with the library
    q_cmd = robot.from_controller(np.radians(ta[cmd].to_numpy()))
    comp = compensate(robot, q, robot.nominal_stiffness, w_base)
    assert np.allclose(q_cmd, comp.q_cmd, atol=1e-10)
    pred = predict_deflection(robot, q, robot.nominal_stiffness, w_base)
    assert np.allclose(ta[["dx_mm", "dy_mm", "dz_mm"]], 1e3 * pred.screw[:, :3], atol=1e-9)
    assert (ta["residual_um"] < 1).all() and (ta["residual_urad"] < 1).all()
    # the KRL program holds the compensated joints in the pendant convention
    dat = (tmp_path / "A" / "comp_path.dat").read_text()
    axes = re.findall(r"XPATH\[(\d+)\]=\{A1 ([-\d.]+),A2 ([-\d.]+),A3 ([-\d.]+),A4 ([-\d.]+),"
                      r"A5 ([-\d.]+),A6 ([-\d.]+)", dat)
    assert len(axes) == 12
    assert np.allclose(np.array(axes, float)[:, 1:], ta[cmd].to_numpy(), atol=1e-6)
    assert "FOR I = 2 TO 12" in (tmp_path / "A" / "comp_path.src").read_text()
    summary = json.loads((tmp_path / "A" / "summary.json").read_text())
    n = np.linalg.norm(pred.screw[:, :3], axis=1)
    assert summary["translation_m"]["before"]["max"] == pytest.approx(n.max(), rel=1e-12)
    assert summary["worst_point"]["line"] == int(np.argmax(n)) + 2


def test_urscript_for_ur_models(tmp_path):
    robot = load_robot("ur10e")
    q = _path_points(robot, 5, seed=6, span=0.05)
    csv = tmp_path / "u.csv"
    _write_path(csv, np.degrees(q))
    assert main(["compensate", "--robot", "ur10e", "--joint-stiffness",
                 "2e5,2e5,2e5,1e5,1e5,1e5", "--path", str(csv), "--out", str(tmp_path / "U"),
                 "--wrench", "0,0,-100,0,0,0"]) == 0
    script = (tmp_path / "U" / "comp_path.script").read_text()
    rows = re.findall(r"movej\(\[([^\]]+)\]", script)
    assert len(rows) == 5
    table = pd.read_csv(tmp_path / "U" / "compensated.csv")
    q_cmd = np.radians(table[[f"q{j}_cmd_deg" for j in range(1, 7)]].to_numpy())
    assert np.allclose(np.array([r.split(",") for r in rows], float), q_cmd, atol=1e-8)


def test_program_writers_validate_names_and_targets(tmp_path):
    with pytest.raises(InputError, match="KRL name"):
        write_krl(tmp_path, "1bad", np.zeros((2, 6)))
    with pytest.raises(InputError, match="finite"):
        write_urscript(tmp_path / "x.script", "x", np.full((1, 6), np.nan))
    src, dat = write_krl(tmp_path, "p", np.ones((3, 6)))
    assert dat.read_text().count("E6AXIS XPATH[3]") == 1 and src.suffix == ".src"


def test_fake_lab_verification_on_the_demo(tmp_path):
    """Demo campaign -> model.toml -> compensate --verify-fake: after <= 10 % of before."""
    assert main(["demo", "--out", str(tmp_path / "demo"), "--quiet", "--no-report"]) == 0
    model = tmp_path / "demo" / "run" / "analysis" / "model.toml"
    robot = load_robot(str(model))
    q = _path_points(robot, 30, seed=7)
    csv = tmp_path / "path.csv"
    _write_path(csv, np.degrees(q))
    out = tmp_path / "out"
    assert main(["compensate", "--robot", str(model), "--path", str(csv), "--out", str(out),
                 "--wrench", "0,1000,-1500,100,50,0", "--verify-fake", "--protocol", PROTOCOL,
                 "--readings", "4"]) == 0
    check = json.loads((out / "summary.json").read_text())["verify_fake"]
    assert check["before"]["rms_m"] > 1e-3  # the load deflects the arm by millimetres
    assert check["ratio_rms_translation"] <= 0.10
    assert check["after"]["rms_rad"] <= 0.10 * check["before"]["rms_rad"]


# --- bad-input corpus (issue 20): refusals with one line, nothing written ---


def _corpus_path(tmp_path, header_extra=""):
    robot = load_robot("kr240-2")
    csv = tmp_path / "p.csv"
    _write_path(csv, np.degrees(_path_points(robot, 4, seed=4)))
    if header_extra:
        lines = csv.read_text().splitlines()
        csv.write_text("\n".join([lines[0] + header_extra,
                                  *(row + ",0" for row in lines[1:])]) + "\n")
    return csv


def test_duplicated_joint_column_refused(tmp_path, capsys):
    """pandas would read the second q1_deg as q1_deg.1 and use the first: a guess."""
    from tests.refusal import assert_refused

    csv = _corpus_path(tmp_path, ",q1_deg")
    assert pd.read_csv(csv).columns[-1] == "q1_deg.1"  # what pandas makes of it
    assert_refused(capsys, ["compensate", "--robot", "kr240-2", "--path", csv, "--out",
                            tmp_path / "o", "--wrench", "0,1000,0,0,0,0"],
                   f"{csv}:1: column 'q1_deg' appears more than once", watch=[tmp_path])


@pytest.mark.parametrize("wrench, message", [
    ("", "--wrench: empty value"), ("0,1000,,0,0,0", "--wrench: item 3 is empty")])
def test_empty_wrench_refused(tmp_path, capsys, wrench, message):
    from tests.refusal import assert_refused

    csv = _corpus_path(tmp_path)
    assert_refused(capsys, ["compensate", "--robot", "kr240-2", "--path", csv, "--out",
                            tmp_path / "o", "--wrench", wrench], message, watch=[tmp_path])


def test_second_tool_point_on_a_flange_model_refused(tmp_path, capsys):
    """docs/use.md: a model.toml's P is the run's tool point; with P at the flange a tool
    option is a second tool point and is refused (the same one, 0,0,0, is accepted)."""
    from tests.refusal import assert_refused
    from tests.use.test_model_file import _with_identification

    model = _with_identification(tmp_path, 1e-15 * np.eye(6))
    csv = _corpus_path(tmp_path)
    base = ["compensate", "--robot", model, "--path", csv, "--wrench", "0,1000,0,0,0,0"]
    for tool in (["--tool-xyz-mm", "0,0,100"], ["--tool-rpy-deg", "0,30,0"]):
        assert_refused(capsys, [*base, "--out", tmp_path / "o", *tool],
                       f"{model}: this identified model (model.toml) has P at the flange",
                       watch=[tmp_path])
    assert_refused(capsys, ["stiffness", "--robot", model, "--q", "15,50,-195,30,40,20",
                            "--tool-xyz-mm", "0,0,100"], "a second tool point (xyz [0.0, "
                   "0.0, 100.0] mm, rpy [0.0, 0.0, 0.0] deg) is refused", watch=[tmp_path])
    assert main([*base, "--out", str(tmp_path / "same"), "--tool-xyz-mm", "0,0,0"]) == 0
    # the nominal built-in model takes a tool point
    assert main([*base[:2], "kr240-2", *base[3:], "--out", str(tmp_path / "nominal"),
                 "--tool-xyz-mm", "0,0,100"]) == 0
