"""plan: the CLI and the web API write the same plan for the same protocol."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.jobs.conftest import cli, cli_error, cli_json

PROTOCOL = Path(__file__).parents[2] / "protocols" / "kr240-2.toml"


@pytest.fixture
def proto(ws) -> str:
    shutil.copy(PROTOCOL, ws / "kr240-2.toml")
    return "kr240-2.toml"


def test_plan_same_files_from_cli_and_api(ws, client, proto):
    doc = cli_json(ws, "plan", "-p", proto, "-o", "cli", "--candidates", "400",
                   "--no-figure", "--seed", "3")
    answer = client.post("/api/jobs/plan", json={"protocol": proto, "out": "api",
                                                 "candidates": 400, "figure": False,
                                                 "seed": 3})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    assert got["plan_file"] == "api/plan.csv"
    assert doc["plan_file"] == "cli/plan.csv"
    assert {k: v for k, v in got.items() if k != "plan_file"} == \
        {k: v for k, v in doc.items() if k != "plan_file"}
    for name in ("plan.csv", "summary.txt", "summary.json", "protocol.toml"):
        assert (ws / "api" / name).read_text() == (ws / "cli" / name).read_text(), name
    summary = json.loads((ws / "api" / "summary.json").read_text())
    assert summary == {k: v for k, v in got.items() if k != "plan_file"}
    rows = (ws / "api" / "plan.csv").read_text().strip().splitlines()
    assert len(rows) - 1 == summary["tests"] == 5  # the protocol's 5 tests, one row each


def test_plan_refusals_same_line(ws, client, proto):
    cli(ws, "plan", "-p", proto, "-o", "busy", "--candidates", "200", "--no-figure")
    for body, args in (
        ({"protocol": proto, "out": "busy"}, ["-p", proto, "-o", "busy"]),
        ({"protocol": "missing.toml", "out": "x"}, ["-p", "missing.toml", "-o", "x"]),
        ({"protocol": proto, "out": "w", "strategy": "weighted", "weights": [1, 2],
          "candidates": 200}, ["-p", proto, "-o", "w", "--strategy", "weighted",
                               "--weights", "1,2", "--candidates", "200"]),
    ):
        answer = client.post("/api/jobs/plan", json=body)
        assert answer.status_code == 400, answer.text
        assert answer.json()["detail"] == cli_error(ws, "plan", *args)
    assert not (ws / "x").exists() and not (ws / "w").exists()


@pytest.mark.parametrize("out", ["../escape", "/tmp/escape", "a/../../escape"])
def test_plan_out_of_the_workspace_refused(client, proto, out):
    answer = client.post("/api/jobs/plan", json={"protocol": proto, "out": out})
    assert answer.status_code == 400
    assert answer.json()["detail"].startswith("out: ")


def test_plan_unknown_strategy_is_422(client, proto):
    answer = client.post("/api/jobs/plan", json={"protocol": proto, "out": "o",
                                                 "strategy": "best"})
    assert answer.status_code == 422
