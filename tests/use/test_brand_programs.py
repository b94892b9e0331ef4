"""ABB RAPID and FANUC ``.LS`` programs of ``campaign compensate`` and ``campaign place``,
parsed back by readers written here from the formats' public descriptions (RAPID:
``CONST jointtarget`` array literals and ``MoveAbsJ``; FANUC ASCII TP: ``/PROG``,
``/ATTR``, ``/MN`` numbered lines, ``/POS`` ``P[i]{ GP1: ... J1=.. deg ...}``, ``/END``),
every joint value compared with the command's own table in the controller's
convention to 0.001 deg."""

from __future__ import annotations

import csv
import re

import numpy as np
import pandas as pd
import pytest

from analysis.errors import InputError
from analysis.export.fanuc_tp import write_fanuc_ls
from analysis.export.rapid_program import write_rapid
from analysis.model.robots import load_robot
from campaign.cli import main

K = "1.2e6,1.5e6,7e5,2e5,1.8e5,1.2e5"
CMD = [f"q{j}_cmd_deg" for j in range(1, 7)]
TOL = 1e-3  # deg


def parse_rapid(text: str) -> tuple[str, np.ndarray, list[str]]:
    """Module name, robot axes (deg) of its jointtarget array, and its MoveAbsJ lines."""
    module = re.search(r"^MODULE (\w+)\s*$", text, re.M).group(1)
    assert re.search(r"^ENDMODULE\s*$", text, re.M)
    m = re.search(r"CONST jointtarget (\w+)\{(\d+)\} := \[(.*?)\];", text, re.S)
    name, n, body = m.group(1), int(m.group(2)), m.group(3)
    targets = re.findall(r"\[\[([^\]]*)\],\[([^\]]*)\]\]", body)
    assert len(targets) == n
    robax = np.array([[float(v) for v in rob.split(",")] for rob, _ in targets])
    assert all(ext.split(",") == ["9E+09"] * 6 for _, ext in targets)
    moves = re.findall(rf"MoveAbsJ {name}\{{(\w+)\}}, (\w+), (\w+), tool0;", text)
    return module, robax, [f"{i}:{z}" for i, _, z in moves]


def read(path) -> str:
    """A program's text with its CR LF line ends kept (both formats use them)."""
    raw = path.read_bytes().decode("ascii")
    assert "\r\n" in raw and "\n" not in raw.replace("\r\n", "")
    return raw


def parse_ls(text: str) -> tuple[str, np.ndarray, list[str]]:
    """Program name, J1..J6 (deg) of its /POS points, and the motion lines of /MN."""
    lines = text.split("\r\n")
    sections = [s for s in lines if s.startswith("/")]
    assert [s.split()[0] for s in sections] == ["/PROG", "/ATTR", "/MN", "/POS", "/END"]
    name = sections[0].split()[1]
    mn = lines[lines.index("/MN") + 1:lines.index("/POS")]
    numbers = [int(line.split(":")[0]) for line in mn]
    assert numbers == list(range(1, len(mn) + 1))
    count = re.search(r"LINE_COUNT\s*=\s*(\d+);", text)
    assert int(count.group(1)) == len(mn)
    assert all(line.rstrip().endswith(";") for line in mn)
    motions = re.findall(r"J P\[(\d+)\] (\d+)% (FINE|CNT\d+) ;", "\n".join(mn))
    pos = "\n".join(lines[lines.index("/POS") + 1:lines.index("/END")])
    points = re.findall(r"P\[(\d+)\]\{\s*GP1:\s*UF : \d+, UT : \d+,(.*?)\};", pos, re.S)
    q = []
    for k, (idx, body) in enumerate(points, start=1):
        assert int(idx) == k
        values = dict(re.findall(r"(J\d)=\s*([-\d.]+) deg", body))
        q.append([float(values[f"J{j}"]) for j in range(1, 7)])
    return name, np.array(q), [f"{i}:{t}" for i, _, t in motions]


def _path(tmp_path, robot, controller: bool) -> tuple:
    q0 = np.radians([0, 20, 30, 45, 45, 45])
    q1 = np.radians([20, 35, 15, 30, 60, 40])
    q = q0 + (q1 - q0) * np.linspace(0, 1, 7)[:, None]
    out = robot.to_controller(q) if controller else q
    csv_path = tmp_path / "path.csv"
    pd.DataFrame(np.degrees(out), columns=[f"q{j}_deg" for j in range(1, 7)]).to_csv(
        csv_path, index=False)
    return csv_path


@pytest.mark.parametrize("key, kind, controller", [
    ("r2000ic", "auto", False), ("r2000ic", "fanuc-ls", True), ("irb6640", "auto", True),
    ("irb6640", "rapid", False), ("r2000ic", "rapid", False)])
def test_compensate_programs_round_trip(tmp_path, key, kind, controller):
    robot = load_robot(key)
    path = _path(tmp_path, robot, controller)
    out = tmp_path / "out"
    args = ["compensate", "--robot", key, "--joint-stiffness", K, "--path", str(path),
            "--out", str(out), "--wrench", "200,-500,-900,40,20,10", "--program", kind]
    assert main(args + (["--controller-angles"] if controller else [])) == 0
    table = pd.read_csv(out / "compensated.csv")[CMD].to_numpy()
    q_ctrl = table if controller else np.degrees(robot.to_controller(np.radians(table)))
    fmt = kind if kind != "auto" else ("fanuc-ls" if key == "r2000ic" else "rapid")
    if fmt == "rapid":
        module, q, moves = parse_rapid(read(out / "comp_path.mod"))
        assert module == "comp_path"
        assert moves == ["1:fine", "i:z1", "7:fine"]
        assert "Robot model: " + robot.name in read(out / "comp_path.mod")
    else:
        name, q, moves = parse_ls(read(out / "COMP_PATH.LS"))
        assert name == "COMP_PATH"
        assert moves == ["1:FINE", *[f"{i}:CNT10" for i in range(2, 7)], "7:FINE"]
    assert q.shape == (7, 6)
    np.testing.assert_allclose(q, q_ctrl, atol=TOL, rtol=0)
    # the model's angles differ from the pendant's where the model says so
    model = table if not controller else np.degrees(robot.from_controller(np.radians(table)))
    if key == "r2000ic":  # J3 relative to the horizontal, J6 reversed
        np.testing.assert_allclose(q[:, 2], model[:, 2] - model[:, 1], atol=TOL)
        np.testing.assert_allclose(q[:, 5], -model[:, 5], atol=TOL)
        assert np.max(np.abs(q[:, 2] - model[:, 2])) > 10
    else:
        np.testing.assert_allclose(q, model, atol=TOL)


@pytest.mark.parametrize("key, kind, name", [("r2000ic", "auto", "PLACE_PATH.LS"),
                                             ("irb6640", "rapid", "place_path.mod")])
def test_place_programs_round_trip(tmp_path, key, kind, name):
    t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    part = tmp_path / "part.csv"
    part.write_text("x_mm,y_mm,z_mm,ax,ay,az\n" + "".join(
        f"{50 * np.cos(a):.6f},{50 * np.sin(a):.6f},0,0,0,-1\n" for a in t))
    out = tmp_path / "out"
    assert main(["place", "--robot", key, "--joint-stiffness", K, "--path", str(part),
                 "--out", str(out), "--x-mm", "1400..1800", "--y-mm", "-200..200",
                 "--z-mm", "400", "--x-step-mm", "200", "--y-step-mm", "200",
                 "--tool-angle-step-deg", "30", "--wrench", "400,250,-300,0,0,20",
                 "--workers", "0", "--program", kind]) == 0
    robot = load_robot(key)
    rows = list(csv.DictReader((out / "path_joints.csv").open()))
    q_model = np.radians([[float(r[f"q{j}_deg"]) for j in range(1, 7)] for r in rows])
    q_ctrl = np.degrees(robot.to_controller(q_model))
    text = read(out / name)
    q = parse_ls(text)[1] if name.endswith(".LS") else parse_rapid(text)[1]
    np.testing.assert_allclose(q, q_ctrl, atol=TOL, rtol=0)
    remarks = " ".join(re.findall(r"! (.*?) ;", text)) if name.endswith(".LS") else text
    assert "the path is not compensated" in " ".join(remarks.split())
    assert "process wrench: --wrench 400,250,-300,0,0,20" in " ".join(remarks.split())


def test_writers_refuse_bad_names_and_targets(tmp_path):
    with pytest.raises(InputError, match="RAPID name"):
        write_rapid(tmp_path / "x.mod", "1bad", np.zeros((2, 6)))
    with pytest.raises(InputError, match="finite"):
        write_rapid(tmp_path / "x.mod", "ok", np.full((2, 6), np.nan))
    with pytest.raises(InputError, match="FANUC program name"):
        write_fanuc_ls(tmp_path / "X.LS", "bad name", np.zeros((2, 6)))
    with pytest.raises(InputError, match="1..100"):
        write_fanuc_ls(tmp_path / "X.LS", "OK", np.zeros((2, 6)), speed_percent=0)
    for n in (1, 2, 3):  # no FOR loop without middle points (RAPID's FOR counts down)
        written = write_rapid(tmp_path / f"m{n}.mod", f"m{n}", np.full((n, 6), 1.5))
        _, q, moves = parse_rapid(read(written))
        assert q.shape == (n, 6)
        assert moves == {1: ["1:fine"], 2: ["1:fine", "2:fine"],
                         3: ["1:fine", "i:z1", "3:fine"]}[n]
    name, q, moves = parse_ls(read(write_fanuc_ls(tmp_path / "ONE.LS", "one",
                                                  np.array([[1, 2, 3, 4, 5, -179.9996]]),
                                                  comments=["a; b " * 20])))
    assert name == "ONE" and moves == ["1:FINE"]
    np.testing.assert_allclose(q, [[1, 2, 3, 4, 5, -180.0]], atol=0)
