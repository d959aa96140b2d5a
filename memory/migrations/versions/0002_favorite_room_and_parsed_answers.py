"""The user's favorite room; the fields each answer to a general question filled.

Revision ID: memory_0002
Revises: memory_0001
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "memory_0002"
down_revision = "memory_0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("users") as batch:
        batch.add_column(sa.Column("favorite_room", sa.String(100), nullable=True))
    with op.batch_alter_table("answers") as batch:
        batch.add_column(sa.Column("applied", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("answers") as batch:
        batch.drop_column("applied")
    with op.batch_alter_table("users") as batch:
        batch.drop_column("favorite_room")
