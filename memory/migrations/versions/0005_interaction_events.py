"""Each session's interaction events: offers, inputs, activity decisions, arrival, departure.

What a participant model is fitted to (``dms sessions export --events``, ``dms sim fit``):
every row is one event of one session, written by the daemon as the session runs.

Revision ID: memory_0005
Revises: memory_0004
Create Date: 2026-12-06
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "memory_0005"
down_revision = "memory_0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "interaction_events",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column(
            "user_id",
            sa.String(200),
            sa.ForeignKey("users.user_id", ondelete="CASCADE"),
            nullable=False,
            index=True,
        ),
        sa.Column(
            "session_id",
            sa.Integer(),
            sa.ForeignKey("sessions.id", ondelete="CASCADE"),
            nullable=True,
            index=True,
        ),
        sa.Column("seq", sa.Integer(), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("event", sa.String(20), nullable=False),
        sa.Column("offer", sa.Integer(), nullable=True),
        sa.Column("offer_kind", sa.String(20), nullable=True),
        sa.Column("channel", sa.String(20), nullable=True),
        sa.Column("value", sa.String(200), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=True),
        sa.Column("understood", sa.Boolean(), nullable=True),
        sa.Column("delay_s", sa.Float(), nullable=True),
        sa.Column("activity", sa.String(50), nullable=True),
        sa.Column("by", sa.String(64), nullable=True),
        sa.Column("detail", sa.String(200), nullable=True),
    )


def downgrade() -> None:
    op.drop_table("interaction_events")
