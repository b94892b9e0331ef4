"""Add and read ledger records (SQLAlchemy 2 sessions on an engine of :mod:`.database`).

A record is written in one transaction, whole or not at all. ``add`` is idempotent
by report_id under concurrency: the unique constraint decides, and the loser of a
race reads the winner's record instead of inserting (no check-then-insert).
Records are returned as :class:`StoredCampaign`, a frozen record with the JSON
columns decoded.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import UTC, datetime

from analysis.errors import InputError
from campaign.ledger.entry import LedgerEntry


@dataclass(frozen=True)
class StoredCampaign:
    """One committed record: the entry's fields, its row id and when it was recorded."""

    id: int
    recorded_utc: str
    entry: LedgerEntry


def _row(entry: LedgerEntry):
    from campaign.ledger.schema import CampaignRecord

    return CampaignRecord(
        report_id=entry.report_id, robot_id=entry.robot_id, robot_model=entry.robot_model,
        campaign_date=entry.campaign_date,
        recorded_utc=datetime.now(UTC).isoformat(timespec="seconds"),
        estimator=entry.estimator, model_class=entry.model_class,
        joints_identified=json.dumps(list(entry.joints)),
        k_Nm_per_rad=json.dumps(list(entry.k)),
        ci95_Nm_per_rad=json.dumps([None if c is None else list(c) for c in entry.ci95]),
        covariance_of_compliance=json.dumps([list(r) for r in entry.covariance]),
        chi2_reduced=entry.chi2_reduced, dof=entry.dof,
        condition_number=entry.condition_number,
        accepted_despite_refusal=entry.accepted_despite_refusal,
        tool=json.dumps(entry.tool), payload_kg=entry.payload_kg,
        instruments=json.dumps(list(entry.instruments)),
        temperatures=None if entry.temperatures is None else json.dumps(entry.temperatures),
        results_sha256=entry.results_sha256, tests_sha256=entry.tests_sha256,
        plan_sha256=entry.plan_sha256, protocol_sha256=entry.protocol_sha256,
        source_dir=entry.source_dir, software_version=entry.software_version,
        supersedes=entry.supersedes)


def stored(row) -> StoredCampaign:
    """A row of the campaigns table as a frozen record (JSON columns decoded)."""
    ci = json.loads(row.ci95_Nm_per_rad)
    entry = LedgerEntry(
        report_id=row.report_id, robot_id=row.robot_id, robot_model=row.robot_model,
        campaign_date=row.campaign_date, estimator=row.estimator, model_class=row.model_class,
        joints=tuple(json.loads(row.joints_identified)),
        k=tuple(json.loads(row.k_Nm_per_rad)),
        ci95=tuple(None if c is None else tuple(c) for c in ci),
        covariance=tuple(tuple(r) for r in json.loads(row.covariance_of_compliance)),
        chi2_reduced=row.chi2_reduced, dof=row.dof, condition_number=row.condition_number,
        accepted_despite_refusal=bool(row.accepted_despite_refusal),
        tool=json.loads(row.tool), payload_kg=row.payload_kg,
        instruments=tuple(json.loads(row.instruments)),
        temperatures=None if row.temperatures is None else json.loads(row.temperatures),
        results_sha256=row.results_sha256, tests_sha256=row.tests_sha256,
        plan_sha256=row.plan_sha256, protocol_sha256=row.protocol_sha256,
        source_dir=row.source_dir, software_version=row.software_version,
        supersedes=row.supersedes)
    return StoredCampaign(row.id, row.recorded_utc, entry)


def _same_content(a: LedgerEntry, b: LedgerEntry) -> bool:
    """The same campaign: every field but where its files were found."""
    skip = {"source_dir"}
    da, db = asdict(a), asdict(b)
    return all(json.dumps(da[k], default=str) == json.dumps(db[k], default=str)
               for k in da if k not in skip)


def _by_report(session, report_id: str):
    from sqlalchemy import select

    from campaign.ledger.schema import CampaignRecord

    return session.scalars(select(CampaignRecord)
                           .where(CampaignRecord.report_id == report_id)).first()


def _check_robot(session, entry: LedgerEntry) -> None:
    """Refuse a campaign of another robot model under an identity already recorded, and a
    correction of a report that is not there or belongs to another robot."""
    from sqlalchemy import select

    from campaign.ledger.schema import CampaignRecord

    models = set(session.scalars(select(CampaignRecord.robot_model).distinct()
                                 .where(CampaignRecord.robot_id == entry.robot_id)))
    if models and entry.robot_model not in models:
        raise InputError(f"robot {entry.robot_id!r} is recorded as {sorted(models)[0]!r}, "
                         f"this campaign is of {entry.robot_model!r}: another robot under "
                         "the same identity; give its own --robot-id", where=entry.source_dir)
    if entry.supersedes is not None:
        old = _by_report(session, entry.supersedes)
        if old is None or old.robot_id != entry.robot_id:
            raise InputError(f"no record {entry.supersedes} of robot {entry.robot_id!r} to "
                             "supersede", where="--supersedes")


def add(engine, entry: LedgerEntry,
        before_commit: Callable[[], None] | None = None) -> tuple[StoredCampaign, bool]:
    """Record ``entry``: (the stored record, True) when added, (the existing one, False)
    when its report_id was already there with the same content. A report_id recorded
    with other content is refused. ``before_commit``: called with the row flushed but
    not committed (the kill -9 test's window)."""
    from sqlalchemy.exc import IntegrityError
    from sqlalchemy.orm import Session

    from campaign.ledger.database import writer

    try:
        with Session(writer(engine)) as session, session.begin():
            existing = _by_report(session, entry.report_id)
            if existing is None:
                _check_robot(session, entry)
                row = _row(entry)
                session.add(row)
                session.flush()
                if before_commit is not None:
                    before_commit()
                result = stored(row)
            else:
                result = stored(existing)
        if existing is None:
            return result, True
    except IntegrityError:  # another writer recorded this report_id first
        with Session(engine) as session:
            existing = _by_report(session, entry.report_id)
            if existing is None:
                raise
            result = stored(existing)
    if not _same_content(result.entry, entry):
        raise InputError(f"report {entry.report_id} is already recorded with other content "
                         f"(robot {result.entry.robot_id!r}, {result.entry.campaign_date}): "
                         "a record is never changed; a correction is a new analysis "
                         "recorded with --supersedes", where=entry.source_dir)
    return result, False


def campaigns(engine, robot: str | None = None) -> list[StoredCampaign]:
    """The records (of one robot, or all), oldest campaign first."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from campaign.ledger.schema import CampaignRecord

    query = select(CampaignRecord)
    if robot is not None:
        query = query.where(CampaignRecord.robot_id == robot)
    query = query.order_by(CampaignRecord.robot_id, CampaignRecord.campaign_date,
                           CampaignRecord.id)
    with Session(engine) as session:
        return [stored(row) for row in session.scalars(query)]


def robots(engine) -> list[str]:
    """Every robot identity in the ledger, sorted."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from campaign.ledger.schema import CampaignRecord

    with Session(engine) as session:
        return list(session.scalars(select(CampaignRecord.robot_id).distinct()
                                    .order_by(CampaignRecord.robot_id)))
