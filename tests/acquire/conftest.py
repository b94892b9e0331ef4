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


def plan_and_acquire(protocol, tmp_path: Path, time_scale: float,
                     candidates: int = 2000) -> Path:
    """Plan ``protocol`` with one repeat per test into ``tmp_path/plan`` and acquire it on the
    simulated lab (``acquire --fake``: the protocol's real drivers against the fakes) into
    ``tmp_path/run``; asserts the run is complete and returns its directory."""
    from campaign.acquire.progress import QuietReporter
    from campaign.acquire.session import AcquireOptions, acquire
    from campaign.planning.planner import make_plan, write_plan

    protocol.campaign.repeats = 1
    plan, run = tmp_path / "plan", tmp_path / "run"
    write_plan(make_plan(protocol, candidates=candidates), plan, figure=False)
    outcome = acquire(plan, run, None,
                      AcquireOptions(fake=True, assume_yes=True, time_scale=time_scale),
                      QuietReporter(), say=lambda s: None)
    assert outcome.status == "complete", outcome.reason
    return run


def displacement_noise(protocol):
    """The noise model of a fake run's tests: the tracker's pose noise of the protocol with
    the displacement's variance, 1.5 sigma^2 (loaded pose minus the mean of two unloaded
    ones), and the lab's F/T noise, 0.5 N and 0.05 N m."""
    import math

    from analysis.identification.noise import NoiseModel

    pose = protocol.instruments["pose"].noise
    return NoiseModel().with_overrides(
        translation_sigma_override=pose.translation_um * 1e-6 * math.sqrt(1.5),
        rotation_sigma_override=pose.rotation_urad * 1e-6 * math.sqrt(1.5),
        force_sigma=0.5, moment_sigma=0.05)


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
