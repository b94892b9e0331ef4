"""The ``history`` jobs: record campaigns in the fleet ledger, list them, trend and check
a robot's stiffness over time, verify the recorded files.

One function per command (``add``, ``listing``, ``trend``, ``check``, ``verify``),
shared by the command line and the GUI. Each opens the ledger named by ``db``
(``--db`` or ``STIFFNESS_CAMPAIGN_DB``; :mod:`campaign.ledger.database`), does its
work and closes it. Bad input is one InputError before anything is written.
SQLAlchemy is imported here, inside the functions, never at ``campaign --help``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from analysis.errors import InputError

#: defaults of ``history check``: the change worth an alarm (fraction) and the level
DEFAULT_MIN_CHANGE = 0.05
DEFAULT_ALPHA = 0.05

#: the test named in an alarm
TEST_BOUND = "one-sided bound, Holm over joints"
TEST_EWMA = "EWMA of standardised changes"


def _open(db: str | None, create: bool = False):
    from campaign.ledger.database import open_ledger

    return open_ledger(db, create=create)


def _use(db: str | None, work, create: bool = False):
    """Run ``work(engine)`` on the ledger; a database failure is one InputError."""
    from sqlalchemy.exc import SQLAlchemyError

    from campaign.ledger.database import database_error, ledger_url, shown

    engine = _open(db, create)
    try:
        return work(engine)
    except SQLAlchemyError as err:
        raise database_error(err, shown(ledger_url(db))) from None
    finally:
        engine.dispose()


# ---------------------------------------------------------------- add

@dataclass(frozen=True)
class AddOptions:
    """paths: run directories, analysis directories or results.json files; db: the ledger
    (None: the environment variable); robot_id: the identity when the run gives none (or
    to override it); date: the campaign date when the run has none (ISO 8601);
    supersedes: report_id of the record this campaign corrects."""

    paths: tuple[Path, ...]
    db: str | None = None
    robot_id: str | None = None
    date: str | None = None
    supersedes: str | None = None


@dataclass(frozen=True)
class AddResult:
    """Per path: report_id, robot and whether it was added (False: already recorded)."""

    rows: tuple[dict, ...]

    def to_json(self) -> dict:
        return {"campaigns": list(self.rows)}


def add(o: AddOptions, before_commit=None) -> AddResult:
    """Read every path first (a damaged one stops the command before anything is written),
    then record each in its own transaction."""
    from campaign.ledger import store
    from campaign.ledger.entry import read_entry

    if not o.paths:
        raise InputError("expected at least one run or analysis directory", where="history add")
    entries = [read_entry(Path(p), o.robot_id, o.date, o.supersedes) for p in o.paths]

    def work(engine):
        rows = []
        for entry in entries:
            rec, added = store.add(engine, entry, before_commit)
            rows.append({"report_id": rec.entry.report_id, "robot": rec.entry.robot_id,
                         "date": rec.entry.campaign_date, "added": added})
        return AddResult(tuple(rows))

    return _use(o.db, work, create=True)


def configured_ledger(db: str | None) -> str | None:
    """The ledger ``campaign analyze`` and the GUI record into: ``db``, else the environment
    variable, else None (no ledger: nothing recorded)."""
    import os

    from campaign.ledger.database import ENV

    if db is not None and db.strip():
        return db
    return os.environ.get(ENV, "").strip() or None


def record_analysis(analysis_dir: Path, db: str, robot_id: str | None = None,
                    warn=None) -> dict:
    """Record a just-written analysis in the ledger ``db``: the ``history add`` row, or
    ``{"added": False, "reason": ...}`` (and a ``warn`` line) when the run names no robot."""
    from campaign.ledger.entry import NoRobotIdentity

    try:
        return add(AddOptions((Path(analysis_dir),), db, robot_id)).rows[0]
    except NoRobotIdentity as err:
        reason = f"not recorded in the ledger: {err}"
        if warn is not None:
            warn(f"warning: {reason}")
        return {"added": False, "reason": reason}


def report_history(analysis_dir: Path, run_dir: Path | None, db: str,
                   robot_id: str | None = None):
    """The report's history section (:class:`analysis.report.document.Section`): this
    campaign against the robot's earlier campaigns in the ledger ``db`` (read only)."""
    from analysis.report.document import Paragraph, Section
    from campaign.ledger import store
    from campaign.ledger.entry import NoRobotIdentity, read_entry
    from campaign.ledger.report_history import history_blocks

    title = "History of this robot (fleet ledger)"
    try:
        entry = read_entry(Path(analysis_dir), robot_id, run_dir=run_dir)
    except NoRobotIdentity:
        return Section(title, [Paragraph("The run names no robot serial and no robot id "
                                         "was given: this campaign cannot be placed in the "
                                         "ledger's history.", "note")])

    def earlier(engine):
        return [r for r in store.campaigns(engine, entry.robot_id)
                if r.entry.report_id != entry.report_id]

    try:
        records = _use(db, earlier)
    except InputError as err:
        if "no ledger file here" not in str(err):
            raise
        records = []
    return Section(title, history_blocks(entry, records, DEFAULT_MIN_CHANGE, DEFAULT_ALPHA))


# ---------------------------------------------------------------- list

def _summary(rec) -> dict:
    e = rec.entry
    return {"robot": e.robot_id, "report_id": e.report_id, "date": e.campaign_date,
            "robot_model": e.robot_model, "estimator": e.estimator,
            "joints_identified": list(e.joints), "k_Nm_per_rad": list(e.k),
            "supersedes": e.supersedes, "source_dir": e.source_dir}


@dataclass(frozen=True)
class ListResult:
    """The records, oldest first per robot."""

    campaigns: tuple[dict, ...]

    def to_json(self) -> dict:
        return {"campaigns": list(self.campaigns)}


def listing(db: str | None, robot: str | None = None) -> ListResult:
    """Every record (of one robot)."""
    from campaign.ledger import store

    return _use(db, lambda engine: ListResult(tuple(_summary(r) for r in
                                                   store.campaigns(engine, robot))))


# ---------------------------------------------------------------- trend and check

def _stats_campaign(rec):
    import numpy as np

    from campaign.ledger.drift import Campaign, log_variance

    e = rec.entry
    k = np.array([np.nan if v is None else float(v) for v in e.k])
    return Campaign(e.report_id, e.campaign_date, k, log_variance(k, e.covariance, e.joints),
                    e.estimator, tuple(e.joints), e.model_class, e.accepted_despite_refusal)


@dataclass
class RobotHistory:
    """One robot's records with the statistics' view of them: the reference, and per
    record whether it is compared (reason when not)."""

    robot: str
    records: list
    reference: str | None
    reasons: dict = field(default_factory=dict)  # report_id -> reason left out

    def comparable(self) -> list:
        return [r for r in self.records if r.entry.report_id not in self.reasons]


def robot_history(records: list, reference: str | None = None) -> RobotHistory:
    """Mark superseded and non-comparable records; choose the reference (``reference``, or
    the first record not accepted despite a refusal)."""
    from campaign.ledger.drift import comparable_reason

    robot = records[0].entry.robot_id
    superseded = {r.entry.supersedes: r.entry.report_id for r in records if r.entry.supersedes}
    reasons = {rid: f"superseded by {new}" for rid, new in superseded.items()}
    live = [r for r in records if r.entry.report_id not in reasons]
    if reference is not None:
        chosen = [r for r in records if r.entry.report_id == reference]
        if not chosen:
            raise InputError(f"no record {reference} of robot {robot!r}", where="--reference")
        if reference in reasons:
            raise InputError(f"{reference} is {reasons[reference]}", where="--reference")
        ref = chosen[0]
    else:
        usable = [r for r in live if not r.entry.accepted_despite_refusal]
        ref = usable[0] if usable else None
    if ref is None:
        for r in live:
            reasons[r.entry.report_id] = "no reference: every campaign was accepted " \
                "despite a refusal"
        return RobotHistory(robot, records, None, reasons)
    ref_c = _stats_campaign(ref)
    for r in live:
        if r is ref:
            continue
        why = comparable_reason(_stats_campaign(r), ref_c)
        if why is not None:
            reasons[r.entry.report_id] = why
    return RobotHistory(robot, records, ref.entry.report_id, reasons)


def _percent(v: float) -> float:
    return 100.0 * v


def _trend_row(rec, hist: RobotHistory, ref_rec) -> dict:
    e = rec.entry
    row = {"report_id": e.report_id, "date": e.campaign_date, "k_Nm_per_rad": list(e.k),
           "ci95_Nm_per_rad": [None if c is None else list(c) for c in e.ci95],
           "estimator": e.estimator, "joints_identified": list(e.joints),
           "reference": e.report_id == hist.reference,
           "compared": e.report_id not in hist.reasons,
           "reason": hist.reasons.get(e.report_id), "supersedes": e.supersedes,
           "source_dir": e.source_dir}
    if ref_rec is not None and row["compared"]:
        row["change_percent"] = [None if (v is None or ref_rec.entry.k[j] is None)
                                 else _percent(v / ref_rec.entry.k[j] - 1)
                                 for j, v in enumerate(e.k)]
    return row


@dataclass(frozen=True)
class TrendResult:
    """A robot's campaigns, oldest first (see :func:`trend`)."""

    robot: str
    reference: str | None
    campaigns: tuple[dict, ...]
    plot: str | None = None

    def to_json(self) -> dict:
        out = {"robot": self.robot, "reference": self.reference,
               "campaigns": list(self.campaigns)}
        if self.plot is not None:
            out["plot"] = self.plot
        return out


def _records(engine, robot: str) -> list:
    from campaign.ledger import store

    records = store.campaigns(engine, robot)
    if not records:
        raise InputError(f"no campaign of robot {robot!r} in the ledger", where="--robot")
    return records


def trend(db: str | None, robot: str, reference: str | None = None,
          plot: Path | None = None) -> TrendResult:
    """k per joint over time with the recorded 95 % intervals, the change against the
    reference; ``plot``: a PNG/PDF/SVG of the six joints."""
    if plot is not None:
        from analysis.identification.compare.plot import check_plot_path

        check_plot_path(Path(plot))
    records = _use(db, lambda engine: _records(engine, robot))
    hist = robot_history(records, reference)
    ref_rec = next((r for r in records if r.entry.report_id == hist.reference), None)
    rows = tuple(_trend_row(r, hist, ref_rec) for r in records)
    result = TrendResult(robot, hist.reference, rows)
    if plot is not None:
        from campaign.ledger.plot import plot_trend

        plot_trend(result.to_json(), Path(plot))
        result = TrendResult(robot, hist.reference, rows, str(plot))
    return result


@dataclass(frozen=True)
class CheckResult:
    """The alarms, and per robot the tests run and the campaigns left out."""

    alarms: tuple[dict, ...]
    robots: tuple[dict, ...]
    min_change: float
    alpha: float

    @property
    def alarmed(self) -> bool:
        return bool(self.alarms)

    def to_json(self) -> dict:
        return {"alarms": list(self.alarms), "robots": list(self.robots),
                "min_change_percent": _percent(self.min_change), "alpha": self.alpha}


def check_robot(records: list, min_change: float, alpha: float,
                reference: str | None = None) -> tuple[list[dict], dict]:
    """(alarms, the robot's summary) of one robot's records: the latest comparable
    campaign against the reference (one-sided bounds, Holm), and the EWMA chart per joint."""
    from campaign.ledger.drift import ewma_chart, one_sided_tests

    hist = robot_history(records, reference)
    comp = hist.comparable()
    summary = {"robot": hist.robot, "reference": hist.reference,
               "excluded": [{"report_id": rid, "reason": why}
                            for rid, why in hist.reasons.items()],
               "latest": None, "tests": [], "ewma": []}
    after = [r for r in comp if r.entry.report_id != hist.reference]
    if hist.reference is None or not after:
        summary["status"] = "reference only" if hist.reference else "no reference"
        return [], summary
    ref = _stats_campaign(next(r for r in records if r.entry.report_id == hist.reference))
    series = [_stats_campaign(r) for r in after]
    latest = series[-1]
    summary["latest"] = latest.report_id
    alarms = []
    for t in one_sided_tests(latest, ref, min_change, alpha):
        summary["tests"].append({"joint": t.joint, "change_percent": _percent(t.change),
                                 "upper_bound_percent": _percent(t.bound),
                                 "interval": [_percent(t.interval[0]),
                                              _percent(t.interval[1])],
                                 "z": t.z, "p": t.p, "p_holm": t.p_holm, "alarm": t.alarm})
        if t.alarm:
            alarms.append({"robot": hist.robot, "joint": t.joint,
                           "change_percent": _percent(t.change),
                           "interval": [_percent(t.interval[0]), _percent(t.interval[1])],
                           "campaigns": [ref.report_id, latest.report_id],
                           "test": TEST_BOUND})
    tested = {a["joint"] for a in alarms}
    for j in latest.joints:
        chart = ewma_chart(series, ref, j, min_change)
        summary["ewma"].append(chart)
        if chart["alarm"] and j not in tested:
            change = math.expm1(math.log(latest.k[j - 1] / ref.k[j - 1]))
            alarms.append({"robot": hist.robot, "joint": j, "change_percent": _percent(change),
                           "interval": None,
                           "campaigns": [ref.report_id] + [c.report_id for c in series],
                           "test": TEST_EWMA})
    summary["status"] = "alarm" if alarms else "ok"
    return alarms, summary


def _check_numbers(min_change: float, alpha: float) -> None:
    if not (math.isfinite(min_change) and 0 <= min_change < 1):
        raise InputError("expected a change in percent, 0 <= PCT < 100", where="--min-change")
    if not (math.isfinite(alpha) and 0 < alpha < 0.5):
        raise InputError("expected a level 0 < alpha < 0.5", where="--alpha")


def check(db: str | None, robot: str | None = None, min_change: float = DEFAULT_MIN_CHANGE,
          alpha: float = DEFAULT_ALPHA, reference: str | None = None) -> CheckResult:
    """The drift test of one robot, or of every robot in the ledger."""
    from campaign.ledger import store

    _check_numbers(min_change, alpha)
    if reference is not None and robot is None:
        raise InputError("a reference campaign belongs to one robot: give --robot too",
                         where="--reference")

    def load(engine):
        return _records(engine, robot) if robot is not None else store.campaigns(engine)

    records = _use(db, load)
    by_robot: dict[str, list] = {}
    for r in records:
        by_robot.setdefault(r.entry.robot_id, []).append(r)
    alarms, robots = [], []
    for rid in sorted(by_robot):
        a, s = check_robot(by_robot[rid], min_change, alpha, reference)
        alarms += a
        robots.append(s)
    return CheckResult(tuple(alarms), tuple(robots), min_change, alpha)


# ---------------------------------------------------------------- verify

@dataclass(frozen=True)
class VerifyResult:
    """Files checked, mismatches and files no longer there."""

    checked: int
    mismatches: tuple[dict, ...]
    missing: tuple[dict, ...]

    def to_json(self) -> dict:
        return {"checked": self.checked, "mismatches": list(self.mismatches),
                "missing": list(self.missing)}


def recorded_files(entry) -> dict:
    """name -> (path, recorded SHA-256) of a record's files."""
    import json

    folder = Path(entry.source_dir)
    run = folder if (folder / "metadata.json").is_file() else folder.parent
    plan = "plan.csv"
    try:
        meta = json.loads((run / "metadata.json").read_text(encoding="utf-8"))
        plan = str(meta.get("plan_file") or plan)
    except (OSError, ValueError, AttributeError):
        pass
    return {"results.json": (folder / "results.json", entry.results_sha256),
            "tests.csv": (run / "tests.csv", entry.tests_sha256),
            "plan": (run / plan, entry.plan_sha256),
            "protocol": (run / "protocol.toml", entry.protocol_sha256)}


def verify(db: str | None, robot: str | None = None) -> VerifyResult:
    """Re-hash every recorded file that still exists; report each mismatch."""
    from campaign.ledger import store
    from campaign.ledger.entry import sha256

    records = _use(db, lambda engine: store.campaigns(engine, robot))
    checked, bad, missing = 0, [], []
    for rec in records:
        for name, (path, digest) in recorded_files(rec.entry).items():
            if digest is None:
                continue
            where = {"robot": rec.entry.robot_id, "report_id": rec.entry.report_id,
                     "file": name, "path": str(path)}
            if not path.is_file():
                missing.append(where)
                continue
            checked += 1
            now = sha256(path)
            if now != digest:
                bad.append({**where, "recorded_sha256": digest, "sha256": now})
    return VerifyResult(checked, tuple(bad), tuple(missing))


# ---------------------------------------------------------------- the GUI's Fleet view

@dataclass(frozen=True)
class FleetResult:
    """Per robot: its campaigns, the last one and the drift test's status (Fleet view)."""

    robots: tuple[dict, ...]
    min_change: float
    alpha: float

    def to_json(self) -> dict:
        return {"robots": list(self.robots), "min_change_percent": _percent(self.min_change),
                "alpha": self.alpha}


def fleet(db: str | None, min_change: float = DEFAULT_MIN_CHANGE,
          alpha: float = DEFAULT_ALPHA) -> FleetResult:
    """Every robot with its last campaign and status (ok, alarm with its joints, or
    reference only)."""
    from campaign.ledger import store

    _check_numbers(min_change, alpha)
    records = _use(db, store.campaigns)
    by_robot: dict[str, list] = {}
    for r in records:
        by_robot.setdefault(r.entry.robot_id, []).append(r)
    rows = []
    for rid in sorted(by_robot):
        recs = by_robot[rid]
        alarms, summary = check_robot(recs, min_change, alpha)
        last = recs[-1].entry
        rows.append({"robot": rid, "robot_model": last.robot_model, "campaigns": len(recs),
                     "last_date": last.campaign_date, "last_report_id": last.report_id,
                     "status": summary["status"],
                     "alarm_joints": sorted({a["joint"] for a in alarms})})
    return FleetResult(tuple(rows), min_change, alpha)


def robot_view(db: str | None, robot: str, min_change: float = DEFAULT_MIN_CHANGE,
               alpha: float = DEFAULT_ALPHA) -> dict:
    """One robot for the Fleet view: its trend (:func:`trend`), the drift test's summary
    and alarms (:func:`check_robot`)."""
    _check_numbers(min_change, alpha)
    records = _use(db, lambda engine: _records(engine, robot))
    hist = robot_history(records)
    ref_rec = next((r for r in records if r.entry.report_id == hist.reference), None)
    alarms, summary = check_robot(records, min_change, alpha)
    return {"robot": robot, "reference": hist.reference,
            "campaigns": [_trend_row(r, hist, ref_rec) for r in records],
            "alarms": alarms, "check": summary,
            "min_change_percent": _percent(min_change), "alpha": alpha}
