"""``campaign analyze`` imports matplotlib only to make the report's figures, never pyplot;
scipy.spatial (the k-d tree of the held-out clusters) only for hundreds of poses.

Each run is a fresh interpreter, so ``sys.modules`` holds what that path imported.
"""

from __future__ import annotations

import json
import subprocess
import sys

PROBE = """
import json, sys
from campaign.cli import main
status = main({args!r})
print("PROBE=" + json.dumps({{"status": status, "modules": sorted(
    m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")),
    "spatial": "scipy.spatial" in sys.modules}}))
"""


def run_analyze(args: list[str]) -> dict:
    proc = subprocess.run([sys.executable, "-c", PROBE.format(args=args)], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    line = [s for s in proc.stdout.splitlines() if s.startswith("PROBE=")][-1]
    return json.loads(line.removeprefix("PROBE="))


def test_analyze_without_report_imports_no_matplotlib(complete_run, tmp_path):
    out = tmp_path / "no-report"
    probe = run_analyze(["analyze", str(complete_run), "--no-report", "--out", str(out)])
    assert probe["status"] == 0
    assert probe["modules"] == []
    assert not probe["spatial"]  # a few poses: their close pairs without the k-d tree
    assert json.loads((out / "results.json").read_text())["joint_stiffness_Nm_per_rad"]
    assert not (out / "report.html").exists()


def test_analyze_report_draws_without_pyplot(complete_run, tmp_path):
    out = tmp_path / "report"
    probe = run_analyze(["analyze", str(complete_run), "--trials", "10", "--out", str(out)])
    assert probe["status"] == 0
    assert "matplotlib.figure" in probe["modules"]
    assert "matplotlib.pyplot" not in probe["modules"]
    html = (out / "report.html").read_text(encoding="utf-8")
    assert html.count("data:image/png;base64,") >= 3
