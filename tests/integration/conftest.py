"""What the tests with a daemon and a Zenoh session share."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.integration.harness import Collector


@pytest.fixture(autouse=True)
def collectors_closed() -> Iterator[None]:
    """Every collector a test made is closed after it (see :class:`Collector`)."""
    yield
    Collector.close_all()
