"""What the report's traceability needs from a run directory (campaign side).

:func:`run_trace` reads the campaign name, whether the run came from the
simulated lab, which clock its readings' time stamps follow, the SHA-256 of
``tests.csv`` and ``plan.csv``, the instruments' model, serial and calibration
(the protocol's documented keys, else what the device reported at connection)
and each row's repeatability, as keyword arguments of
:class:`analysis.report.summary.CampaignInfo`.
"""

from __future__ import annotations

import numpy as np

from analysis.report.traceability import file_sha256


def _hash(path) -> str:
    try:
        return file_sha256(path) if path.is_file() else ""
    except OSError:
        return ""


def instrument_records(meta: dict, protocol) -> list[dict]:
    """One dict per instrument role (protocol's first, then any the metadata adds)."""
    recorded = meta.get("instruments") or {}
    roles = list(protocol.instruments) if protocol is not None else []
    roles += [r for r in recorded if r not in roles]
    out = []
    for role in roles:
        spec = protocol.instruments.get(role) if protocol is not None else None
        device = recorded.get(role) if isinstance(recorded.get(role), dict) else {}
        rec = {"role": role, "driver": (spec.driver if spec else device.get("driver")),
               "address": (spec.address if spec else device.get("address"))}
        for key in ("model", "serial", "calibration_date", "calibration_due", "certificate"):
            value = getattr(spec, key, None) if spec is not None else None
            rec[key] = str(value) if value is not None else device.get(key)
        reported = device.get("serial")
        if reported and rec["serial"] and str(reported) != str(rec["serial"]):
            rec["serial"] = f"{rec['serial']} (device reports {reported})"
        out.append(rec)
    return out


def run_trace(run, protocol) -> dict:
    """CampaignInfo keyword arguments of a run (:class:`campaign.run_format.reader.Run`)."""
    meta = run.metadata
    rep = {}
    if "repeatability_mm" in run.tests:
        values = run.tests["repeatability_mm"].to_numpy()
        for line, v in zip(run.tests["line"].to_numpy(), values, strict=True):
            try:
                rep[int(line)] = float(v)
            except (TypeError, ValueError):
                rep[int(line)] = float("nan")
    stamps = meta.get("time_stamps")
    campaign = meta.get("campaign") or (protocol.campaign.name if protocol is not None else "")
    return {
        "campaign": str(campaign or ""),
        "simulated": bool(meta.get("fake")) or bool(meta.get("fake_lab")),
        "time_stamps": str(stamps.get("text") or "") if isinstance(stamps, dict) else "",
        "tests_sha256": _hash(run.path / "tests.csv"),
        "plan_sha256": _hash(run.path / str(meta.get("plan_file") or "plan.csv")),
        "instrument_records": instrument_records(meta, protocol),
        "repeatability_mm": {k: v for k, v in rep.items() if np.isfinite(v)},
    }
