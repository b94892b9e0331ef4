"""Shared pytest options: hardware addresses, the opt-in slow marker, loopback only."""

from __future__ import annotations

import os

import pytest

from drivers.loopback_guard import ENV as LOOPBACK_ONLY


def pytest_configure(config: pytest.Config) -> None:
    # Nothing leaves loopback: every driver this run (and every process it starts) builds
    # refuses a device off this machine, unless a real device's address was given.
    if not any(config.getoption(o) for o in ("--ft-url", "--tracker-url", "--robot-url")):
        os.environ[LOOPBACK_ONLY] = "1"


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("stiffness-campaign")
    group.addoption("--ft-url", default=None, help="Address of a real force/torque sensor.")
    group.addoption("--tracker-url", default=None, help="Address of a real laser tracker.")
    group.addoption("--robot-url", default=None, help="Address of a real robot controller.")
    group.addoption("--run-slow", action="store_true", default=False,
                    help="Run long soak and fuzzing tests (marker 'slow').")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--run-slow"):
        return
    skip = pytest.mark.skip(reason="slow: opt in with --run-slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
