"""The campaign summary and data-quality part of the report.

:class:`CampaignInfo` is filled by the caller (from a run directory or from
an imported CSV file) and turned into tables here.
"""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass, field

from analysis.report.document import Paragraph, Table
from analysis.report.formatting import fixed, utc_text

VERSIONED = ("robot-stiffness-campaign", "numpy", "scipy", "pandas", "pin", "matplotlib", "fpdf2")


@dataclass
class CampaignInfo:
    """What the summary says about the campaign.

    Attributes
    ----------
    source : ``"run"`` or ``"csv"``; ``location`` the run directory or CSV file.
    robot, tool : robot name (and model file); tool description (text).
    instruments : role -> description (driver, address, serial...).
    started_utc, ended_utc, operator, status, reason : from the run metadata.
    protocol_file, protocol_sha256 : the protocol and its SHA-256 (hex).
    measurements_sha256 : SHA-256 of an imported measurements file ('' for a run).
    wrenches : the distinct wrenches of an imported file, (text, number of tests).
    software : package -> version recorded at acquisition.
    n_planned, n_rows, n_ok, n_failed : test rows planned, present, ok, failed.
    flagged : rows of the data-quality table (dicts: test_id, repeat, pose, status,
        flags, repeatability_mm, drift_mm, wrench_error_N, tracker_sigma_mm, line).
    flag_counts : flag -> number of rows.
    notes : remarks from reading the input (hash mismatch, dropped line, ...).
    campaign : the protocol's ``[campaign] name`` ('' unknown).
    simulated : the run came from the simulated lab (metadata ``fake``/``fake_lab``).
    time_stamps : which clock the readings' ``t_utc`` follows (metadata ``time_stamps``
        ``text``: the UTC wall clock, or the simulated lab's clock); '' when not recorded.
    tests_sha256, plan_sha256 : SHA-256 of the run's tests.csv and plan.csv ('' unknown).
    instrument_records : one dict per instrument: role, model, serial, calibration_date,
        calibration_due, certificate, driver, address (protocol keys, device reports).
    repeatability_mm : tests.csv line -> repeatability (mm) of that row.
    report_id : the report ID stamped into results.json ('' before).
    """

    source: str
    location: str
    robot: str
    tool: str = "-"
    instruments: dict[str, str] = field(default_factory=dict)
    started_utc: str = "-"
    ended_utc: str = "-"
    operator: str = "-"
    status: str = "-"
    reason: str = ""
    protocol_file: str = "-"
    protocol_sha256: str = "-"
    measurements_sha256: str = ""
    wrenches: list[tuple[str, int]] = field(default_factory=list)
    software: dict[str, str] = field(default_factory=dict)
    n_planned: int | None = None
    n_rows: int = 0
    n_ok: int = 0
    n_failed: int = 0
    flagged: list[dict] = field(default_factory=list)
    flag_counts: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    campaign: str = ""
    simulated: bool = False
    time_stamps: str = ""
    tests_sha256: str = ""
    plan_sha256: str = ""
    instrument_records: list[dict] = field(default_factory=list)
    repeatability_mm: dict[int, float] = field(default_factory=dict)
    report_id: str = ""

    def input_hashes(self) -> dict[str, str]:
        """Name -> SHA-256 of each input file (for the report ID)."""
        return {"tests": self.tests_sha256 or self.measurements_sha256,
                "plan": self.plan_sha256, "protocol": self.protocol_sha256}

    @property
    def partial(self) -> bool:
        """A run that did not finish (aborted, failed or still running)."""
        return self.source == "run" and self.status != "complete"


def analysis_versions() -> dict[str, str]:
    """Versions of the packages doing this analysis."""
    out = {}
    for name in VERSIONED:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return out


def partial_text(info: CampaignInfo) -> str:
    """One sentence on an unfinished run ('' for a complete run or CSV import)."""
    if not info.partial:
        return ""
    planned = f" of {info.n_planned} planned" if info.n_planned else ""
    why = f": {info.reason}" if info.reason else ""
    return (f"PARTIAL RUN (status {info.status}{why}). Analysed from the {info.n_ok} test "
            f"row(s) that finished ok{planned}; the results carry less information than "
            "the plan intended.")


def summary_table(info: CampaignInfo) -> Table:
    """Key facts of the campaign, one per row."""
    rows = [
        *([["campaign", info.campaign]] if info.campaign else []),
        ["source", f"{info.source}: {info.location}"],
        ["robot", info.robot],
        ["tool", info.tool],
        ["status", info.status + (f" ({info.reason})" if info.reason else "")],
        ["started / ended", f"{utc_text(info.started_utc)} / {utc_text(info.ended_utc)}"],
        ["operator", info.operator],
        *([["protocol", info.protocol_file], ["protocol SHA-256", info.protocol_sha256]]
          if info.source == "run" or info.protocol_sha256 not in ("", "-") else
          [["protocol", "none (imported measurements)"]]),
        *([["measurements SHA-256", info.measurements_sha256]]
          if info.measurements_sha256 else []),
        *([["tests.csv SHA-256", info.tests_sha256]] if info.tests_sha256 else []),
        *([["plan SHA-256", info.plan_sha256]] if info.plan_sha256 else []),
        *[[f"load case {i + 1}", f"{text} ({n} test(s))"]
          for i, (text, n) in enumerate(info.wrenches)],
        ["test rows", f"{info.n_rows} recorded ({info.n_ok} ok, {info.n_failed} failed)"
                      + (f", {info.n_planned} planned" if info.n_planned else "")],
    ]
    for role, text in info.instruments.items():
        rows.append([f"instrument: {role}", text])
    if info.simulated:  # said only when true: a real run's report never says "simulated"
        rows.append(["data", "SIMULATED DATA from the simulated lab (metadata fake), not a "
                     "measurement of a real robot"])
    if info.time_stamps:
        rows.append(["time stamps", info.time_stamps])
    if info.software:
        rows.append(["software (acquisition)",
                     ", ".join(f"{k} {v}" for k, v in info.software.items())])
    rows.append(["software (analysis)",
                 ", ".join(f"{k} {v}" for k, v in analysis_versions().items())])
    return Table("Campaign", ["item", "value"], rows, widths=[1, 3.2])


INSTRUMENT_KEYS = ("model", "serial", "calibration_date", "calibration_due", "certificate")


def instrument_table(info: CampaignInfo) -> Table | None:
    """Instruments with model, serial and calibration (None when nothing is known)."""
    if not info.instrument_records:
        return None
    rows = [[r.get("role", "-"), *[str(r.get(k) or "-") for k in INSTRUMENT_KEYS]]
            for r in info.instrument_records]
    return Table("Instruments and calibration",
                 ["role", "model", "serial", "calibrated on", "calibration due",
                  "certificate"], rows,
                 caption="From the protocol's [instruments.<role>] keys model, serial, "
                 "calibration_date, calibration_due and certificate; a serial the device "
                 "reported at connection is shown when the protocol gives none. '-': not "
                 "given.", widths=[1, 1.4, 1.1, 1.1, 1.1, 1.4])


def approval_table() -> Table:
    """Blank fields for the signatures of the analyst, the checker and the approver."""
    rows = [[role, "", "", ""] for role in ("analysed by", "checked by", "approved by")]
    return Table("Approval", ["role", "name", "signature", "date"], rows,
                 widths=[1, 1.6, 1.6, 0.9], tall=True)


def quality_blocks(info: CampaignInfo) -> list:
    """Flag counts, the table of flagged or failed rows, and notes."""
    blocks: list = []
    if info.source != "run":
        blocks.append(Paragraph("Imported measurements: no data-quality flags are recorded "
                                "with a CSV file.", "note"))
    elif not info.flagged:
        blocks.append(Paragraph("No test row carries a data-quality flag and none failed."))
    else:
        counts = ", ".join(f"{flag}: {n}" for flag, n in info.flag_counts.items())
        failed = f"{info.n_failed} failed test row(s) (not used for identification)"
        blocks.append(Paragraph(f"Data-quality flags: {counts or 'none'}; {failed}.",
                                "warning"))
        rows, marked = [], []
        for r in info.flagged:
            rows.append([str(r["test_id"]), str(r["repeat"]), str(r["pose"]), r["status"],
                         ", ".join(r["flags"]) or "-", fixed(r["repeatability_mm"], 3),
                         fixed(r["drift_mm"], 3), fixed(r["wrench_error_N"], 2),
                         fixed(r["tracker_sigma_mm"], 3), str(r["line"])])
            marked.append(r["status"] == "failed")
        blocks.append(Table(
            "Flagged and failed test rows",
            ["test", "repeat", "pose", "status", "flags", "repeatability (mm)",
             "drift (mm)", "wrench error (N)", "tracker sigma (mm)", "tests.csv line"],
            rows, marked, caption="Highlighted rows failed and were left out of the fit.",
            widths=[0.6, 0.7, 0.6, 0.8, 1.9, 1.2, 0.8, 1.1, 1.1, 0.9],
        ))
    for note in info.notes:
        blocks.append(Paragraph(note, "note"))
    return blocks
