"""What a user sees in the report: clean numbers, labels, pose labels on the maps,
CSV-import rows, and a rendered-page check of the PDF (pdftoppm, when installed).

The HTML is read with html.parser, the PDF text with pypdf; pages are rendered
with poppler's pdftoppm when it is on PATH (skipped otherwise).
"""

from __future__ import annotations

import hashlib
import io
import re
import shutil
import subprocess

import numpy as np
import pytest
from pypdf import PdfReader
from report_html import ReportPage
from report_runs import write_csv

from campaign.cli import main


def _flat(text: str) -> str:
    return re.sub(r"\s+", " ", text)


@pytest.fixture(scope="module")
def run_report(complete_report):
    out = complete_report
    page = ReportPage()
    page.feed((out / "report.html").read_text(encoding="utf-8"))
    pages = [p.extract_text() for p in PdfReader(out / "report.pdf").pages]
    return {"out": out, "page": page, "html_text": _flat(" ".join(page.text)),
            "pdf_text": _flat(" ".join(pages))}


@pytest.fixture(scope="module")
def csv_report(rows, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("csvq")
    csv = write_csv(tmp / "tests.csv", rows)
    out = tmp / "out"
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out", str(out),
                 "--trials", "10", "--force-sigma-N", "0.5", "--moment-sigma-Nm", "0.05"]) == 0
    page = ReportPage()
    page.feed((out / "report.html").read_text(encoding="utf-8"))
    return {"csv": csv, "page": page, "html_text": _flat(" ".join(page.text))}


ROUND_OFF = re.compile(r"(?<![\w.])-?\d(\.\d+)?e-(1\d|[2-9]\d)\b")  # e.g. -4.70e-11, 8.0e-19
SIGNED_ZERO = re.compile(r"(?<![\w.])-0(\.0+)?(?![\d.])")  # -0, -0.0000


@pytest.mark.parametrize("which", ["html_text", "pdf_text"])
def test_no_round_off_shown_as_a_value(run_report, which):
    text = run_report[which]
    assert not ROUND_OFF.search(text), ROUND_OFF.search(text)
    assert not SIGNED_ZERO.search(text), text[max(0, SIGNED_ZERO.search(text).start() - 80):
                                              SIGNED_ZERO.search(text).end() + 20]


def test_labels_read_as_a_user_expects(run_report):
    text = run_report["html_text"] + " " + run_report["pdf_text"]
    assert "Pose pose" not in text and "pose pose" not in text
    assert "(0 %)" not in text
    assert "K_X^-1" not in text and "J^-T" not in text  # formulas not in ASCII
    table = run_report["page"].tables["Stiffness with standard errors and reference values"]
    assert table[0][6] == "k/nominal - 1 (%)"
    # where the nominal values come from: the robot file's [sources] stiffness
    assert "Nominal values: Dumas et al. 2011 Table 2" in text
    html = (run_report["out"] / "report.html").read_text(encoding="utf-8")
    assert "<i>K</i><sub>X</sub>" in html and "<i>K</i><sub>C</sub>" in html


def test_kx_in_engineering_units_with_the_kc_effect(run_report):
    tables = run_report["page"].tables
    kx = [t for title, t in tables.items() if title.startswith("K_X at ")]
    assert kx and all(t[0][1] == "\u03b4x (per mm)" and t[0][4] == "\u03b4rx (per mrad)"
                      for t in kx)
    assert "Effect of K_C (the load's geometric stiffness)" in tables
    assert not any("(SI)" in title for title in tables)  # no near-identical SI pair


def test_maps_carry_the_pose_labels_and_the_fixed_joint_rule(run_report):
    alts = {i: alt for i, (alt, _) in enumerate(run_report["page"].figures)}
    maps = [a for a in alts.values() if "(labels P1, P2, P3, P4, P5)" in a]
    assert len(maps) == 2  # the dexterity map and the joint-space deflection map
    for alt in maps:
        assert "\u03b81 = 0, \u03b84 = 45, \u03b85 = 45, \u03b86 = 45 deg" in alt
        assert "from the protocol's [sampling] fixed_deg" in alt


def test_figures_fill_their_canvas_without_clipping(run_report):
    """Nothing drawn touches a figure's edge (legends and labels inside), none is blank."""
    import matplotlib.image as mpimg

    for alt, png in run_report["page"].figures:
        px = mpimg.imread(io.BytesIO(png))
        # a grey figure is an 8-bit grey PNG (h, w); a colour one RGB (h, w, 3)
        px = np.repeat(px[..., None], 3, axis=2) if px.ndim == 2 else px[..., :3]
        assert px.std() > 0.05, alt
        border = np.concatenate([px[:2].reshape(-1, 3), px[-2:].reshape(-1, 3),
                                 px[:, :2].reshape(-1, 3), px[:, -2:].reshape(-1, 3)])
        assert border.min() > 0.95, f"something touches the edge of: {alt[:60]}"


def test_csv_import_rows_say_what_they_are(csv_report):
    summary = csv_report["page"].tables["Campaign"]
    rows = {r[0]: r[1] for r in summary[1:]}
    assert "protocol SHA-256" not in rows
    assert rows["measurements SHA-256"] == hashlib.sha256(
        csv_report["csv"].read_bytes()).hexdigest()
    assert rows["load case 1"] == "f = (0, 2200, 2200) N, m = (200, 200, 0) N m (6 test(s))"
    text = csv_report["html_text"]
    assert "User wrench at P, base frame: f = (0, 2200, 2200) N, m = (200, 200, 0) N m" in text
    assumptions = {r[0]: r[1] for r in csv_report["page"].tables["Assumptions"][1:]}
    assert "force 0.5 N" in assumptions["noise per test row"]
    assert "--force-sigma-N" in assumptions["noise per test row"]


@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="poppler's pdftoppm not installed")
def test_rendered_pdf_pages(run_report, tmp_path):
    """Each PDF page rendered: figure pages are not blank and nothing runs off the page."""
    import matplotlib.image as mpimg

    pdf = run_report["out"] / "report.pdf"
    subprocess.run(["pdftoppm", "-png", "-r", "40", str(pdf), str(tmp_path / "p")], check=True)
    pngs = sorted(tmp_path.glob("p-*.png"))
    assert len(pngs) == len(PdfReader(pdf).pages)
    texts = [p.extract_text() for p in PdfReader(pdf).pages]
    figure_pages = 0
    for png, text in zip(pngs, texts, strict=True):
        px = mpimg.imread(png)[..., :3]
        h, w = px.shape[:2]
        margin = px[:, : w // 40], px[:, -w // 40:], px[: h // 60], px[-h // 60:]
        assert all(m.min() > 0.9 for m in margin), f"content in the page margin: {png.name}"
        dark = (px.mean(axis=2) < 0.9).mean()
        assert dark > 0.005, f"blank page {png.name}"
        if "Figure" in text or re.search(r"\bmap\b", text):
            figure_pages += 1
            # a page with a plot has a large coloured/grey area, not just text lines
            assert dark > 0.03, png.name
    assert figure_pages >= 2
