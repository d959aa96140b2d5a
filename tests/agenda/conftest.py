"""Fixtures of the agenda tests: a real SQLite file per test and a virtual start time."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest

from agenda import Agenda

START = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)
"""A Monday, 10:00 in Madrid."""


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'dms.db'}"


@pytest.fixture
def agenda(db_url: str) -> Iterator[Agenda]:
    store = Agenda.open(db_url)
    yield store
    store.close()
