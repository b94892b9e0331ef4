"""The Use view in a real headless Chromium: K_X and the deflection at a pose with joint
sliders, the compensation of a path and the comparison of two analyses.

The user moves sliders with the keyboard, types into the boxes and clicks; the numbers
on the page are compared with the jobs' own results (campaign.jobs.stiffness,
compensate, compare) for the same inputs.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.web.conftest import browser_page, gui_server
from tests.web.pages import wait_use_shown

ROOT = Path(__file__).parents[2]
WRENCH = [0.0, 0.0, -2000.0, 0.0, 200.0, 0.0]  # the page's default at a pose


@pytest.fixture(scope="module")
def ws(tmp_path_factory, analyses) -> Path:
    """A workspace with the example path, the two analyses and a robot file."""
    from analysis.model.robots import builtin_files

    ws = tmp_path_factory.mktemp("use-ws") / "ws"
    ws.mkdir()
    shutil.copy(builtin_files()["kr240-2"], ws / "robot.toml")
    shutil.copy(ROOT / "examples" / "kr240-2_path.csv", ws / "path.csv")
    for a in analyses:
        shutil.copytree(a, ws / a.name)
    return ws


@pytest.fixture(scope="module")
def page(browser, ws):
    with gui_server(ws, "use-view-token-0123456789") as url, browser_page(browser, url) as pg:
        pg.wait_for_selector("#row-k6", timeout=30_000)  # the page's tabs are live
        pg.wait_for_selector("#view-use[data-ready='1']", state="attached", timeout=30_000)
        pg.click("#tab-use")
        pg.wait_for_selector("#view-use", state="visible")
        yield pg


def _settled(page) -> list[float]:
    """Wait until the page shows the job's answer for the joints and wrench now set; those
    joints (deg)."""
    wait_use_shown(page)
    return json.loads(page.get_attribute("#view-use", "data-shown-q"))


def _num(text: str) -> float:
    return float(text.strip())


def _close(shown: str, value: float) -> None:
    """A number shown with 5 significant digits equals ``value``."""
    assert math.isclose(_num(shown), value, rel_tol=1e-4, abs_tol=1e-9), (shown, value)


def _job(robot: str, q_deg, ws: Path):
    from campaign.jobs.stiffness import StiffnessOptions, run

    name = str(ws / robot) if robot.endswith(".toml") else robot
    return run(StiffnessOptions(robot=name, q_rad=np.radians(q_deg).tolist(),
                                wrench_N_Nm=WRENCH))


def _check_pose(page, ws: Path, robot: str) -> None:
    q = _settled(page)
    res = _job(robot, q, ws)
    K = np.asarray(res.K_X)
    for i in range(3):
        for j in range(3):
            _close(page.inner_text(f"#use-kx-t-{i}{j}"), K[i, j] / 1e3)        # N/mm
            _close(page.inner_text(f"#use-kx-r-{i}{j}"), K[3 + i, 3 + j] / 1e3)  # N m/mrad
    d = np.asarray(res.deflection_nonlinear_m_rad) * 1e3
    for i, name in enumerate(["dx", "dy", "dz", "rx", "ry", "rz"]):
        _close(page.inner_text(f"#use-d-{name}"), d[i])
        band = page.inner_text(f"#use-d-{name}-95")
        if res.uncertainty is None:
            assert band == "no covariance in the model"
        else:
            lo, hi = (float(v) for v in re.findall(r"-?[\d.]+(?:e-?\d+)?", band))
            _close(str(lo), 1e3 * res.uncertainty["deflection_nonlinear_lo95_m_rad"][i])
            _close(str(hi), 1e3 * res.uncertainty["deflection_nonlinear_hi95_m_rad"][i])
            assert lo < d[i] < hi


def test_slider_moves_show_the_stiffness_jobs_numbers(page, ws):
    q_before = _settled(page)
    slider = page.locator("#q2")
    slider.focus()
    for _ in range(6):
        slider.press("ArrowRight")
    q = _settled(page)
    assert q[1] == pytest.approx(q_before[1] + 3.0)  # 6 steps of 0.5 deg
    from analysis.model.robots import load_robot

    pendant = np.degrees(load_robot("kr240-2").to_controller(np.radians(q)))
    shown = [float(v) for v in re.findall(r"A\d (-?[\d.]+)", page.inner_text("#use-pendant"))]
    assert np.allclose(shown, pendant, rtol=1e-4, atol=1e-9), (shown, pendant)
    _check_pose(page, ws, "kr240-2")
    # an identified model: the deflection with its 95 % interval from the covariance
    page.select_option("#use-robot", "A/model.toml")
    page.wait_for_function("() => document.getElementById('use-robot-info')"
                           ".textContent.includes('model.toml')")
    page.locator("#q3").focus()
    page.locator("#q3").press("ArrowLeft")
    _check_pose(page, ws, "A/model.toml")
    assert "(N m/mrad)" in page.inner_text("#use-kx-r caption")
    assert "(N/mm)" in page.inner_text("#use-kx-t caption")


def test_a_slider_cannot_leave_the_limits(page, ws):
    from analysis.model.robots import load_robot

    page.select_option("#use-robot", "kr240-2")
    page.wait_for_function("() => !document.getElementById('use-robot-info')"
                           ".textContent.includes('model.toml')")
    r = load_robot("kr240-2")
    hi, lo = math.degrees(r.upper[0]), math.degrees(r.lower[0])
    s = page.locator("#q1")
    s.focus()
    s.press("End")
    for _ in range(4):
        s.press("ArrowRight")
    assert float(s.input_value()) == pytest.approx(hi)
    s.press("Home")
    for _ in range(4):
        s.press("ArrowLeft")
    assert float(s.input_value()) == pytest.approx(lo)
    box = page.locator("#q1-deg")  # typing past the limit holds the joint at it
    box.fill("999")
    box.press("Enter")
    assert float(box.input_value()) == pytest.approx(hi)
    assert float(s.input_value()) == pytest.approx(hi)
    assert "held at its limit" in page.inner_text("#use-limit")
    q = _settled(page)
    assert q[0] == pytest.approx(hi)
    assert page.inner_text("#use-error") == ""  # the job accepted it: inside the limits
    _check_pose(page, ws, "kr240-2")


def test_singular_pose_shows_undefined(page, ws):
    page.locator("#q5-deg").fill("0")  # wrist straight: J is singular
    page.locator("#q5-deg").press("Enter")
    q = _settled(page)
    assert q[4] == 0
    res = _job("kr240-2", q, ws)
    assert res.K_X is None  # the job says so itself
    assert page.is_visible("#use-undefined")
    assert "K_X is undefined" in page.inner_text("#use-undefined")
    for i in range(3):
        for j in range(3):
            assert page.inner_text(f"#use-kx-t-{i}{j}") == "undefined"
            assert page.inner_text(f"#use-kx-r-{i}{j}") == "undefined"
    # the deflection stays defined and is the job's
    _close(page.inner_text("#use-d-dz"), 1e3 * res.deflection_nonlinear_m_rad[2])


def test_compensation_shows_the_jobs_numbers(page, ws):
    from campaign.jobs.compensate import CompensateOptions, run

    page.click("#tab-use")  # refreshes the file lists
    page.select_option("#comp-path", "path.csv")
    page.select_option("#comp-robot", "A/model.toml")
    page.fill("#comp-out", "comp-page")
    page.click("#comp-run")
    page.wait_for_selector("#view-use[data-comp='done']", timeout=30_000)
    mine = run(CompensateOptions(robot=str(ws / "A/model.toml"), path=ws / "path.csv",
                                 out=ws / "comp-job", wrench_N_Nm=[500, 0, -1000, 0, 20, 0]))
    s = mine.summary
    rows = len((ws / "path.csv").read_text().strip().splitlines()) - 1
    assert int(page.inner_text("#comp-points")) == s["points"] == rows
    _close(page.inner_text("#comp-before-max"), 1e3 * s["translation_m"]["before"]["max"])
    _close(page.inner_text("#comp-before-hi"), 1e3 * s["translation_m"]["before_upper95_max"])
    _close(page.inner_text("#comp-rbefore-max"), 1e3 * s["rotation_rad"]["before"]["max"])
    assert int(page.inner_text("#comp-worst")) == s["worst_point"]["line"]
    hrefs = page.eval_on_selector_all("#comp-files a", "els => els.map(a => a.textContent)")
    assert "comp-page/compensated.csv" in hrefs
    assert any(h.endswith(".src") for h in hrefs)
    # the plot draws every point of the path, with the band
    n = page.evaluate("() => useView.state.plot.data[0].length")
    assert n == s["points"]
    band_hi = page.evaluate("() => useView.state.plot.data[2]")
    import pandas as pd

    table = pd.read_csv(ws / "comp-job" / "compensated.csv")
    assert np.allclose(band_hi, table["dx_hi95_mm"], rtol=1e-9)
    # the program link opens the program text
    src = next(h for h in hrefs if h.endswith(".src"))
    text = page.evaluate("async (p) => (await fetch('/api/use/program?path=' + "
                         "encodeURIComponent(p))).text()", src)
    assert text == (ws / src).read_bytes().decode()  # the bytes: CR LF kept
    # the same output directory again, without "replace": the job's one line beside the form,
    # naming the checkbox (not the command line's --force)
    page.click("#comp-run")
    page.wait_for_selector("#view-use[data-comp='error']", timeout=30_000)
    err = page.inner_text("#comp-error")
    assert "comp-page" in err and "\n" not in err and str(ws) not in err
    # the previous compensation's numbers are not left beside the refusal
    assert page.locator("#comp-result").is_hidden()
    with pytest.raises(Exception) as refused:
        run(CompensateOptions(robot=str(ws / "A/model.toml"), path=ws / "path.csv",
                              out=ws / "comp-page", wrench_N_Nm=[500, 0, -1000, 0, 20, 0]))
    # the job's line in the page's terms: its command-line options are the form's labels
    line = str(refused.value).replace(f"{ws}/", "")
    assert "--force" in line and "--force" not in err
    assert err == line.replace("--out", "\u201cOutput directory\u201d").replace(
        "--force", "\u201cReplace its files\u201d")


def test_a_new_wrench_gives_the_jobs_numbers(page, ws):
    page.select_option("#use-robot", "kr240-2")
    page.wait_for_function("() => !document.getElementById('use-robot-info')"
                           ".textContent.includes('model.toml')")
    box = page.locator("#use-w-fz")
    page.locator("#q5-deg").fill("40")
    page.locator("#q5-deg").press("Enter")
    _settled(page)
    box.fill("-500")  # the wrench alone changes: the page asks the job again
    box.press("Enter")
    q = _settled(page)
    assert json.loads(page.get_attribute("#view-use", "data-shown-w"))[2] == -500
    from campaign.jobs.stiffness import StiffnessOptions, run

    res = run(StiffnessOptions(robot="kr240-2", q_rad=np.radians(q).tolist(),
                               wrench_N_Nm=[0, 0, -500, 0, 200, 0]))
    for i, name in enumerate(["dx", "dy", "dz", "rx", "ry", "rz"]):
        _close(page.inner_text(f"#use-d-{name}"), 1e3 * res.deflection_nonlinear_m_rad[i])
    _close(page.inner_text("#use-kx-t-22"), res.K_X[2][2] / 1e3)
    box.fill("-2000")
    box.press("Enter")
    _settled(page)


def test_compare_shows_the_jobs_numbers(page, ws):
    from campaign.jobs.compare import CompareOptions, run

    page.select_option("#cmp-a", "A")
    page.select_option("#cmp-b", "B")
    page.click("#cmp-run")
    page.wait_for_selector("#view-use[data-cmp='done']", timeout=30_000)
    res = run(CompareOptions(a=ws / "A", b=ws / "B")).comparison
    assert res["interval_level_text"] in page.inner_text("#cmp-level")
    for row in res["joints"]:
        tr = page.locator(f"#cmp-row-{row['joint']}")
        _close(tr.locator(".dk").inner_text(), row["difference_Nm_per_rad"] / 1e3)
        lo, hi = (float(v) for v in re.findall(r"-?[\d.]+(?:e-?\d+)?",
                                               tr.locator(".iv").inner_text()))
        _close(str(lo), row["interval_difference_Nm_per_rad"][0] / 1e3)
        _close(str(hi), row["interval_difference_Nm_per_rad"][1] / 1e3)
        assert tr.locator(".verdict").inner_text().startswith(row["verdict"])
    verdicts = {r["joint"]: r["verdict"] for r in res["joints"]}
    assert verdicts[2] == "changed"  # B's joint 2 is 10 % stiffer


def test_export_writes_the_jobs_file_and_says_what_it_leaves_out(page, ws):
    """The export form: an identified model to SDF (the file is the job's, byte for byte),
    then a robot without stiffness refused with the job's line."""
    from campaign.jobs.choices import SimFormat
    from campaign.jobs.export import ExportOptions, run

    page.select_option("#exp-robot", "A/model.toml")
    page.select_option("#exp-format", "sdf")
    assert page.input_value("#exp-out") == "robot.sdf"  # the name follows the format
    page.fill("#exp-out", "A.sdf")
    page.click("#exp-run")
    page.wait_for_selector("#view-use[data-exp='done']", timeout=30_000)
    res = run(ExportOptions(robot=str(ws / "A" / "model.toml"), format=SimFormat.sdf,
                            out=ws / "A-job.sdf"))
    assert (ws / "A.sdf").read_text().replace(str(ws / "A.sdf"), "") == \
        res.file.read_text().replace(str(ws / "A-job.sdf"), "")
    wrote = page.inner_text("#exp-wrote")
    assert "A.sdf" in wrote and res.report_id in wrote
    for v in res.stiffness_Nm_per_rad:
        assert f"{float(f'{v / 1e3:.5g}'):g}" in wrote
    items = page.locator("#exp-left li").all_inner_texts()
    assert items == res.left_out and any("covariance" in t for t in items)
    assert page.locator("#exp-notes li").all_inner_texts() == res.notes
    page.select_option("#exp-robot", "ur10e")
    page.fill("#exp-out", "u.sdf")
    page.click("#exp-run")
    page.wait_for_selector("#view-use[data-exp='error']", timeout=30_000)
    assert "has no joint stiffness" in page.inner_text("#exp-error")
    assert not (ws / "u.sdf").exists()
