"""The first ledger schema: the campaigns table without temperatures and software_version.

Revision ID: 0001
Revises: (none)
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "campaigns",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("report_id", sa.String(64), nullable=False),
        sa.Column("robot_id", sa.String(200), nullable=False),
        sa.Column("robot_model", sa.String(200), nullable=False),
        sa.Column("campaign_date", sa.String(40), nullable=False),
        sa.Column("recorded_utc", sa.String(40), nullable=False),
        sa.Column("estimator", sa.String(100), nullable=False),
        sa.Column("model_class", sa.String(300), nullable=False),
        sa.Column("joints_identified", sa.Text, nullable=False),
        sa.Column("k_Nm_per_rad", sa.Text, nullable=False),
        sa.Column("ci95_Nm_per_rad", sa.Text, nullable=False),
        sa.Column("covariance_of_compliance", sa.Text, nullable=False),
        sa.Column("chi2_reduced", sa.Float, nullable=True),
        sa.Column("dof", sa.Integer, nullable=True),
        sa.Column("condition_number", sa.Float, nullable=True),
        sa.Column("accepted_despite_refusal", sa.Boolean, nullable=False),
        sa.Column("tool", sa.Text, nullable=False),
        sa.Column("payload_kg", sa.Float, nullable=True),
        sa.Column("instruments", sa.Text, nullable=False),
        sa.Column("results_sha256", sa.String(64), nullable=False),
        sa.Column("tests_sha256", sa.String(64), nullable=True),
        sa.Column("plan_sha256", sa.String(64), nullable=True),
        sa.Column("protocol_sha256", sa.String(64), nullable=True),
        sa.Column("source_dir", sa.Text, nullable=False),
        sa.Column("supersedes", sa.String(64), nullable=True),
        sa.UniqueConstraint("report_id", name="uq_campaigns_report_id"),
    )
    op.create_index("ix_campaigns_robot_id", "campaigns", ["robot_id"])


def downgrade() -> None:
    op.drop_index("ix_campaigns_robot_id", table_name="campaigns")
    op.drop_table("campaigns")
