"""Users, their activity scores and their history (sessions, runs, feedback, answers).

Revision ID: memory_0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "memory_0001"
down_revision = None
branch_labels = None
depends_on = None


def _user_fk() -> sa.Column[str]:
    return sa.Column(
        "user_id",
        sa.String(200),
        sa.ForeignKey("users.user_id", ondelete="CASCADE"),
        nullable=False,
        index=True,
    )


def upgrade() -> None:
    op.create_table(
        "users",
        sa.Column("user_id", sa.String(200), primary_key=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("name", sa.String(200), nullable=True),
        sa.Column("age", sa.Integer(), nullable=True),
        sa.Column("sex", sa.String(20), nullable=True),
        sa.Column("language", sa.String(50), nullable=True),
        sa.Column("hearing", sa.Boolean(), nullable=True),
        sa.Column("dialogue_mode", sa.String(20), nullable=True),
        sa.Column("interaction_style", sa.String(20), nullable=False),
        sa.Column("volume", sa.Float(), nullable=True),
        sa.Column("distance", sa.Float(), nullable=True),
        sa.Column("robot_initiative_frequency", sa.String(20), nullable=True),
        sa.Column("proactivity", sa.String(20), nullable=False),
        sa.Column("proactivity_confidence", sa.Float(), nullable=False),
        sa.Column("bondlevel", sa.Integer(), nullable=True),
        sa.Column("attributes", sa.JSON(), nullable=False),
        sa.Column("voice_failures", sa.Integer(), nullable=False),
        sa.Column("screen_failures", sa.Integer(), nullable=False),
        sa.Column("initiative_taken", sa.Integer(), nullable=False),
        sa.Column("initiative_offered", sa.Integer(), nullable=False),
    )
    op.create_table(
        "activity_scores",
        sa.Column(
            "user_id",
            sa.String(200),
            sa.ForeignKey("users.user_id", ondelete="CASCADE"),
            primary_key=True,
        ),
        sa.Column("activity", sa.String(50), primary_key=True),
        sa.Column("feedback_sum", sa.Float(), nullable=False),
        sa.Column("feedback_count", sa.Integer(), nullable=False),
        sa.Column("completions", sa.Integer(), nullable=False),
        sa.Column("cancellations", sa.Integer(), nullable=False),
    )
    op.create_table(
        "sessions",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        _user_fk(),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("ended_at", sa.DateTime(timezone=True), nullable=True),
    )
    op.create_table(
        "activity_runs",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        _user_fk(),
        sa.Column(
            "session_id",
            sa.Integer(),
            sa.ForeignKey("sessions.id", ondelete="CASCADE"),
            nullable=True,
            index=True,
        ),
        sa.Column("activity", sa.String(50), nullable=False),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("ended_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("outcome", sa.String(50), nullable=False),
        sa.Column("chosen_by", sa.String(20), nullable=False),
        sa.Column("cancelled", sa.Boolean(), nullable=False),
    )
    op.create_table(
        "feedback",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        _user_fk(),
        sa.Column("activity", sa.String(50), nullable=False),
        sa.Column("score", sa.Float(), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
    )
    op.create_table(
        "answers",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        _user_fk(),
        sa.Column("question_id", sa.String(100), nullable=False),
        sa.Column("answer", sa.Text(), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
    )


def downgrade() -> None:
    for table in ("answers", "feedback", "activity_runs", "sessions", "activity_scores", "users"):
        op.drop_table(table)
