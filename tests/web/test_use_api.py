"""``/api/use``: the Use view's file lists and program files, inside the workspace only."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

ROOT = Path(__file__).parents[2]


def test_files_lists_models_paths_and_analyses(client, workspace, tmp_path):
    shutil.copy(ROOT / "examples" / "kr240-2_path.csv", workspace / "p.csv")
    (workspace / "an").mkdir()
    (workspace / "an" / "results.json").write_text("{}")
    (workspace / "an" / "compensated.csv").write_text("point,q1_deg,q1_cmd_deg\n1,0,0\n")
    (workspace / "run").mkdir()  # a run's tests file (the import format) is not a path
    (workspace / "run" / "tests.csv").write_text(
        "pose,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_N,fy_N,fz_N,mx_Nm,my_Nm,mz_Nm,"
        "dx_mm,dy_mm,dz_mm,rx_mrad,ry_mrad,rz_mrad\n")
    outside = tmp_path / "outside.csv"
    outside.write_text("q1_deg\n0\n")
    os.symlink(outside, workspace / "link.csv")
    got = client.get("/api/use/files").json()
    assert "kr240-2" in got["builtin"]
    assert got["models"] == ["robot.toml"]  # the plan's protocol.toml is not a robot
    assert got["paths"] == ["p.csv"]  # not a compensation's output, a tests file, a link out
    assert got["analyses"] == ["an"]


def test_program_files_only_inside_the_workspace(client, workspace):
    (workspace / "c").mkdir()
    (workspace / "c" / "comp_path.src").write_text("DEF comp_path()\nEND\n")
    r = client.get("/api/use/program", params={"path": "c/comp_path.src"})
    assert r.status_code == 200 and r.text == "DEF comp_path()\nEND\n"
    for bad in ("../x.src", "/etc/passwd", "robot.toml", "c/none.src"):
        r = client.get("/api/use/program", params={"path": bad})
        assert r.status_code in (400, 422), (bad, r.status_code)
        assert "path" in r.json()["detail"] or r.json().get("where") == "path"


def test_export_writes_a_simulator_file_inside_the_workspace(client, workspace):
    """``POST /api/jobs/export``: the export job, answered at once; paths stay inside."""
    import xml.etree.ElementTree as ET

    r = client.post("/api/jobs/export", json={"robot": "robot.toml", "format": "sdf",
                                              "out": "robot.sdf"})
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc["file"] == "robot.sdf" and doc["stiffness_source"].startswith("nominal")
    springs = [float(e.text) for e in ET.parse(workspace / "robot.sdf").iter(
        "spring_stiffness")]
    assert springs == doc["stiffness_Nm_per_rad"] and len(springs) == 6
    r = client.post("/api/jobs/export", json={"robot": "ur10e", "format": "mjcf",
                                              "out": "u.xml"})
    assert r.status_code == 400 and "has no joint stiffness" in r.json()["detail"]
    assert not (workspace / "u.xml").exists()
    r = client.post("/api/jobs/export", json={"robot": "kr240-2", "format": "urdf",
                                              "out": "../k.urdf"})
    assert r.status_code == 400 and "out" in r.json()["detail"]
