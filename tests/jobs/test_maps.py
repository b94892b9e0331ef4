"""maps: the CLI (deg) and the web API (rad) write the same table and summary."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from tests.jobs.conftest import cli_error, cli_json


def test_maps_same_files_from_cli_and_api(ws, client):
    doc = cli_json(ws, "maps", "--robot", "kr240-2", "--out", "cli", "--step", "15",
                   "--format", "csv", "--fixed", "10,0,0,20,30,40")
    answer = client.post("/api/jobs/maps", json={
        "robot": "kr240-2", "out": "api", "step_rad": float(np.radians(15)), "format": "csv",
        "fixed_rad": np.radians([10, 0, 0, 20, 30, 40]).tolist()})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    assert [f.replace("api/", "") for f in got["files"]] == \
        [f.replace("cli/", "") for f in doc["files"]]
    assert {k: v for k, v in got.items() if k != "files"} == \
        {k: v for k, v in doc.items() if k != "files"}
    assert got["grid_step_deg"] == 15
    for name in ("map_summary.json", "map_joint_space.csv"):
        assert (ws / "api" / name).read_text() == (ws / "cli" / name).read_text(), name
    table = pd.read_csv(ws / "api" / "map_joint_space.csv")
    assert len(table) == got["nodes"]
    summary = json.loads((ws / "api" / "map_summary.json").read_text())
    assert summary["max_v_p"] == table.loc[~table["singular"], "v_p"].max()


def test_maps_refusals_same_line(ws, client):
    for body, args in (
        ({"robot": "kr240-2", "out": "a", "step_rad": 0.0}, ["--out", "a", "--step", "0"]),
        ({"robot": "kr240-2", "out": "a", "length_m": -1.0}, ["--out", "a", "--length", "-1"]),
        ({"robot": "kr240-2", "out": "a", "step_rad": 0.3, "upper_bound": True},
         ["--out", "a", "--step", "17.188733853924695", "--deflection-upper-bound"]),
    ):
        answer = client.post("/api/jobs/maps", json=body)
        assert answer.status_code == 400, answer.text
        line = cli_error(ws, "maps", "--robot", "kr240-2", *args)
        assert answer.json()["detail"] == line
    assert not (ws / "a").exists()
