"""demo: the CLI and the web API give the same results.json on the seeded simulated lab.

The simulated lab draws every reading's noise from (seed, instrument, test, repeat,
phase, sample), not from the wall clock, so two demos with the same options measure
the same numbers; only the report id (which hashes the time-stamped tests.csv) differs.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.protocol import load_protocol
from campaign.shipped_protocols import shipped_protocol
from tests.jobs.conftest import cli, cli_error

pytestmark = pytest.mark.timeout(240)
#: a small demo: 3 test poses of 3 repeats, a short candidate draw, fast simulated time
SMALL = {"tests": 3, "candidates": 500, "time_scale": 1000.0, "report": False}
SMALL_ARGS = ("--tests", "3", "--candidates", "500", "--time-scale", "1000", "--no-report")


def _results(path) -> dict:
    doc = json.loads(path.read_text())
    doc.pop("report_id")  # a hash over the run's files, time stamps included
    return doc


def test_demo_same_results_from_cli_and_api(ws, client):
    proc = cli(ws, "demo", "--out", "cli", *SMALL_ARGS, "--json")
    assert proc.returncode == 0, proc.stderr
    from_cli = json.loads(proc.stdout)
    answer = client.post("/api/jobs/demo", json={"out": "api", **SMALL})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    assert got["status"] == from_cli["status"] == "complete"
    assert got["acquisition"]["ok"] == 9 and got["acquisition"]["failed"] == 0
    assert got["plan"]["plan_file"] == "api/plan/plan.csv"
    cli_results = _results(ws / "cli" / "run" / "analysis" / "results.json")
    api_results = _results(ws / "api" / "run" / "analysis" / "results.json")
    k_cli = np.array(cli_results["joint_stiffness_Nm_per_rad"])
    k_api = np.array(api_results["joint_stiffness_Nm_per_rad"])
    np.testing.assert_array_equal(k_api, k_cli)
    assert api_results["ci95_Nm_per_rad"] == cli_results["ci95_Nm_per_rad"]
    assert api_results["chi2_reduced"] == cli_results["chi2_reduced"]
    # the whole documents agree but for the files' own paths
    drop = ("files", "run", "model_file")
    assert {k: v for k, v in api_results.items() if k not in drop} == \
        {k: v for k, v in cli_results.items() if k not in drop}
    # the answer is results.json; and the lab's true stiffness is inside the 95 % intervals
    assert got["analysis"]["joint_stiffness_Nm_per_rad"] == list(k_api)
    true_k = np.array(load_protocol(shipped_protocol("kr240-2")).lab["true_joint_stiffness"])
    ci = np.array(api_results["ci95_Nm_per_rad"])
    assert np.all(ci[:, 0] < true_k) and np.all(true_k < ci[:, 1]), (ci, true_k)
    assert np.all(np.abs(k_api / true_k - 1) < 0.05)


def test_demo_refusals_same_line(ws, client):
    (ws / "full").mkdir()
    (ws / "full" / "x.txt").write_text("not empty")
    (ws / "bare.toml").write_text(shipped_protocol("kr240-2").read_text()
                                  .split("[fake_lab]")[0])
    for body, args in (
        ({"out": "full"}, ["--out", "full"]),
        ({"out": "new", "time_scale": -1.0}, ["--out", "new", "--time-scale", "-1"]),
        ({"out": "new", "protocol": "missing.toml"}, ["--out", "new", "--protocol",
                                                       "missing.toml"]),
        ({"out": "new", "protocol": "bare.toml"}, ["--out", "new", "--protocol", "bare.toml"]),
    ):
        answer = client.post("/api/jobs/demo", json=body)
        assert answer.status_code == 400, answer.text
        assert answer.json()["detail"] == cli_error(ws, "demo", *args)
    assert not (ws / "new").exists()
    assert sorted(p.name for p in (ws / "full").iterdir()) == ["x.txt"]
