"""The ledger's table, one row per campaign record (SQLAlchemy 2 typed ORM).

A row is never updated: a correction is a new row whose ``supersedes`` names the
report_id it replaces. Vectors and matrices are JSON text (SI units): the six
joint stiffnesses (N m/rad, null for a joint not identified), their 95 %
intervals as the analysis reported them, and the full covariance of the
compliance x = 1/k ((rad/(N m))^2) over the identified joints, in the order of
``joints_identified``. The schema's history is in :mod:`campaign.ledger.migrations`
(revision 0002 added temperatures and software_version; this module is the head).
"""

from __future__ import annotations

from sqlalchemy import Boolean, Float, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column


class Base(DeclarativeBase):
    """The ledger's declarative base (its metadata is the head schema)."""


class CampaignRecord(Base):
    """One recorded campaign of one robot (immutable once committed)."""

    __tablename__ = "campaigns"
    __table_args__ = (UniqueConstraint("report_id", name="uq_campaigns_report_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    #: the analysis' report id (results.json ``report_id``): one record per report
    report_id: Mapped[str] = mapped_column(String(64))
    #: the robot's identity: its serial as the report shows it, or --robot-id
    robot_id: Mapped[str] = mapped_column(String(200), index=True)
    #: the robot model's name (results.json ``robot``)
    robot_model: Mapped[str] = mapped_column(String(200))
    #: campaign date, ISO 8601 UTC (the run's start)
    campaign_date: Mapped[str] = mapped_column(String(40))
    recorded_utc: Mapped[str] = mapped_column(String(40))
    #: estimator (results.json ``method``, with the robust mode) and model class
    estimator: Mapped[str] = mapped_column(String(100))
    model_class: Mapped[str] = mapped_column(String(300))
    joints_identified: Mapped[str] = mapped_column(Text)  # JSON list of 1-based joints
    k_Nm_per_rad: Mapped[str] = mapped_column(Text)  # JSON, 6 values or null
    ci95_Nm_per_rad: Mapped[str] = mapped_column(Text)  # JSON, 6 [lo, hi] or null
    covariance_of_compliance: Mapped[str] = mapped_column(Text)  # JSON p x p
    chi2_reduced: Mapped[float | None] = mapped_column(Float, nullable=True)
    dof: Mapped[int | None] = mapped_column(Integer, nullable=True)
    condition_number: Mapped[float | None] = mapped_column(Float, nullable=True)
    #: the analysis was kept despite a refusal (results.json ``misfit_accepted``)
    accepted_despite_refusal: Mapped[bool] = mapped_column(Boolean)
    tool: Mapped[str] = mapped_column(Text)  # JSON: xyz_mm, rpy_deg as the run recorded
    payload_kg: Mapped[float | None] = mapped_column(Float, nullable=True)
    instruments: Mapped[str] = mapped_column(Text)  # JSON: role, model, serial, calibration
    results_sha256: Mapped[str] = mapped_column(String(64))
    tests_sha256: Mapped[str | None] = mapped_column(String(64), nullable=True)
    plan_sha256: Mapped[str | None] = mapped_column(String(64), nullable=True)
    protocol_sha256: Mapped[str | None] = mapped_column(String(64), nullable=True)
    #: where the files were when recorded (``history verify`` re-hashes them)
    source_dir: Mapped[str] = mapped_column(Text)
    #: report_id of the record this one corrects (None: an original record)
    supersedes: Mapped[str | None] = mapped_column(String(64), nullable=True)
    #: temperatures recorded by the run (JSON, deg C), None when none were
    temperatures: Mapped[str | None] = mapped_column(Text, nullable=True)
    software_version: Mapped[str | None] = mapped_column(String(100), nullable=True)
