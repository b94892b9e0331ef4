"""Temperatures recorded by the run and the software version that analysed it.

Revision ID: 0002
Revises: 0001
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("campaigns") as batch:
        batch.add_column(sa.Column("temperatures", sa.Text, nullable=True))
        batch.add_column(sa.Column("software_version", sa.String(100), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("campaigns") as batch:
        batch.drop_column("software_version")
        batch.drop_column("temperatures")
