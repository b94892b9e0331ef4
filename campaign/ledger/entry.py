"""One campaign as the ledger records it, read from a run or an analysis directory.

:func:`read_entry` finds results.json (a run directory, its ``analysis``
directory, or the file), checks every field the ledger stores through the same
reader as ``campaign compare`` (:func:`analysis.identification.compare.load.load_campaign`),
and gathers the run's metadata beside it: date, tool, payload, instruments with
serials and calibration dates, temperatures when recorded, and the SHA-256 of
results.json, tests.csv, plan.csv and protocol.toml. Nothing is written.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from analysis.errors import InputError

#: instrument keys the ledger keeps (the protocol's documented traceability keys)
INSTRUMENT_KEYS = ("model", "serial", "calibration_date", "calibration_due", "certificate")


class NoRobotIdentity(InputError):
    """The campaign names no robot serial and no ``--robot-id`` was given."""


@dataclass(frozen=True)
class LedgerEntry:
    """One campaign record before it is stored (SI units; JSON-ready tuples).

    k: six joint stiffnesses (N m/rad, None for a joint not identified); ci95: six
    (lo, hi) intervals (N m/rad) as the analysis reported them; covariance: the
    compliance covariance ((rad/(N m))^2) over ``joints`` (1-based, in that order).
    Hashes are SHA-256 hex (None: the file was not there).
    """

    report_id: str
    robot_id: str
    robot_model: str
    campaign_date: str
    estimator: str
    model_class: str
    joints: tuple[int, ...]
    k: tuple
    ci95: tuple
    covariance: tuple
    chi2_reduced: float | None
    dof: int | None
    condition_number: float | None
    accepted_despite_refusal: bool
    tool: dict
    payload_kg: float | None
    instruments: tuple
    temperatures: dict | None
    results_sha256: str
    tests_sha256: str | None
    plan_sha256: str | None
    protocol_sha256: str | None
    source_dir: str
    software_version: str | None
    supersedes: str | None = None


def sha256(path: Path) -> str | None:
    """SHA-256 (hex) of a file, None when it is not there."""
    if not path.is_file():
        return None
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def locate(path: Path) -> tuple[Path, Path | None]:
    """(results.json, run directory or None) of a run dir, analysis dir or results file."""
    path = Path(path)
    if path.is_file():
        results = path
    elif (path / "results.json").is_file():
        results = path / "results.json"
    elif (path / "analysis" / "results.json").is_file():
        results = path / "analysis" / "results.json"
    else:
        raise InputError("no results.json here (expected a run directory, its analysis "
                         "directory or a results.json file)", where=str(path))
    for cand in (results.parent, results.parent.parent):
        if (cand / "metadata.json").is_file():
            return results, cand
    return results, None


def _json_file(path: Path) -> dict:
    from analysis.identification.compare.load import read_text_utf8

    try:
        doc = json.loads(read_text_utf8(path))
    except json.JSONDecodeError as err:
        raise InputError(f"not JSON: {err}", where=str(path)) from None
    if not isinstance(doc, dict):
        raise InputError("expected a JSON object", where=str(path))
    return doc


def _protocol_instruments(run: Path | None) -> dict:
    """[instruments.<role>] tables of the run's protocol.toml (empty when absent)."""
    if run is None or not (run / "protocol.toml").is_file():
        return {}
    try:
        doc = tomllib.loads((run / "protocol.toml").read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise InputError(f"not a TOML file: {err}", where=str(run / "protocol.toml")) from None
    tables = doc.get("instruments")
    return tables if isinstance(tables, dict) else {}


def instrument_records(meta: dict, protocol: dict) -> list[dict]:
    """Per instrument role: model, serial and calibration, the protocol's keys first,
    else what the device reported at connection (as the report's traceability table)."""
    recorded = meta.get("instruments") if isinstance(meta.get("instruments"), dict) else {}
    roles = list(protocol) + [r for r in recorded if r not in protocol]
    out = []
    for role in roles:
        spec = protocol.get(role) if isinstance(protocol.get(role), dict) else {}
        device = recorded.get(role) if isinstance(recorded.get(role), dict) else {}
        rec = {"role": str(role)}
        for key in INSTRUMENT_KEYS:
            value = spec.get(key, device.get(key))
            rec[key] = None if value is None else str(value)
        out.append(rec)
    return out


def robot_serial(instruments: list[dict]) -> str | None:
    """The robot's serial as the report shows it (the protocol's, else the device's)."""
    for rec in instruments:
        if rec["role"] == "robot" and rec.get("serial"):
            return rec["serial"]
    return None


def _model_class(results: Path, robot: str) -> str:
    """The robot model and the SHA-256 (16 hex) of model.toml's geometry without stiffness:
    campaigns of another kinematic model are not comparable."""
    from analysis.identification.compare.comparison import _geometry

    model = results.parent / "model.toml"
    if not model.is_file():
        return robot
    try:
        doc = tomllib.loads(model.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise InputError(f"not a TOML file: {err}", where=str(model)) from None
    text = json.dumps(_geometry(doc), sort_keys=True, default=str)
    return f"{robot}; geometry {hashlib.sha256(text.encode()).hexdigest()[:16]}"


def _date(meta: dict, date: str | None, where: str) -> str:
    text = date if date is not None else meta.get("started_utc")
    if not isinstance(text, str) or not text:
        raise InputError("no campaign date: the run's metadata.json has no started_utc; "
                         "give --date YYYY-MM-DD[THH:MM:SS]", where=where)
    try:
        when = datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise InputError(f"{text!r} is not an ISO 8601 date", where="--date"
                         if date is not None else where) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    return when.astimezone(UTC).isoformat(timespec="seconds")


def _optional(doc: dict, key: str, kind):
    value = doc.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return kind(value)


def read_entry(path: Path, robot_id: str | None = None, date: str | None = None,
               supersedes: str | None = None, run_dir: Path | None = None) -> LedgerEntry:
    """The ledger entry of one campaign; refuses damaged files and a campaign without a
    robot identity (no serial in the protocol or from the controller, no ``robot_id``).
    ``run_dir``: the run directory when it is not the analysis directory's parent."""
    from analysis.identification.compare.load import load_campaign

    results, run = locate(Path(path))
    if run_dir is not None and (Path(run_dir) / "metadata.json").is_file():
        run = Path(run_dir)
    campaign = load_campaign(results)  # every stored number checked here
    doc = _json_file(results)
    report_id = doc.get("report_id")
    if not isinstance(report_id, str) or not report_id:
        raise InputError("report_id: expected the analysis' report id (text)", where=str(results))
    meta = _json_file(run / "metadata.json") if run is not None else {}
    instruments = instrument_records(meta, _protocol_instruments(run))
    rid = robot_id.strip() if robot_id is not None else robot_serial(instruments)
    if not rid:
        raise NoRobotIdentity("no robot identity: the protocol's [instruments.robot] has no "
                         "serial and the controller reported none; give --robot-id ID",
                         where=str(path))
    joints = tuple(j + 1 for j in campaign.joints)
    cov = tuple(tuple(float(campaign.cov_x[i, j]) for j in campaign.joints)
                for i in campaign.joints)
    ci = doc.get("ci95_Nm_per_rad")
    ci95 = tuple(tuple(float(v) if isinstance(v, int | float) else None for v in pair)
                 if isinstance(pair, list) and len(pair) == 2 and j + 1 in joints else None
                 for j, pair in enumerate(ci if isinstance(ci, list) and len(ci) == 6
                                          else [None] * 6))
    tool = meta.get("tool") if isinstance(meta.get("tool"), dict) else {}
    software = meta.get("software") if isinstance(meta.get("software"), dict) else {}
    temps = meta.get("temperatures")
    return LedgerEntry(
        report_id=report_id, robot_id=rid, robot_model=campaign.robot,
        campaign_date=_date(meta, date, str(run or results)),
        estimator=campaign.method or "unknown", model_class=_model_class(results, campaign.robot),
        joints=joints,
        k=tuple(float(campaign.k[j]) if j + 1 in joints else None for j in range(6)),
        ci95=ci95, covariance=cov,
        chi2_reduced=_optional(doc, "chi2_reduced", float), dof=_optional(doc, "dof", int),
        condition_number=_optional(doc, "condition_number", float),
        accepted_despite_refusal=campaign.accepted,
        tool={k: v for k, v in tool.items() if k in ("xyz_mm", "rpy_deg")},
        payload_kg=_optional(tool, "mass_kg", float), instruments=tuple(instruments),
        temperatures=temps if isinstance(temps, dict) else None,
        results_sha256=sha256(results),
        tests_sha256=sha256(run / "tests.csv") if run is not None else None,
        plan_sha256=sha256(run / str(meta.get("plan_file") or "plan.csv"))
        if run is not None else None,
        protocol_sha256=sha256(run / "protocol.toml") if run is not None else None,
        source_dir=str(results.parent.resolve()),
        software_version=str(software["robot-stiffness-campaign"])
        if software.get("robot-stiffness-campaign") else None,
        supersedes=supersedes)
