"""analyze: the CLI (um, urad at its edge) and the web API (SI) identify the same k and write
the same results.json."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.jobs.conftest import cli, cli_error
from tests.use._campaigns import TRUE_K
from tests.use.conftest import SIGMAS, write_tests_csv

#: the simulation's noise figures in SI, as the API takes them (um and urad as the CLI has
#: them, times 1e-6: the same floats)
SI_SIGMAS = {"translation_sigma_m": float(SIGMAS[1]) * 1e-6,
             "rotation_sigma_rad": float(SIGMAS[3]) * 1e-6,
             "force_sigma_N": 1e-9, "moment_sigma_Nm": 1e-9}


def _without_places(doc: dict, where: str):
    """``doc`` with the output directory's name taken out of its strings."""
    return json.loads(json.dumps(doc).replace(f"{where}/", "OUT/").replace(f'"{where}"',
                                                                           '"OUT"'))


def test_analyze_same_results_from_cli_and_api(ws, client):
    write_tests_csv(ws / "tests.csv")
    proc = cli(ws, "analyze", "--measurements", "tests.csv", "--robot", "kr240-2", "--out",
               "cli", "--no-report", *SIGMAS, "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    answer = client.post("/api/jobs/analyze", json={
        "measurements": "tests.csv", "robot": "kr240-2", "out": "api", "report": False,
        **SI_SIGMAS})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    # the queued job adds the report's verdict line (the Analyze view shows it)
    verdict = got.pop("verdict")
    assert verdict["kind"] in ("verdict", "warning") and "\u03c7\u00b2/\u03bd" in verdict["text"]
    assert _without_places(got, "api") == _without_places(doc, "cli")
    on_disk = json.loads((ws / "api" / "results.json").read_text())
    assert _without_places(on_disk, str(ws / "api")) == \
        _without_places(json.loads((ws / "cli" / "results.json").read_text()), "cli")
    # the simulated campaign's true stiffness: within 20 % of every k, and the intervals
    # are ordered around the estimates
    k, ci = np.array(got["joint_stiffness_Nm_per_rad"]), np.array(got["ci95_Nm_per_rad"])
    assert np.all(np.abs(k / TRUE_K - 1) < 0.2)
    assert np.all((ci[:, 0] < k) & (k < ci[:, 1]))


def test_analyze_refusals_same_line(ws, client):
    write_tests_csv(ws / "tests.csv")
    for body, args in (
        ({"measurements": "tests.csv", "robot": "kr240-2"},
         ["--measurements", "tests.csv", "--robot", "kr240-2"]),
        ({"measurements": "tests.csv", "robot": "kr240-2", "out": "o", "force_relative": -0.01},
         ["--measurements", "tests.csv", "--robot", "kr240-2", "--out", "o", "--force-pct",
          "-1"]),
        ({"measurements": "tests.csv", "robot": "kr240-2", "out": "o", "joints": "1,7"},
         ["--measurements", "tests.csv", "--robot", "kr240-2", "--out", "o", "--joints",
          "1,7"]),
        ({"measurements": "tests.csv", "robot": "kr240-2", "out": "o", "trials": 5},
         ["--measurements", "tests.csv", "--robot", "kr240-2", "--out", "o", "--trials",
          "5"]),
        ({}, []),
    ):
        answer = client.post("/api/jobs/analyze", json=body)
        assert answer.status_code == 400, answer.text
        assert answer.json()["detail"] == cli_error(ws, "analyze", *args)
    assert not (ws / "o").exists()


def test_a_refused_result_reaches_the_api_as_records_from_its_own_process(ws, app, client):
    """Noise figures 30x too large: residuals far below them, refused as too good to be
    true. The queued job runs in a process of its own (as the GUI's): the refusal crosses
    back as the typed exception, its reasons as records equal to the job's, its line equal
    to the command line's; nothing is written."""
    from analysis.errors import InputError, Refused
    from campaign.jobs.analyze import AnalyzeOptions, run

    write_tests_csv(ws / "tests.csv")
    loose = {**SI_SIGMAS, "translation_sigma_m": 30 * SI_SIGMAS["translation_sigma_m"],
             "rotation_sigma_rad": 30 * SI_SIGMAS["rotation_sigma_rad"]}
    with pytest.raises(Refused) as err:
        run(AnalyzeOptions(measurements=ws / "tests.csv", robot="kr240-2", out=ws / "direct",
                           report=False, **loose))
    assert isinstance(err.value, InputError) and len(err.value.reasons) >= 1
    assert any("too good" in r.text for r in err.value.reasons), err.value.reasons
    app.state.jobs_in_threads = False  # the job's own process, as the GUI runs it
    answer = client.post("/api/jobs/analyze", json={
        "measurements": "tests.csv", "robot": "kr240-2", "out": "api", "report": False,
        **loose})
    assert answer.status_code == 400, answer.text
    record = answer.json()
    assert record["refused"] == [{"text": r.text.replace(f"{ws}/", "")}
                                 for r in err.value.reasons]
    args = ["--measurements", "tests.csv", "--robot", "kr240-2", "--out", "cli",
            "--no-report", "--translation-sigma-um", str(loose["translation_sigma_m"] * 1e6),
            "--rotation-sigma-urad", str(loose["rotation_sigma_rad"] * 1e6),
            "--force-sigma-N", "1e-9", "--moment-sigma-Nm", "1e-9"]
    assert record["detail"] == cli_error(ws, "analyze", *args)
    assert record["detail"].count(" | ") == len(record["refused"]) - 1
    assert not (ws / "api").exists() and not (ws / "cli").exists()
