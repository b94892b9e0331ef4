"""The shipped protocols are package data: a wheel holds them and an installed copy finds them.

The wheel is built offline from a copy of the sources (``pip wheel --no-deps
--no-build-isolation``: the installed setuptools, nothing downloaded, nothing written
into the source tree), installed (not editable) into a directory of its own, and a new
interpreter that imports the package from there alone finds every protocol of the
source tree's ``campaign/protocols/`` through importlib.resources, in that directory.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ("pyproject.toml", "README.md", "campaign", "drivers", "analysis")
PROBE = """
import json, campaign
from campaign.jobs.demo import DemoOptions, demo_protocol
from campaign.protocol import load_protocol
from campaign.shipped_protocols import shipped_folder, shipped_protocols
found = shipped_protocols()
print(json.dumps({"package": campaign.__file__, "folder": str(shipped_folder()),
                  "names": sorted(found), "demo": str(demo_protocol(DemoOptions(out="x"))),
                  "campaign_name": load_protocol(found["kr240-2"]).campaign.name}))
"""


def _setuptools_version() -> tuple[int, ...]:
    try:
        from importlib.metadata import version

        return tuple(int(p) for p in version("setuptools").split(".")[:2])
    except Exception:
        return (0,)


@pytest.mark.timeout(180)
def test_wheel_ships_the_protocols_and_the_installed_reader_finds_them(tmp_path):
    if _setuptools_version() < (77,):
        pytest.skip("setuptools >= 77 is needed to build the wheel offline "
                    "(pip install 'setuptools>=77')")
    src = tmp_path / "src"
    src.mkdir()
    for name in SOURCES:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy2(path, src / name)
    wheels = tmp_path / "wheels"
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps",
                            "--no-build-isolation", "--no-index", "-q", "-w", str(wheels),
                            str(src)], capture_output=True, text=True, timeout=150)
    assert build.returncode == 0, build.stderr
    (wheel,) = wheels.glob("*.whl")
    shipped = sorted(p.name for p in (ROOT / "campaign" / "protocols").glob("*.toml"))
    assert {"kr240-2.toml", "ur10e.toml"} <= set(shipped)
    names = zipfile.ZipFile(wheel).namelist()
    assert {f"campaign/protocols/{n}" for n in shipped} <= set(names)
    assert "campaign/protocols/README.md" in names
    assert not [n for n in names if n.startswith("campaign/protocols/examples/")]
    # the fleet ledger's Alembic scripts are package data (opening a ledger runs them)
    migrations = sorted(str(p.relative_to(ROOT)) for p in
                        (ROOT / "campaign" / "ledger" / "migrations").rglob("*.py"))
    assert "campaign/ledger/migrations/versions/0001_initial.py" in migrations
    assert set(migrations) <= set(names)

    target = tmp_path / "installed"
    install = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps",
                              "--no-index", "-q", "--target", str(target), str(wheel)],
                             capture_output=True, text=True, timeout=120)
    assert install.returncode == 0, install.stderr
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {**os.environ, "PYTHONPATH": str(target)}
    probe = subprocess.run([sys.executable, "-c", PROBE], cwd=elsewhere, env=env,
                           capture_output=True, text=True, timeout=120)
    assert probe.returncode == 0, probe.stderr
    got = json.loads(probe.stdout.strip().splitlines()[-1])
    assert Path(got["package"]).is_relative_to(target)  # not the source tree
    assert Path(got["folder"]) == target / "campaign" / "protocols"
    assert got["names"] == sorted(n.removesuffix(".toml") for n in shipped)
    assert Path(got["demo"]) == target / "campaign" / "protocols" / "kr240-2.toml"
    assert got["campaign_name"]
