"""Claims of occurrences: one robot of a fleet delivers each one.

Revision ID: agenda_0002
Revises: agenda_0001
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from agenda.models import UtcDateTime

revision = "agenda_0002"
down_revision = "agenda_0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "agenda_claims",
        sa.Column("item_id", sa.Integer(), nullable=False),
        sa.Column("fire_time", UtcDateTime(), nullable=False),
        sa.Column("user_id", sa.String(64), nullable=False),
        sa.Column("claimed_by", sa.String(200), nullable=False),
        sa.Column("claimed_at", UtcDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("item_id", "fire_time", name="pk_agenda_claims"),
    )
    op.create_index("ix_agenda_claims_user_id", "agenda_claims", ["user_id"])


def downgrade() -> None:
    op.drop_index("ix_agenda_claims_user_id", table_name="agenda_claims")
    op.drop_table("agenda_claims")
