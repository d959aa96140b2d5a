"""Fixtures of the fleet tests: several robots' stores on one database.

Two stores (or agendas) opened on one URL are two robots: each has its own engine and
connections. ``fleet_url`` is a SQLite file and, when ``DMS_TEST_POSTGRES_URL`` is set, a
fresh PostgreSQL schema too; ``pg_url`` is PostgreSQL only (skipped without it).
"""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest

from tests.postgres import POSTGRES_URL, fresh_schema

NOW = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)
BACKENDS = ["sqlite", *(["postgres"] if POSTGRES_URL else [])]
NO_POSTGRES = "DMS_TEST_POSTGRES_URL is not set: no PostgreSQL server to share"


@pytest.fixture(params=BACKENDS)
def fleet_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """One database for every robot of the test: a SQLite file or a PostgreSQL schema."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'fleet.db'}"
        return
    with fresh_schema("fleet") as url:
        yield url


@pytest.fixture
def pg_url() -> Iterator[str]:
    """A fresh PostgreSQL schema; the test is skipped without a server."""
    if not POSTGRES_URL:
        pytest.skip(NO_POSTGRES)
    with fresh_schema("fleet") as url:
        yield url
