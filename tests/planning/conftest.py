"""Shared fixtures of the planning tests: example protocols and plans made once."""

from __future__ import annotations

from pathlib import Path

import pytest

from campaign.planning.planner import make_plan
from campaign.protocol import load_protocol

ROOT = Path(__file__).resolve().parents[2]
KR_FILE = ROOT / "protocols" / "kr240-2.toml"
UR_FILE = ROOT / "protocols" / "ur10e.toml"


@pytest.fixture(scope="session")
def kr_protocol():
    return load_protocol(KR_FILE)


@pytest.fixture(scope="session")
def ur_protocol():
    return load_protocol(UR_FILE)


@pytest.fixture(scope="session")
def kr_plan(kr_protocol):
    """The CLI's default plan of the KR240-2 example (D-optimal, 1e4 candidates, seed 0)."""
    return make_plan(kr_protocol, "d-optimal", seed=0, candidates=10000)
