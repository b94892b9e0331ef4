"""One Playwright per test session: a second sync_playwright() started while the shared
one (tests/conftest.py's ``browser``, used by the web and the ledger's Fleet view tests)
is alive fails with "Sync API inside the asyncio loop", so browser tests take the shared
fixtures instead."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_only_the_root_conftest_starts_playwright():
    starts = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "tests").rglob("*.py")
                    if "sync_playwright(" in p.read_text(encoding="utf-8")
                    and p.name != "test_one_playwright.py")
    assert starts == ["tests/conftest.py"], starts
