"""The agenda's items and its log of deliveries and misses.

Revision ID: agenda_0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from agenda.models import UtcDateTime

revision = "agenda_0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "agenda_items",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column("user_id", sa.String(64), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("activity", sa.String(64), nullable=True),
        sa.Column("text", sa.Text(), nullable=True),
        sa.Column("schedule", sa.String(8), nullable=False),
        sa.Column("spec", sa.String(200), nullable=False),
        sa.Column("anchor", UtcDateTime(), nullable=True),
        sa.Column("tz", sa.String(64), nullable=False),
        sa.Column("priority", sa.String(8), nullable=False),
        sa.Column("lead_s", sa.Integer(), nullable=False),
        sa.Column("grace_s", sa.Integer(), nullable=False),
        sa.Column("created_at", UtcDateTime(), nullable=False),
        sa.Column("next_fire", UtcDateTime(), nullable=True),
        sa.PrimaryKeyConstraint("id", name="pk_agenda_items"),
    )
    op.create_index("ix_agenda_items_user_id", "agenda_items", ["user_id"])
    op.create_table(
        "agenda_occurrences",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column("item_id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.String(64), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("what", sa.Text(), nullable=False),
        sa.Column("outcome", sa.String(16), nullable=False),
        sa.Column("fire_time", UtcDateTime(), nullable=False),
        sa.Column("last_fire_time", UtcDateTime(), nullable=False),
        sa.Column("count", sa.Integer(), nullable=False),
        sa.Column("recorded_at", UtcDateTime(), nullable=False),
        sa.Column("reason", sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_agenda_occurrences"),
        sa.UniqueConstraint("item_id", "fire_time", name="uq_agenda_occurrences_item_id"),
    )
    op.create_index("ix_agenda_occurrences_user_id", "agenda_occurrences", ["user_id"])


def downgrade() -> None:
    op.drop_index("ix_agenda_occurrences_user_id", table_name="agenda_occurrences")
    op.drop_table("agenda_occurrences")
    op.drop_index("ix_agenda_items_user_id", table_name="agenda_items")
    op.drop_table("agenda_items")
