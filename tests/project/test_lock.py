"""requirements.lock holds every dependency of pyproject.toml (and of its test extra) at
a version pyproject allows, each with its sha256 hashes: the README's install and
.ci/run install exactly it (``pip install --require-hashes``). A dependency added to
pyproject.toml without ``tools/update-lock --lock-only`` fails here, naming it."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[2]
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==(\S+)(?:\s*;\s*([^\\]+?))?\s*\\?$")


def _pins() -> dict[str, list[tuple[str, str | None, int]]]:
    """{name: [(version, marker, hashes)]} of requirements.lock."""
    out: dict = {}
    lines = (ROOT / "requirements.lock").read_text().splitlines()
    for i, line in enumerate(lines):
        m = PIN.match(line)
        if not m:
            continue
        hashes = 0
        for follow in lines[i + 1:]:
            if not follow.startswith("    --hash=sha256:"):
                break
            hashes += 1
        out.setdefault(canonicalize_name(m[1]), []).append((m[2], m[3], hashes))
    return out


def test_every_dependency_is_locked_within_its_range():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pins = _pins()
    env = default_environment()
    for spec in project["dependencies"] + project["optional-dependencies"]["test"]:
        req = Requirement(spec)
        name = canonicalize_name(req.name)
        assert name in pins, f"{name} is not in requirements.lock: tools/update-lock --lock-only"
        versions = [v for v, marker, _ in pins[name]
                    if marker is None or Requirement(f"x; {marker}").marker.evaluate(env)]
        assert versions, f"{name}: no pin for this Python/platform"
        for v in versions:
            assert req.specifier.contains(v, prereleases=True), f"{name}=={v} not in {spec}"


def test_every_pin_is_exact_and_hashed():
    pins = _pins()
    assert len(pins) > 50
    assert "psycopg-binary" in pins and "distributed" in pins  # the extras' packages
    for name, entries in pins.items():
        for version, _, hashes in entries:
            assert hashes >= 1, f"{name}=={version} has no hash"
    text = (ROOT / "requirements.lock").read_text()
    assert not re.search(r"^[A-Za-z0-9][^\s#]*\s*(>=|<=|~=|>|<)", text, re.M)
