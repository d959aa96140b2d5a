"""A fresh PostgreSQL schema per test, on the server of ``DMS_TEST_POSTGRES_URL`` (CI
starts one; tests that need it skip without it)."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from urllib.parse import quote

from sqlalchemy import create_engine, text

POSTGRES_URL = os.environ.get("DMS_TEST_POSTGRES_URL")


def schema_url(base: str, schema: str) -> str:
    """``base`` with ``schema`` as its search path: the store's tables land there."""
    separator = "&" if "?" in base else "?"
    return f"{base}{separator}options={quote(f'-csearch_path={schema}')}"


@contextmanager
def fresh_schema(prefix: str = "t") -> Iterator[str]:
    """The URL of a new empty schema on the test server, dropped afterwards."""
    assert POSTGRES_URL is not None, "DMS_TEST_POSTGRES_URL is not set"
    schema = f"{prefix}_{uuid.uuid4().hex[:12]}"
    admin = create_engine(POSTGRES_URL)
    with admin.begin() as connection:
        connection.execute(text(f'CREATE SCHEMA "{schema}"'))
    try:
        yield schema_url(POSTGRES_URL, schema)
    finally:
        with admin.begin() as connection:
            connection.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()
