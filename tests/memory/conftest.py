"""Fixtures of the memory tests: a store on a real SQLite file, and on PostgreSQL too
when ``DMS_TEST_POSTGRES_URL`` is set (each test then gets its own fresh schema)."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest

from memory import ProfileStore
from tests.postgres import POSTGRES_URL, fresh_schema

NOW = datetime(2026, 11, 22, 10, 0, tzinfo=UTC)
BACKENDS = ["sqlite", *(["postgres"] if POSTGRES_URL else [])]


@pytest.fixture(params=BACKENDS)
def db_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """An empty database: a SQLite file, or a fresh PostgreSQL schema."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'dms.db'}"
        return
    with fresh_schema() as url:
        yield url


@pytest.fixture
def store(db_url: str) -> Iterator[ProfileStore]:
    profiles = ProfileStore(db_url)
    yield profiles
    profiles.close()
