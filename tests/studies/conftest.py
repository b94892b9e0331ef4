"""Fixtures of the identification-quality tests: a protocol of a robot file the tests write."""

from __future__ import annotations

from pathlib import Path

import pytest

from campaign.protocol import load_protocol
from tests.studies._own_robot import write_protocol


@pytest.fixture(scope="session")
def own_protocol_path(tmp_path_factory):
    """Protocol (F/T noise 0.5 N, 0.05 N m) of the test-written 6R arm."""
    return write_protocol(tmp_path_factory.mktemp("own"))


ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def ur_protocol():
    return load_protocol(ROOT / "protocols" / "ur10e.toml")


@pytest.fixture(scope="session")
def kr_protocol():
    return load_protocol(ROOT / "protocols" / "kr240-2.toml")
