"""Fixtures of the acquisition tests: a KR240-2 plan directory and small variants of it."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = ROOT / "protocols" / "kr240-2.toml"
#: simulated time runs this much faster than the wall clock in the tests
TIME_SCALE = 100.0


@pytest.fixture(scope="session")
def kr240_plan(tmp_path_factory) -> Path:
    """Plan directory of the built-in KR240-2 protocol (5 tests x 3 repeats)."""
    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    out = tmp_path_factory.mktemp("plan")
    write_plan(make_plan(load_protocol(PROTOCOL), candidates=2000), out, figure=False)
    return out


def variant(plan: Path, dest: Path, tests: int | None = None, repeats: int | None = None,
            edit=None) -> Path:
    """Copy of ``plan`` with fewer tests/repeats, or rows edited by ``edit(frame)``."""
    shutil.copytree(plan, dest)
    df = pd.read_csv(dest / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    if tests is not None:
        df = df.iloc[:tests]
    if repeats is not None:
        df["repeats"] = repeats
    if edit is not None:
        df = edit(df)
    df.to_csv(dest / "plan.csv", index=False)
    return dest


@pytest.fixture
def small_plan(kr240_plan, tmp_path) -> Path:
    """Three tests, one repeat each."""
    return variant(kr240_plan, tmp_path / "small_plan", tests=3, repeats=1)


def _cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "campaign", *args], capture_output=True,
                          text=True, timeout=timeout, cwd=ROOT)


@pytest.fixture
def cli():
    """``cli(*args)`` runs ``campaign ARGS`` in a subprocess."""
    return _cli


@pytest.fixture
def time_scale() -> float:
    return TIME_SCALE


@pytest.fixture
def make_variant():
    """``make_variant(plan, dest, tests=, repeats=, edit=)``: a modified copy of a plan."""
    return variant
