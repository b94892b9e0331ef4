"""place: the CLI and the web API find the same placement and write the same files."""

from __future__ import annotations

import json

import numpy as np

from tests.jobs.conftest import cli, cli_error

OPTIONS = {"x_mm": "1400..1800", "y_mm": "-200..200", "z_mm": "200", "x_step_mm": 200,
           "y_step_mm": 200, "tool_angle_step_deg": 30, "config": "-1,-1,-1",
           "wrench": "0,0,-500,0,0,0", "workers": 0}


def _part(ws) -> str:
    """An 8-point circle of radius 50 mm in the workpiece frame, tool axis down."""
    lines = ["x_mm,y_mm,z_mm,ax,ay,az"]
    for a in np.linspace(0, 2 * np.pi, 8, endpoint=False):
        lines.append(f"{50 * np.cos(a):.6f},{50 * np.sin(a):.6f},0,0,0,-1")
    (ws / "part.csv").write_text("\n".join(lines) + "\n")
    return "part.csv"


def _args(options: dict) -> list[str]:
    return [a for k, v in options.items() for a in (f"--{k.replace('_', '-')}", str(v))]


def test_place_same_placement_from_cli_and_api(ws, client):
    part = _part(ws)
    proc = cli(ws, "place", "--robot", "kr240-2", "--path", part, "--out", "cli",
               *_args(OPTIONS))
    assert proc.returncode == 0, proc.stderr
    answer = client.post("/api/jobs/place", json={"robot": "kr240-2", "path": part,
                                                  "out": "api", **OPTIONS})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    doc = json.loads((ws / "cli" / "placement.json").read_text())
    speed = ("run",)  # timings differ from run to run
    assert {k: v for k, v in got.items() if k not in speed} == \
        {k: v for k, v in doc.items() if k not in speed}
    assert (ws / "api" / "path_joints.csv").read_text() == \
        (ws / "cli" / "path_joints.csv").read_text()
    p = got["placement"]
    assert 1400 <= p["x_mm"] <= 1800 and -200 <= p["y_mm"] <= 200 and p["z_mm"] == 200


def test_place_refusals_same_line(ws, client):
    part = _part(ws)
    bad = {**OPTIONS, "x_mm": "1800..1400"}
    answer = client.post("/api/jobs/place", json={"robot": "kr240-2", "path": part,
                                                  "out": "o", **bad})
    assert answer.status_code == 400, answer.text
    assert answer.json()["detail"] == cli_error(ws, "place", "--robot", "kr240-2", "--path",
                                                part, "--out", "o", *_args(bad))
    assert not (ws / "o").exists()


def test_place_options_one_record_for_both_faces():
    """Every option of ``campaign place`` is a field of PlaceOptions with the record's
    default (what the web API uses for an omitted field), and the record's module, which
    the command line reads to build, imports no numerical library."""
    import dataclasses
    import subprocess
    import sys

    from campaign.cli.app import load_command
    from campaign.jobs.place import DEFAULTS, PlaceOptions

    cmd = load_command("place", "place")
    fields = {f.name: f for f in dataclasses.fields(PlaceOptions)}
    params = {p.name: p for p in cmd.params if p.name in fields}
    assert set(params) == set(fields)
    for name, f in fields.items():
        if f.default is dataclasses.MISSING:
            assert params[name].required, name
        else:
            assert params[name].default == f.default == DEFAULTS[name], name
    assert (DEFAULTS["x_step_mm"], DEFAULTS["tool_angle_deg"], DEFAULTS["objective"]) == \
        (100.0, "-180..180", "max")
    probe = ("import sys, campaign.jobs.place; print(sorted(m for m in ('numpy', 'rich', "
             "'campaign.use.place_run') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         timeout=60, check=True).stdout.strip()
    assert out == "[]"
