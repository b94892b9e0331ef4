"""robustness: the CLI (um, urad, deg) and the web API (SI) give the same Monte-Carlo table."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from tests.jobs.conftest import cli_error, cli_json


def test_robustness_same_table_from_cli_and_api(ws, client):
    doc = cli_json(ws, "robustness", "--robot", "kr240-2", "--tests", "4,8", "--trials", "30",
                   "--pool-size", "60", "--seed", "2", "--method", "ols",
                   "--translation-sigma-um", "25", "--encoder-resolution-deg", "0.002",
                   "--out", "cli")
    answer = client.post("/api/jobs/robustness", json={
        "robot": "kr240-2", "tests": [8, 4], "trials": 30, "pool_size": 60, "seed": 2,
        "method": "ols",
        "translation_sigma_m": 25e-6, "encoder_resolution_rad": float(np.radians(0.002)),
        "out": "api"})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    assert [f.removeprefix("api/") for f in got.pop("files")] == \
        [f.removeprefix("cli/") for f in doc.pop("files")]
    assert got["noise"]["translation_sigma_um"] == pytest.approx(25, rel=1e-12)
    assert got["noise"].keys() == doc["noise"].keys()
    for key, value in doc["noise"].items():  # 25 * 1e-6 at the CLI's edge, 25e-6 here
        assert got["noise"][key] == (value if isinstance(value, str) else
                                     pytest.approx(value, rel=1e-12)), key
    got.pop("noise"), doc.pop("noise")
    assert got == doc
    assert got["tests"] == [4, 8] and len(got["results"]) == 2 * 6
    assert (ws / "api" / "robustness.csv").read_text() == \
        (ws / "cli" / "robustness.csv").read_text()
    table = pd.read_csv(ws / "api" / "robustness.csv")
    # more tests, less spread: for every joint the relative std at 8 tests is below that at 4
    wide = table.pivot(index="joint", columns="n_tests", values="relative_std")
    assert np.all(wide[8] < wide[4])
    assert json.loads((ws / "api" / "robustness.json").read_text())["trials"] == 30


@pytest.mark.parametrize(("body", "args"), [
    ({"tests": [0, 6]}, ["--tests", "0,6"]),
    ({"tests": [300]}, ["--tests", "300"]),
    ({"trials": 1}, ["--trials", "1"]),
    ({"pool_size": 5}, ["--pool-size", "5"]),
    ({"wrench_N_Nm": [1, 2]}, ["--wrench", "1,2"]),
])
def test_robustness_refusals_same_line(ws, client, body, args):
    answer = client.post("/api/jobs/robustness", json={"robot": "kr240-2", **body})
    assert answer.status_code == 400, answer.text
    assert answer.json()["detail"] == cli_error(ws, "robustness", "--robot", "kr240-2", *args)
