"""Alembic environment of the agenda, run programmatically by ``agenda.migrations``.

The connection comes in ``config.attributes["connection"]``; the agenda keeps its
own version table so that it shares the daemon's database with the profile store.
"""

from __future__ import annotations

from alembic import context

from agenda.migrations import VERSION_TABLE
from agenda.models import Base

connection = context.config.attributes["connection"]
context.configure(
    connection=connection,
    target_metadata=Base.metadata,
    version_table=VERSION_TABLE,
    include_name=lambda name, type_, _parent: type_ != "table" or name in Base.metadata.tables,
    render_as_batch=True,
)
with context.begin_transaction():
    context.run_migrations()
