"""Shared pytest options: hardware addresses and the opt-in slow marker."""

from __future__ import annotations

import pytest


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
