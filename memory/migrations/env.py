"""Alembic environment of the profile store, run programmatically by ``memory.migrations``.

The connection comes in ``config.attributes["connection"]``; the store keeps its own
version table so that it shares the daemon's database with the agenda.
"""

from __future__ import annotations

from alembic import context

from memory.migrations import VERSION_TABLE
from memory.models import Base

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
