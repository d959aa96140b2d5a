"""Several robots on one profile: a version per user row, applied write ids.

``users.version`` is the optimistic lock of field writes (0 for the rows that exist
before it); ``applied_writes`` holds the unique id of each applied write so that a
write replayed from a spool is applied once.

Revision ID: memory_0004
Revises: memory_0003
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "memory_0004"
down_revision = "memory_0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("users") as batch:
        batch.add_column(sa.Column("version", sa.Integer(), nullable=False, server_default="0"))
    op.create_table(
        "applied_writes",
        sa.Column("write_id", sa.String(64), primary_key=True),
        sa.Column(
            "user_id",
            sa.String(200),
            sa.ForeignKey("users.user_id", ondelete="CASCADE"),
            nullable=False,
            index=True,
        ),
        sa.Column("result", sa.Integer(), nullable=True),
        sa.Column("applied_at", sa.DateTime(timezone=True), nullable=False, index=True),
    )


def downgrade() -> None:
    op.drop_table("applied_writes")
    with op.batch_alter_table("users") as batch:
        batch.drop_column("version")
