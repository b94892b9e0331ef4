"""campaign analyze RUN_DIR: results.json, the HTML report and the PDF report.

The HTML is parsed with html.parser and the PDF text extracted with pypdf;
the numbers shown are compared with results.json and with the simulated
truth of the run (Table 2 of the paper).
"""

from __future__ import annotations

import base64
import io
import json
import re
import struct

import numpy as np
import pytest
from pypdf import PdfReader
from report_html import ReportPage
from report_runs import TRUE_K

from analysis.report.build import SECTION_TITLES
from analysis.report.figures import PIXELS
from analysis.report.formatting import interval_kNm, k_kNm
from campaign.cli import main


def _analyze(args):
    return main(["analyze", *args])


@pytest.fixture(scope="module")
def complete(complete_run):
    out = complete_run / "analysis"
    assert _analyze([str(complete_run), "--pose", "0,30,-190,10,40,20"]) == 0
    doc = ReportPage()
    doc.feed((out / "report.html").read_text(encoding="utf-8"))
    pdf = PdfReader(out / "report.pdf")
    pages = [p.extract_text() for p in pdf.pages]
    results = json.loads((out / "results.json").read_text())
    return {"out": out, "html": doc, "pages": pages, "results": results}


def _flat(text: str) -> str:
    return re.sub(r"\s+", " ", text)


def test_results_json_matches_the_simulated_truth(complete):
    res = complete["results"]
    k = np.array(res["joint_stiffness_Nm_per_rad"])
    ci = np.array(res["ci95_Nm_per_rad"])
    assert res["n_tests"] == 14  # 15 rows, one failed
    # each k within 3 % of the truth, and the truth inside at least 4 of 6 intervals
    np.testing.assert_allclose(k, TRUE_K, rtol=0.03)
    inside = (ci[:, 0] <= TRUE_K) & (TRUE_K <= ci[:, 1])
    assert inside.sum() >= 4
    assert np.all(ci[:, 0] < k) and np.all(k < ci[:, 1])


def test_html_table_holds_the_identified_values_and_intervals(complete):
    res, doc = complete["results"], complete["html"]
    table = doc.tables["Stiffness with standard errors and reference values"]
    header, rows = table[0], table[1:]
    assert header[:3] == ["joint", "k (kN m/rad)", "95 % interval (kN m/rad)"]
    assert len(rows) == 6
    for j, row in enumerate(rows):
        k = res["joint_stiffness_Nm_per_rad"][j]
        lo, hi = res["ci95_Nm_per_rad"][j]
        assert row[0] == f"k{j + 1}"
        assert row[1] == k_kNm(k)
        assert float(row[1]) == pytest.approx(k / 1e3, rel=1e-4)
        assert row[2] == interval_kNm(lo, hi)
        shown = [float(v) for v in row[2].strip("[]").split(",")]
        assert shown == pytest.approx([lo / 1e3, hi / 1e3], rel=1e-4)
        assert float(row[5]) == pytest.approx(TRUE_K[j] / 1e3)  # nominal = Table 2


def test_html_is_self_contained_with_plots_of_the_expected_size(complete):
    doc = complete["html"]
    assert doc.external == []
    assert doc.h2 == list(SECTION_TITLES)
    assert len(doc.images) == 6
    for src in doc.images:
        assert src.startswith("data:image/png;base64,")
        png = base64.b64decode(src.split(",", 1)[1])
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        # 300 px per inch: >= 300 ppi printed at the PDF's 150 mm width
        assert struct.unpack(">II", png[16:24]) == PIXELS
        assert PIXELS[0] / (150 / 25.4) >= 300
        import matplotlib.image as mpimg

        pixels = mpimg.imread(io.BytesIO(png))
        assert pixels.std() > 0.05  # not a blank image


def test_grey_figure_is_stored_as_grey_and_colour_figures_as_rgb(complete):
    """The 1/kappa_F map (grey colour map, black and white marks) is an 8-bit grey PNG
    (IHDR colour type 0) in the HTML and a DeviceGray image in the PDF; the five colour
    figures stay RGB (colour type 2)."""
    html = (complete["out"] / "report.html").read_text(encoding="utf-8")
    found = re.findall(r'<figure id="fig-(\w+)"><img src="data:image/png;base64,([^"]+)"',
                       html)
    types = {name: base64.b64decode(data)[25] for name, data in found}
    assert len(types) == 6
    assert types.pop("poses_kappa_map") == 0
    assert set(types.values()) == {2}
    spaces = []
    for page in PdfReader(complete["out"] / "report.pdf").pages:
        xobjects = page["/Resources"].get("/XObject", {})
        spaces += [str(xobjects[k].get_object()["/ColorSpace"]) for k in xobjects]
    assert sorted(spaces) == ["/DeviceGray"] + ["/DeviceRGB"] * 5


def test_grey_or_rgb_keeps_every_pixel():
    """grey_or_rgb: all-grey pixels -> their (h, w) levels; one colour pixel anywhere
    (on a row the 1-in-16 sample skips, too) -> the RGB array unchanged."""
    from analysis.report.figures import grey_or_rgb

    rng = np.random.default_rng(3)
    levels = rng.integers(0, 256, size=(40, 30), dtype=np.uint8)
    rgb = np.repeat(levels[..., None], 3, axis=2)
    grey = grey_or_rgb(rgb)
    assert grey.shape == (40, 30) and np.array_equal(grey, levels)
    for row in (0, 5, 39):  # sampled (0), skipped by the sample (5, 39)
        tinted = rgb.copy()
        tinted[row, 7, 2] ^= 1
        out = grey_or_rgb(tinted)
        assert out.shape == (40, 30, 3) and np.array_equal(out, tinted)


def test_html_shows_flags_and_failed_row(complete):
    doc = complete["html"]
    flagged = doc.tables["Flagged and failed test rows"]
    failed = [r for r in flagged[1:] if r[3] == "failed"]
    assert len(failed) == 1 and failed[0][4] == "saturation, retried" and failed[0][-1] == "12"
    drift = [r for r in flagged[1:] if r[4] == "drift"]
    assert drift and drift[0][6] == "0.051"
    text = _flat(" ".join(doc.text))
    assert "Data-quality flags: drift: 1, saturation: 1, retried: 1" in text
    assert "PARTIAL RUN" not in text


def test_html_residuals_validation_and_kx(complete):
    doc = complete["html"]
    res = complete["results"]
    resid = doc.tables["Residuals (measured - model) per test and component"]
    assert len(resid) == 1 + 14
    first = [r for r in res["residuals"] if r["test"] == 0 and r["component"] == "dz"][0]
    assert resid[1][5].rstrip(" *") == f"{1e6 * first['residual']:.1f}"
    val = doc.tables["Held-out validation (leave one pose out)"]
    assert [r[0] for r in val[1:]] == ["P1", "P2", "P3", "P4", "P5"]
    assert all(0.2 < float(r[4]) < 3 for r in val[1:])
    kx = doc.tables["K_X at pose 1 (command line), with K_C"]
    assert kx[0][1:7] == ["\u03b4x (per mm)", "\u03b4y (per mm)", "\u03b4z (per mm)",
                          "\u03b4rx (per mrad)", "\u03b4ry (per mrad)", "\u03b4rz (per mrad)"]
    m = np.array([[float(v) for v in r[1:7]] for r in kx[1:]])
    # independent: K_X of eq. 6 at the --pose with the identified k, scaled to N/mm, N m/mrad
    from report_runs import PROTOCOL

    from analysis.kinetostatics.stiffness import cartesian_stiffness, complementary_stiffness
    from analysis.model.kinematics import jacobian
    from campaign.protocol import load_protocol
    from campaign.protocol_robot import protocol_robot

    robot = protocol_robot(load_protocol(PROTOCOL))
    q = np.radians([0, 30, -190, 10, 40, 20])
    w = np.array([0, 2200, 2200, 200, 200, 0.0])
    k = np.array(res["joint_stiffness_Nm_per_rad"])
    K = 1e-3 * cartesian_stiffness(jacobian(robot, q), k, complementary_stiffness(robot, q, w))
    np.testing.assert_allclose(m, K, rtol=1e-3, atol=1e-3 * np.abs(K).max())
    table = doc.tables["Principal stiffnesses at pose 1 (command line)"]
    assert [r[0] for r in table[1:]] == ["pure force (N/mm)", "pure moment (N m/mrad)"]
    principal = np.array([[float(v) for v in r[1:]] for r in table[1:]])
    assert np.all(np.diff(principal, axis=1) <= 0)  # largest first
    # independent: inverse eigenvalues of the blocks of K_X^-1
    C = np.linalg.inv(K)
    for row, sl in zip(principal, (slice(0, 3), slice(3, 6)), strict=True):
        np.testing.assert_allclose(row, np.sort(1 / np.linalg.eigvalsh(C[sl, sl]))[::-1],
                                   rtol=2e-3)
    # no SI e-notation and no round-off residue in the engineering table
    assert not any("e" in c for r in kx[1:] for c in r[1:])
    effect = doc.tables["Effect of K_C (the load's geometric stiffness)"]
    row = effect[1]
    dp_with, dp_without, diff = (float(v) for v in row[1:4])
    assert abs(dp_with - dp_without) <= diff + 1e-3  # triangle inequality
    assert float(row[4]) == pytest.approx(100 * diff / dp_with, abs=0.02)
    assert 0 < float(row[5]) < 20  # K_C changes K_X under the wrench, by a little


def test_pdf_pages_and_numbers(complete):
    pages, res = complete["pages"], complete["results"]
    n = len(pages)
    assert 6 <= n <= 12
    for i, text in enumerate(pages, start=1):
        assert f"page {i} of {n}" in text
    # the sections flow in order (no page per section: fewer pages than sections + 2)
    # (headings with notation are drawn with a subscript: compared without "_" and spaces)
    def squeeze(text):
        return re.sub(r"[\s_]", "", text)

    starts = [next(i for i, t in enumerate(pages) if squeeze(f"{s + 1}. {title}") in squeeze(t))
              for s, title in enumerate(SECTION_TITLES)]
    assert starts == sorted(starts) and starts[0] == 0
    assert len(set(starts)) < len(starts)  # two sections share a page somewhere
    ident = _flat(" ".join(pages[starts[1]:starts[1] + 2]))
    for j in range(6):
        k = res["joint_stiffness_Nm_per_rad"][j]
        assert k_kNm(k) in ident
        assert interval_kNm(*res["ci95_Nm_per_rad"][j]) in ident
    assert "saturation, retried" in _flat(" ".join(pages[:starts[1] + 1]))  # in the summary


def test_aborted_run_is_analysed_and_says_partial(aborted_run):
    out = aborted_run / "analysis"
    assert _analyze([str(aborted_run), "--no-report"]) == 0
    assert json.loads((out / "results.json").read_text())["n_tests"] == 12
    assert json.loads((out / "analysis.json").read_text())["partial"] is True
    assert _analyze([str(aborted_run), "--trials", "20", "--force"]) == 0
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "PARTIAL RUN (status aborted: interrupted by the operator (Ctrl-C))" in html
    assert "12 test row(s) that finished ok of 15 planned" in html
    assert "being written when the run stopped: dropped" in html
    text = _flat(PdfReader(out / "report.pdf").pages[0].extract_text())
    assert "PARTIAL RUN" in text and "12 test row(s) that finished ok" in text
