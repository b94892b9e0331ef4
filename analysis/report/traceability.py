"""Traceability of a report: its ID, the software that made it, the time it was made.

The report ID is a stable hash of the inputs and the results: the SHA-256 of
``results.json`` (as written, without ``report_id``, keys sorted) and of the
input files' hashes (tests.csv or the imported file, plan, protocol). The same
inputs analysed with the same options and software give the same ID; any
change of a measurement, of the plan, of the protocol or of a result gives
another. It is written into ``results.json`` as ``report_id`` and printed in
the footer of every PDF page.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
from datetime import UTC, datetime
from pathlib import Path

from analysis.errors import InputError

#: hex digits of the SHA-256 kept in the report ID (64 bits: no collision in practice)
ID_DIGITS = 16


def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a file, read in 1 MB chunks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def report_id(results: dict, inputs: dict[str, str]) -> str:
    """The report ID of ``results`` (results.json as a dict) and ``inputs`` (name ->
    SHA-256 of an input file; empty values are left out), as ``RPT-`` and 16 hex digits."""
    body = {k: v for k, v in results.items() if k != "report_id"}
    digest = hashlib.sha256()
    digest.update(json.dumps(body, sort_keys=True, separators=(",", ":")).encode())
    for name in sorted(inputs):
        if inputs[name] and inputs[name] != "-":
            digest.update(f"\n{name}={inputs[name]}".encode())
    return "RPT-" + digest.hexdigest()[:ID_DIGITS]


def stamp_results(path: str | Path, inputs: dict[str, str]) -> str:
    """Add ``report_id`` to the ``results.json`` at ``path`` (rewritten in place) and
    return it."""
    path = Path(path)
    try:
        results = json.loads(path.read_text(encoding="utf-8"))
        rid = report_id(results, inputs)
        results["report_id"] = rid
        path.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    except OSError as err:
        raise InputError(f"cannot rewrite results.json: {err.strerror}", where=str(path)) \
            from err
    return rid


def software_commit() -> str:
    """The git commit (short hash, '+modified' when the tree has changes) of this
    software's checkout, '' when it is not a git checkout or git is missing."""
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=10", "HEAD"],
                              capture_output=True, text=True, timeout=5, check=False)
        if head.returncode != 0:
            return ""
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no", "--", "analysis", "campaign",
                                "drivers"], capture_output=True, text=True, timeout=10,
                               check=False)
    except (OSError, subprocess.SubprocessError):
        return ""
    return head.stdout.strip() + ("+modified" if dirty.stdout.strip() else "")


def software_text() -> str:
    """'stiffness-campaign 0.1.0 (commit abc1234567)' for the footer."""
    import importlib.metadata

    try:
        version = importlib.metadata.version("robot-stiffness-campaign")
    except importlib.metadata.PackageNotFoundError:
        version = "unknown version"
    commit = software_commit()
    return f"robot-stiffness-campaign {version}" + (f" (commit {commit})" if commit else "")


def utc_now_text() -> str:
    """The current time, UTC, to the minute: '2026-12-01 20:15 UTC'."""
    return datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
