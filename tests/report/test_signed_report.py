"""The report an engineer signs: the result and verdict first, traceable, every test listed.

A simulated run (metadata ``fake``) and a run without the flag whose protocol names the
tracker's model, serial and calibration, with one gross error injected, are analysed
once each; the HTML is parsed, the PDF text extracted with pypdf, and the numbers
compared with results.json and residuals.csv.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pypdf import PdfReader
from report_html import ReportPage
from report_runs import SIGMA, simulated_rows, write_run

from analysis.report.formatting import interval_kNm, k_kNm, sig
from campaign.cli import main

ROOT = Path(__file__).resolve().parents[2]
POSE_KEYS = ('model = "Leica AT960-MR"\nserial = "LT-777"\ncalibration_date = 2026-03-14\n'
             'calibration_due = 2027-03-14\ncertificate = "CAL-2026-0412"')


def _read(out):
    doc = ReportPage()
    html = (out / "report.html").read_text(encoding="utf-8")
    doc.feed(html)
    pages = [p.extract_text() for p in PdfReader(out / "report.pdf").pages]
    return {"out": out, "html": html, "page": doc, "text": re.sub(r"\s+", " ", " ".join(
        doc.text)), "pages": [re.sub(r"\s+", " ", p) for p in pages],
        "results": json.loads((out / "results.json").read_text())}


@pytest.fixture(scope="module")
def sim(tmp_path_factory, rows):
    run = write_run(tmp_path_factory.mktemp("signed") / "sim", [dict(r) for r in rows])
    assert main(["analyze", str(run), "--trials", "20"]) == 0
    return {**_read(run / "analysis"), "run": run}


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    rows = simulated_rows(seed=2)  # other measurements than the simulated run's
    rows[7]["dz_mm"] += 0.4  # a gross error of about 11 sigma on one component
    run = write_run(tmp_path_factory.mktemp("signed") / "real", rows, fake=False,
                    pose_keys=POSE_KEYS)
    text = (run / "protocol.toml").read_text().replace(
        "[instruments.robot]\n", '[instruments.robot]\nserial = "KR-4711"\n', 1)
    (run / "protocol.toml").write_text(text)
    meta = json.loads((run / "metadata.json").read_text())
    import hashlib

    meta["protocol_sha256"] = hashlib.sha256(text.encode()).hexdigest()
    (run / "metadata.json").write_text(json.dumps(meta))
    assert main(["analyze", str(run), "--trials", "20", "--accept-misfit"]) == 0
    return {**_read(run / "analysis"), "run": run}


@pytest.fixture(scope="module")
def misfit(tmp_path_factory):
    rows = simulated_rows(seed=4)
    offset = np.random.default_rng(7).normal(scale=0.5, size=(5, 3))  # mm, per pose
    for r in rows:
        for c, key in enumerate(("dx_mm", "dy_mm", "dz_mm")):
            r[key] += offset[r["test_id"] - 1, c]
    run = write_run(tmp_path_factory.mktemp("signed") / "misfit", rows)
    assert main(["analyze", str(run), "--trials", "10", "--accept-misfit"]) == 0
    return {**_read(run / "analysis"), "run": run}


def test_k_values_and_verdict_open_the_html_and_page_one(sim):
    res, page = sim["results"], sim["page"]
    first_table = next(iter(page.tables))
    assert first_table == "Result: joint stiffness k with 95 % intervals"
    table = page.tables[first_table]
    text_before_contents = sim["text"].split("Contents")[0]
    chi2 = f"\u03c7\u00b2/\u03bd {sig(res['chi2_reduced'], 3)}"
    for text in (text_before_contents, sim["pages"][0]):
        assert chi2 in text and f"p {sig(res['chi2_p_value'], 2)}" in text
        assert re.search(r"(Consistent with the noise model|Warnings|ACCEPTED DESPITE)", text)
        for j in range(6):
            k, (lo, hi) = res["joint_stiffness_Nm_per_rad"][j], res["ci95_Nm_per_rad"][j]
            assert k_kNm(k) in text and interval_kNm(lo, hi) in text
    for j, row in enumerate(table[1:]):
        k, (lo, hi) = res["joint_stiffness_Nm_per_rad"][j], res["ci95_Nm_per_rad"][j]
        # asymmetric intervals quoted as such: each side relative to k
        low, high = (float(v.strip(" %+")) for v in row[3].split("/"))
        assert low == pytest.approx(100 * (lo / k - 1), abs=0.006)
        assert high == pytest.approx(100 * (hi / k - 1), abs=0.006)
    # a clean simulated run: no warning, no refusal
    assert "Consistent with the noise model" in sim["pages"][0]
    assert "Robot: KUKA KR240-2" in sim["pages"][0] and "measured: 2026-11-20" in sim["pages"][0]


def test_accepted_refusal_is_said_in_red_on_page_one(real):
    res = real["results"]
    if not res["misfit_accepted"]["accepted"]:
        pytest.skip("the injected error did not make the checks refuse")
    assert "ACCEPTED DESPITE A REFUSAL" in real["pages"][0]
    assert '<p class="refusal">ACCEPTED DESPITE A REFUSAL' in real["html"]
    assert ".refusal {" in real["html"] and "color: #b00" in real["html"]


def test_simulated_on_every_page_of_a_fake_run_and_nowhere_else(sim, real):
    assert all("SIMULATED DATA" in p for p in sim["pages"])
    assert '<div class="lab-banner"' in sim["html"]
    assert all("simulat" not in p.lower() for p in real["pages"])
    assert "simulat" not in real["text"].lower()


def test_report_id_in_results_and_every_page_footer(sim, tmp_path):
    rid = sim["results"]["report_id"]
    assert re.fullmatch(r"RPT-[0-9a-f]{16}", rid)
    n = len(sim["pages"])
    for i, p in enumerate(sim["pages"], start=1):
        assert re.search(rf"Report ID {rid} · generated \d{{4}}-\d\d-\d\d \d\d:\d\d UTC", p)
        assert f"page {i} of {n}" in p
    assert rid in sim["text"]
    # stable: the same inputs give the same ID; one changed digit of tests.csv another
    copy = shutil.copytree(sim["run"], tmp_path / "copy", ignore=shutil.ignore_patterns(
        "analysis"))
    assert main(["analyze", str(copy), "--no-report"]) == 0
    assert json.loads((copy / "analysis" / "results.json").read_text())["report_id"] == rid
    tests = (copy / "tests.csv").read_text().splitlines()
    cells = tests[3].split(",")
    cells[15] = repr(float(cells[15]) + 1e-4)  # dz of one row, +0.1 um
    (copy / "tests.csv").write_text("\n".join(tests[:3] + [",".join(cells)] + tests[4:]) + "\n")
    assert main(["analyze", str(copy), "--no-report", "--force"]) == 0
    assert json.loads((copy / "analysis" / "results.json").read_text())["report_id"] != rid


def test_traceability_hashes_and_instruments(real):
    import hashlib

    rows = {r[0]: r[1] for r in real["page"].tables["Campaign"][1:]}
    run = real["run"]
    assert rows["tests.csv SHA-256"] == hashlib.sha256((run / "tests.csv").read_bytes()
                                                       ).hexdigest()
    assert rows["protocol SHA-256"] == hashlib.sha256((run / "protocol.toml").read_bytes()
                                                      ).hexdigest()
    assert rows["campaign"].startswith("KR240-2 joint stiffness")
    inst = {r[0]: r for r in real["page"].tables["Instruments and calibration"][1:]}
    # the protocol names the serial, the device reported another at connection: both shown
    assert inst["pose"][1:] == ["Leica AT960-MR", "LT-777 (device reports LT-123)",
                                "2026-03-14", "2027-03-14",
                                "CAL-2026-0412"]
    assert "Robot: KUKA KR240-2 (serial KR-4711)" in real["pages"][0]
    approval = real["page"].tables["Approval"]
    assert [r[0] for r in approval[1:]] == ["analysed by", "checked by", "approved by"]
    assert all(c == "" for r in approval[1:] for c in r[1:])


def test_every_test_row_is_listed_with_residuals_before_and_after(sim):
    res = sim["results"]
    table = sim["page"].tables["Tests: what was done and what each shows"]
    rows = table[1:]
    assert len(rows) == res["n_tests"] == 15
    resid = pd.read_csv(sim["out"] / "residuals.csv")
    assert [int(r[1]) for r in rows] == sorted(resid["line"].unique().tolist())
    for row in rows:
        part = resid[resid["line"] == int(row[1])]
        t = part[part["unit"] == "m"]["residual"].to_numpy()
        r = part[part["unit"] == "rad"]["residual"].to_numpy()
        assert row[-1] == f"{1e6 * np.linalg.norm(t):.1f} / {1e6 * np.linalg.norm(r):.1f}"
        assert re.fullmatch(r"eq22[a-z-]* \([a-z-]+\)", row[3]), row[3]  # a planned case
    rms = {r[0]: r for r in sim["page"].tables["Residual RMS: nominal model against "
                                               "identified"][1:]}
    # nominal = the simulated truth (Table 2): both models leave about the noise
    for key, s in (("translation (\u00b5m)", SIGMA[0]), ("rotation (\u00b5rad)", SIGMA[3])):
        nominal, identified = float(rms[key][1]), float(rms[key][2])
        assert 0.4 * 1e6 * s < identified <= nominal * 1.05 < 2.5 * 1e6 * s


def _circled(monkeypatch, resid: pd.DataFrame, threshold: float) -> tuple[int, int, str]:
    """(points circled as outliers, points crossed as set aside, caption) of the
    report's residual figure drawn from ``resid``."""
    import analysis.report.figures as figures

    drawn = {}
    real_png = figures._png
    monkeypatch.setattr(figures, "_png", lambda fig, name, caption: (
        drawn.setdefault("fig", fig), real_png(fig, name, caption))[1])
    fig = figures.residual_plot(resid, threshold)
    lines = {ln.get_label(): len(ln.get_xdata()) for ax in drawn["fig"].axes
             for ln in ax.get_lines()}
    return (lines.get("outlier", 0), lines.get("set aside by the outlier test", 0),
            fig.caption)


def _check_outliers(run: dict, monkeypatch) -> int:
    res = run["results"]
    resid = pd.read_csv(run["out"] / "residuals.csv")
    threshold = res["outlier_threshold_studentized"]
    beyond = int((resid["studentized"].abs() > threshold).sum())
    flagged = int(resid["outlier"].sum())
    assert flagged == beyond
    assert (resid["outlier"] == (resid["studentized"].abs() > threshold)).all()
    aside = int(resid["set_aside"].sum())
    table = run["page"].tables["Residuals (measured - model) per test and component"]
    stars = sum(c.endswith(" *") for r in table[1:] for c in r)
    assert stars == flagged
    circled, crossed, caption = _circled(monkeypatch, resid, threshold)
    assert circled == flagged and crossed == (aside if aside != flagged else 0)
    shown = next(alt for alt, _ in run["page"].figures if alt.startswith("Studentized"))
    assert f"{flagged} outlier(s): residuals beyond the dashed lines at " \
        f"\u00b1{threshold:.2f}, circled in red" in shown
    assert caption.split(" Shown:")[0] in shown
    verdict = f"{flagged} outlier(s) (|studentized residual| > {threshold:.2f})"
    assert verdict in run["pages"][0] and verdict in run["text"]
    return aside


def test_outlier_flags_equal_the_count_beyond_the_threshold(real, monkeypatch):
    """An injected gross error: every residual beyond the threshold is an outlier, the
    sequential test's set-aside rows are their own column."""
    aside = _check_outliers(real, monkeypatch)
    resid = pd.read_csv(real["out"] / "residuals.csv")
    # the glitch (line 8's dz, 11 sigma) is set aside and beyond the threshold
    line = sorted(resid["line"].unique())[7]
    glitch = resid[(resid["line"] == line) & (resid["component"] == "dz")]
    assert glitch["set_aside"].all() and glitch["outlier"].all() and aside >= 1


def test_outliers_of_a_misfit_run_agree_with_the_figure(misfit, monkeypatch):
    """A campaign simulated with a wrong model (a 0.5 mm offset per pose the joint
    model cannot explain), accepted with --accept-misfit: more residuals beyond the
    threshold than the sequential test's budget sets aside."""
    from analysis.identification.checks.outliers import MAX_OUTLIERS

    assert misfit["results"]["misfit_accepted"]["accepted"]
    aside = _check_outliers(misfit, monkeypatch)
    resid = pd.read_csv(misfit["out"] / "residuals.csv")
    assert int(resid["outlier"].sum()) > aside and aside <= MAX_OUTLIERS + 1
    assert f", {aside} set aside by the outlier test" in misfit["pages"][0]


def test_one_percent_format_as_the_terminal(sim, real, misfit):
    """'95 %' with a space, as the terminal prints it, in every text of the HTML and PDF
    (tables, captions, warnings, verdict) and in results.json's warnings."""
    for run in (sim, real, misfit):
        html = re.sub(r"<style>.*?</style>", "", run["html"], flags=re.S)  # CSS: 100%
        html = re.sub(r"<img [^>]*>", "", html)  # the figures' base64 data
        words = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))
        for text in [words, *run["pages"], *run["results"]["warnings"]]:
            assert not re.search(r"\d%", text), re.search(r".{40}\d%.{20}", text)
        assert "95 % interval" in words


def test_red_is_for_failures_only(sim):
    """The reference outside an interval is a column, not a highlighted (red) row."""
    html = sim["html"]
    stiff = html.split("<h3>Stiffness with standard errors and reference values</h3>")[1]
    stiff = stiff.split("</table>")[0]
    assert 'class="marked"' not in stiff
    assert "nominal in interval" in stiff


def test_viewport_and_scrollable_tables(sim):
    html = sim["html"]
    assert '<meta name="viewport" content="width=device-width, initial-scale=1">' in html
    assert html.count("<table") == html.count('<div class="scroll"><table')
    assert "@media print" in html and "break-inside: avoid" in html


def test_figure_texts_have_no_literal_underscore(monkeypatch, tmp_path, rows):
    import analysis.report.write as write

    captured = []
    real_write = write.write_report
    monkeypatch.setattr(write, "write_report",
                        lambda report, out: (captured.append(report), real_write(report, out))[1])
    run = write_run(tmp_path / "run", [dict(r) for r in rows])
    assert main(["analyze", str(run), "--trials", "10"]) == 0
    figures = [b for s in captured[0].sections for b in s.blocks if hasattr(b, "texts")]
    assert len(figures) == 6
    for f in figures:
        assert f.texts, f.name
        for text in f.texts:
            plain = re.sub(r"\$[^$]*\$", "", text)  # mathtext may use _ for subscripts
            assert "_" not in plain, (f.name, text)


def _part_path(path):
    with path.open("w") as fh:
        fh.write("x_mm,y_mm,z_mm,ax,ay,az\n")
        for a in np.linspace(0, 2 * np.pi, 12, endpoint=False):
            fh.write(f"{80 * np.cos(a):.6f},{80 * np.sin(a):.6f},0,0,0,-1\n")
    return path


#: the pictures of compensate, place and robustness, small enough for a test (seconds)
OTHER_PICTURES = {
    "compensate": lambda tmp: ["compensate", "--robot", "kr240-2", "--path",
                               str(ROOT / "examples" / "kr240-2_path.csv"), "--out",
                               str(tmp / "c"), "--wrench", "0,1000,-1500,100,50,0"],
    "place": lambda tmp: ["place", "--robot", "kr240-2", "--path",
                          str(_part_path(tmp / "part.csv")), "--out", str(tmp / "p"),
                          "--x-mm", "1400..1800", "--y-mm", "-200..200", "--z-mm", "200",
                          "--x-step-mm", "200", "--y-step-mm", "200",
                          "--tool-angle-step-deg", "30", "--config", "-1,-1,-1",
                          "--wrench", "0,0,-1000,0,0,0", "--workers", "0"],
    "robustness": lambda tmp: ["robustness", "--robot", "kr240-2", "--tests", "3,6",
                               "--trials", "20", "--out", str(tmp / "r")],
}


@pytest.mark.parametrize("command", sorted(OTHER_PICTURES))
def test_other_pictures_have_no_literal_underscore(command, monkeypatch, tmp_path):
    """Every text drawn in the PNGs of compensate, place and robustness (titles, axes,
    legends, colour bars): no underscore outside mathtext, except inside a file name
    (``kr240-2_path.csv`` is that file's name, not a subscript)."""
    from matplotlib.figure import Figure as MplFigure
    from matplotlib.text import Text

    drawn = []
    real_save = MplFigure.savefig

    def save(fig, *args, **kwargs):
        drawn.append([t.get_text() for t in fig.findobj(match=Text)
                      if t.get_visible() and t.get_text().strip()])
        return real_save(fig, *args, **kwargs)

    monkeypatch.setattr(MplFigure, "savefig", save)
    assert main(OTHER_PICTURES[command](tmp_path)) == 0
    assert drawn, command
    words = 0
    for texts in drawn:
        assert any(re.search("[a-z]{3}", t) for t in texts)  # titles and labels, not ticks
        for text in texts:
            plain = re.sub(r"\$[^$]*\$", "", text)
            plain = re.sub(r"\S+\.(csv|toml|json)\b", "", plain)  # file names
            assert "_" not in plain, (command, text)
            words += len(plain.split())
    assert words > 10


@pytest.mark.skipif(shutil.which("pdftoppm") is None,
                    reason="poppler-utils (pdftoppm) not installed: apt-get install poppler-utils")
def test_rendered_pdf_pages_are_not_mostly_blank(sim, tmp_path):
    import matplotlib.image as mpimg

    subprocess.run(["pdftoppm", "-png", "-r", "30", str(sim["out"] / "report.pdf"),
                    str(tmp_path / "p")], check=True)
    pngs = sorted(tmp_path.glob("p-*.png"))
    assert len(pngs) == len(sim["pages"])
    for png in pngs[:-1]:
        px = mpimg.imread(png)[..., :3].mean(axis=2)
        h = px.shape[0]
        body = px[int(0.07 * h): int(0.92 * h)]  # between the banner and the footer
        blank = float(np.mean(body.min(axis=1) > 0.97))  # pixel rows with nothing drawn
        assert blank <= 0.70, f"{png.name}: {blank:.0%} blank"


PROBE = """<script>
window.addEventListener('load', function () {
  var t = document.querySelector('table').getBoundingClientRect();
  var v = document.querySelector('.verdict, .warning, .refusal').getBoundingClientRect();
  var wide = 0;
  document.querySelectorAll('.scroll').forEach(function (d) {
    if (d.getBoundingClientRect().right > window.innerWidth + 1) { wide += 1; } });
  var p = document.createElement('pre'); p.id = 'probe';
  p.textContent = JSON.stringify({page: document.documentElement.scrollWidth,
    width: window.innerWidth, table: t.bottom, verdict: v.bottom, wide: wide});
  var host = window.parent !== window ? window.parent.document : document;
  host.body.appendChild(p);
});
</script>"""


def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_chromium() is None,
                    reason="chromium not installed: apt-get install chromium")
@pytest.mark.parametrize("width", [390, 1280])
def test_html_in_chromium_first_screen_and_width(sim, tmp_path, width):
    """Headless Chromium: at 1280 x 800 the verdict and the k table are on the first
    screen; at 390 and 1280 px nothing is wider than the window (wide tables scroll in
    their own box); a screenshot is taken at each width."""
    probe = tmp_path / "probe.html"
    html = sim["html"].replace("</body>", PROBE + "</body>")
    # at 390 px the page is shown in an iframe of that width (headless windows are >= 500)
    if width < 500:
        from html import escape

        html = (f'<!DOCTYPE html><html><body style="margin:0"><iframe id="f" width="{width}" '
                f'height="800" srcdoc="{escape(html)}"></iframe></body></html>')
    probe.write_text(html, encoding="utf-8")
    base = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu",
            f"--window-size={max(width, 500)},800"]
    shot = tmp_path / "shot.png"
    subprocess.run([*base, f"--screenshot={shot}", (sim["out"] / "report.html").as_uri()],
                   check=True, capture_output=True, timeout=120)
    assert shot.stat().st_size > 10_000
    dom = subprocess.run([*base, "--virtual-time-budget=5000", "--dump-dom", probe.as_uri()],
                         check=True, capture_output=True, text=True, timeout=120).stdout
    found = re.search(r'<pre id="probe">([^<]*)</pre>', dom)
    assert found, "the probe did not run"
    m = json.loads(found.group(1))
    assert m["page"] <= m["width"], m  # no horizontal scroll of the page
    assert m["wide"] == 0, m
    assert m["width"] == width
    if width >= 1280:
        assert m["verdict"] < 800 and m["table"] < 800, m  # the first screen


def test_instrument_keys_are_validated(tmp_path):
    from report_runs import PROTOCOL

    from analysis.errors import InputError
    from campaign.protocol import load_protocol

    good = tmp_path / "good.toml"
    good.write_text(PROTOCOL.read_text().replace("[instruments.pose]\n",
                                                 f"[instruments.pose]\n{POSE_KEYS}\n", 1))
    spec = load_protocol(good).instruments["pose"]
    assert (spec.model, spec.serial, str(spec.calibration_date)) == (
        "Leica AT960-MR", "LT-777", "2026-03-14")
    bad = tmp_path / "bad.toml"
    bad.write_text(PROTOCOL.read_text().replace(
        "[instruments.pose]\n", '[instruments.pose]\ncalibration_date = "14 March"\n', 1))
    with pytest.raises(InputError, match="calibration_date"):
        load_protocol(bad)


def _boxes_overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@pytest.mark.parametrize("which", ["kappa", "deflection"])
def test_pose_labels_never_overlap_and_near_poses_are_listed(which):
    """Poses 4 and 5 0.2 deg apart (the demo's), three more near each other: every label is
    drawn where it overlaps no other, and the caption lists the coinciding poses."""
    from analysis.report import figures

    t2, t3 = np.meshgrid(np.linspace(-40, 140, 30), np.linspace(-220, 60, 30))
    table = pd.DataFrame({"theta2_deg": t2.ravel(), "theta3_deg": t3.ravel(),
                          "inv_kappa_F": np.abs(np.sin(np.radians(t3.ravel()))),
                          "deflection_mm": 1 + np.abs(np.cos(np.radians(t2.ravel())))})
    deg = np.array([[0, 40, -200], [0, 60, -100], [0, 41, -198], [0, 90, 10], [0, 90.2, 10.1],
                    [0, 139, 59]])
    q = np.radians(np.column_stack([deg, np.zeros((6, 3))]))
    labels = ["1", "2", "3", "4", "5", "6"]
    if which == "kappa":
        fig = figures.poses_on_kappa_map(table, q, labels, "\u03b81 = 0 deg")
    else:
        fig = figures.deflection_joint_map(table, q, "f = (0, 0, 1) N", "\u03b81 = 0 deg",
                                           labels)
    boxes = fig.label_boxes
    assert len(boxes) == 6
    for i in range(6):
        for j in range(i + 1, 6):
            assert not _boxes_overlap(boxes[i], boxes[j]), (labels[i], labels[j])
    assert "Nearly coinciding on this map" in fig.caption and "4, 5" in fig.caption


def test_plan_map_lists_coinciding_poses_and_sets_their_labels_apart(monkeypatch, tmp_path):
    """plan_map.png: two planned poses 0.1 deg apart are listed under the title and
    their labels (the report's placement) overlap neither each other nor the others."""
    import analysis.output_files as output_files
    from campaign.planning.plan_map import draw_plan_map
    from campaign.planning.planner import make_plan

    plan = make_plan(_kr_protocol(), "d-optimal", seed=5, candidates=2000)
    chosen = np.unique(plan.chosen.pose)
    q = plan.candidates.q
    q[chosen[1], 1:3] = q[chosen[0], 1:3] + np.radians([0.1, -0.1])
    drawn = {}
    monkeypatch.setattr(output_files, "save_figure",
                        lambda fig, path, **kw: drawn.setdefault("fig", fig))
    draw_plan_map(plan, tmp_path / "plan_map.png")
    fig = drawn["fig"]
    title = fig.axes[0].get_title()
    assert "Nearly coinciding on this map (within" in title and "): 1, 2." in title
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)  # the figure was closed after saving
    canvas.draw()
    renderer = canvas.get_renderer()
    boxes = [tuple(t.get_window_extent(renderer).extents) for t in fig.pose_labels]
    assert len(boxes) == len(chosen)
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not _boxes_overlap(boxes[i], boxes[j]), (i + 1, j + 1)


def _kr_protocol():
    from campaign.protocol import load_protocol

    return load_protocol(ROOT / "protocols" / "kr240-2.toml")


def test_time_stamps_are_shown_to_the_second():
    from analysis.report.formatting import utc_text

    assert utc_text("2026-11-20T09:58:00.123456+00:00") == "2026-11-20 09:58:00 UTC"
    assert utc_text("2026-11-20T10:58:00Z") == "2026-11-20 10:58:00 UTC"
    assert utc_text("2026-11-20T11:58:00+01:00") == "2026-11-20 10:58:00 UTC"
    assert utc_text(None) == "-" and utc_text("unknown") == "unknown"


def test_robustness_rows_not_identifiable_are_marked():
    from analysis.identification.studies.robustness_plot import identifiable_rows

    summary = pd.DataFrame({
        "trials": [200, 200, 200], "trials_rejected": [0, 30, 0],
        "iqr_Nm_per_rad": [10e3, 10e3, 600e3], "k_true_Nm_per_rad": [400e3] * 3})
    # fine; 15 % of the trials rejected; a spread (IQR / 1.349 = 445 kN m/rad) above k
    assert identifiable_rows(summary).tolist() == [True, False, False]


def test_map_labels_have_no_literal_underscore():
    from analysis.kinetostatics.map_plots import LABELS

    for text in LABELS.values():
        assert "_" not in re.sub(r"\$[^$]*\$", "", text), text


def test_compare_writes_a_report_naming_both_runs(sim, real, tmp_path, capsys):
    out = tmp_path / "cmp"
    plot = tmp_path / "compare.pdf"
    assert main(["compare", str(sim["out"]), str(real["out"]), "--report", str(out),
                 "--plot", str(plot), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    page = ReportPage()
    page.feed((out / "report.html").read_text(encoding="utf-8"))
    text = re.sub(r"\s+", " ", " ".join(page.text))
    runs = {r[0]: r for r in page.tables["Runs compared"][1:]}
    assert runs["A"][4] == sim["results"]["report_id"]
    assert runs["B"][4] == real["results"]["report_id"]
    assert runs["A"][3] == "2026-11-20 09:58:00 UTC"
    assert ("No evidence of change" in text) or ("Changed: " in text)
    rows = page.tables["Difference per joint"][1:]
    assert len(rows) == len(res["joints"]) == 6
    for row, r in zip(rows, res["joints"], strict=True):
        lo, hi = (float(v) for v in row[4].strip("[]").split(","))
        # the interval at the verdict's level excludes 0 when the verdict is changed (unless
        # the comparison flags the joint as borderline)
        assert row[6].startswith(r["verdict"])
        if "note" not in r:
            assert (lo > 0 or hi < 0) == (r["verdict"] == "changed")
        half = res["critical_z"] * np.hypot(r["se_A_Nm_per_rad"], r["se_B_Nm_per_rad"]) / 1e3
        assert hi - lo == pytest.approx(2 * half, rel=2e-3, abs=2e-3)
    pages = [p.extract_text() for p in PdfReader(out / "report.pdf").pages]
    # A came from the simulated lab, B did not: the banner names A, not "this run"
    assert all("SIMULATED DATA" in p and "run A (" in p and "this run" not in p
               for p in [re.sub(r"\s+", " ", p) for p in pages])
    assert "run A (" in (out / "report.html").read_text(encoding="utf-8").split(
        'class="lab-banner"')[1].split("</div>")[0]
    # the plot of --plot names A and B with their dates and robots
    drawn = re.sub(r"\s+", " ", PdfReader(plot).pages[0].extract_text())
    for label, run in (("A", sim), ("B", real)):
        # no campaign name in these runs' metadata: the run directory's name
        assert f"{label}: {run['run'].name}, measured 2026-11-20 09:58:00 UTC" in drawn, drawn
        assert "KR240" in drawn.split(f"{label}: ")[1]
    assert "(simulated)" in drawn.split("A: ")[1].split("B: ")[0]
    assert "(simulated)" not in drawn.split("B: ")[1]


def test_a_failed_row_makes_the_verdict_a_warning(complete_report):
    out = complete_report
    first = re.sub(r"\s+", " ", PdfReader(out / "report.pdf").pages[0].extract_text())
    assert "Warnings: 1 failed test row(s): see Data quality" in first
    assert "Consistent with the noise model" not in first
    html = (out / "report.html").read_text(encoding="utf-8")
    assert '<p class="warning">Warnings: 1 failed test row(s)' in html


def test_held_out_check_reads_the_total_uncertainty_columns_when_present():
    """The validation's total-uncertainty ratio, limit and flag are presented as given."""
    from types import SimpleNamespace

    from analysis.report.verdict import held_out

    v = pd.DataFrame({"held_out_pose": ["1", "2", "3"], "n_tests": [3, 3, 3],
                      "rms_normalized": [0.9, 2.81, 1.1],
                      "rms_normalized_total": [0.8, 1.4, 2.6],
                      "limit_normalized_total": [1.9, 1.9, 1.9],
                      "beyond_limit": [False, False, True]})
    ho = held_out(SimpleNamespace(validation=v))
    # pose 2 is not flagged (its prediction is uncertain), pose 3 is
    assert ho.flagged == ["pose 3 (2.60)"]
    assert "RMS error / total sigma (noise and prediction) median 1.40, max 2.60 (pose 3; " \
        "limit 1.90, Sidak)" in ho.text
    old = v[["held_out_pose", "n_tests", "rms_normalized"]]
    ho = held_out(SimpleNamespace(validation=old))  # without them: the noise-only ratio
    assert ho.flagged == ["pose 2 (2.81)"] and "limit 2" in ho.text


def test_a_long_campaign_lists_every_test_in_an_appendix(tmp_path):
    """45 tests (three simulated runs' rows, imported as CSV): the table of tests moves to
    an appendix at the end, still one row per test, load cases those of the file."""
    from report_runs import write_csv

    rows = simulated_rows(seed=3) + simulated_rows(seed=4) + simulated_rows(seed=5)
    csv = write_csv(tmp_path / "tests.csv", rows)
    out = tmp_path / "out"
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out",
                 str(out), "--trials", "10", "--tool-xyz-mm", "0,0,0",
                 "--translation-sigma-um", f"{1e6 * SIGMA[0]:.4f}",
                 "--rotation-sigma-urad", f"{1e6 * SIGMA[3]:.4f}",
                 "--force-sigma-N", "0.5", "--moment-sigma-Nm", "0.05"]) == 0
    page = ReportPage()
    page.feed((out / "report.html").read_text(encoding="utf-8"))
    assert page.h2[-1] == "Appendix: tests"
    table = page.tables["Tests: what was done and what each shows"][1:]
    assert len(table) == 45
    assert [int(r[1]) for r in table] == list(range(2, 47))  # CSV lines, header = 1
    assert {r[3] for r in table} <= {f"load case {i} (as measured)" for i in range(1, 5)}
    pages = [p.extract_text() for p in PdfReader(out / "report.pdf").pages]
    assert "Appendix: tests" in pages[-1] or any("Appendix: tests" in p for p in pages[-3:])
