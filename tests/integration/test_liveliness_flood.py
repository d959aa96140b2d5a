"""A peer that declares thousands of distinct liveliness tokens under the robot's
``alive/``: one real ``dms run``, real Zenoh sessions on 127.0.0.1.

Tokens that name no input go no further than the bus: they are counted and reported on
``dms/errors`` once a second at most, with their count and the latest one; the daemon's
memory stays flat, ``dms/state`` keeps coming, and a module's own token still counts.
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import Collector, client_session, put, running_daemon
from tests.integration.hostile import Reports, assert_alive

pytestmark = pytest.mark.integration

TOKENS = 3000
REPORT = re.compile(
    r"ignored (\d+) liveliness tokens that name no input, the latest "
    r"alive/junk/\d+ \((\d+) since start\)"
)
RSS_MARGIN_KIB = 20 * 1024
ANN = {"present": True, "user_id": "ann", "ready": True, "engagement": 0.8}


def _rss_kib(pid: int) -> int:
    """The process's resident memory (``VmRSS`` of /proc/PID/status), in KiB."""
    status = Path(f"/proc/{pid}/status").read_text()
    found = re.search(r"^VmRSS:\s+(\d+) kB$", status, re.MULTILINE)
    assert found is not None
    return int(found.group(1))


def _count(report: dict[str, Any]) -> int:
    """The tokens a report says were ignored since the last one (0: another report)."""
    found = REPORT.fullmatch(report["error"])
    return 0 if found is None else int(found.group(1))


def _total(report: dict[str, Any]) -> int:
    found = REPORT.fullmatch(report["error"])
    return 0 if found is None else int(found.group(2))


def test_a_flood_of_distinct_tokens_is_counted_reported_once_a_second_and_kept_nowhere(
    tmp_path: Path,
) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        assert daemon.proc is not None
        states = Collector(session, "robots/mini/dms/state")
        reports = Reports(session)
        states.wait_count(1)
        before = _rss_kib(daemon.proc.pid)
        peer = client_session(daemon.port)
        try:
            liveliness = peer.liveliness()
            started = time.monotonic()
            tokens = [
                liveliness.declare_token(f"robots/mini/alive/junk/{index}")
                for index in range(TOKENS)
            ]
            reports.wait_for(lambda r: _total(r) == TOKENS, timeout=60)
            elapsed = time.monotonic() - started
            said = [r for r in reports.on("alive/**") if REPORT.fullmatch(r["error"])]
            assert sum(_count(r) for r in said) == TOKENS
            assert len(said) <= elapsed + 2, f"{len(said)} reports in {elapsed:.1f} s"
            assert all(r["key"] == "alive/**" for r in said)
            assert _rss_kib(daemon.proc.pid) - before <= RSS_MARGIN_KIB
            assert_alive(daemon, session, states)

            # a module's own token is still heard after the flood, and its withdrawal too
            user = liveliness.declare_token("robots/mini/alive/perception/user")
            put(peer, "perception/user", ANN)
            states.wait_for(lambda s: s["inputs"].get("perception/user") == "ok")
            mark = states.mark()
            user.undeclare()  # type: ignore[no-untyped-call]
            states.wait_for(lambda s: s["inputs"].get("perception/user") == "missing", start=mark)
            for token in tokens:
                token.undeclare()  # type: ignore[no-untyped-call]
        finally:
            peer.close()  # type: ignore[no-untyped-call]
