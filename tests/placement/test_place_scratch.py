"""``campaign place`` on a local Dask cluster leaves nothing in the system's temporary
directory: Dask's ``dask-scratch-space`` goes to a directory of the search's own, removed
with it (issue 29, item 7)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.timeout(300)
ROOT = Path(__file__).parents[2]


def test_local_cluster_leaves_no_scratch_space(tmp_path):
    temp = tmp_path / "tmp"
    temp.mkdir()
    shutil.copy(ROOT / "examples" / "part_circle.csv", tmp_path / "part.csv")
    env = {**os.environ, "TMPDIR": str(temp)}
    proc = subprocess.run(
        [sys.executable, "-m", "campaign", "place", "--robot", "kr240-2", "--path",
         "part.csv", "--out", "p", "--x-mm", "1400..1800", "--y-mm", "-200..200",
         "--z-mm", "200", "--x-step-mm", "40", "--y-step-mm", "40",
         "--tool-angle-step-deg", "30", "--config", "-1,-1,-1", "--workers", "1"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=280)
    assert proc.returncode == 0, proc.stderr
    placement = json.loads((tmp_path / "p" / "placement.json").read_text())
    assert placement  # the search ran on the cluster and wrote its answer
    assert sorted(os.listdir(temp)) == []
