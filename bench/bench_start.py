"""Start time and idle memory of ``dms run``; prints one JSON object.

- time from exec of ``dms run`` to its liveliness token ``robots/<id>/alive/dms``, seen
  by another process's Zenoh session: median and max of ``--starts`` starts (default 10),
  each on a free loopback port with a fresh temporary SQLite database (``ready_s_*``;
  its schema is made right after ready), and as many restarts on one database already
  at head (``restart_s_*``: what a supervisor restarting a crashed daemon waits);
- beside them, the time of a bare ``python -c "import numpy, sqlalchemy, zenoh, pydantic"``
  run before each start (``bare_import_s_median``), and the starts as multiples of it
  (``ready_vs_bare``, ``restart_vs_bare``; target <= 2): the machine's speed and load
  cancel out; ``*_paired``: the median of each start over its own bare run, which also
  cancels a load that drifts during the benchmark;
- the time from exec to the answer of a ``users/*`` query asked as soon as the token is
  seen (``store_s_median``): the daemon opens its profile store and its agenda right
  after ready, and such a query waits for them;
- the daemon's resident memory (RSS, from ``/proc``) once it answered that query, and
  after ``--idle-s`` seconds idle (default 600: ten minutes) in one more start.

Before timing, the project's modules are compiled to bytecode (``compileall``), as pip
does when it installs a package: the site-packages of the bare import are compiled too,
and under ``PYTHONDONTWRITEBYTECODE`` every start would otherwise compile the project
first (0.3-0.5 s). ``--no-compile`` leaves the tree as it is.

Not a timed test: wall-clock figures on a shared machine; run it when the start path
changes. Usage: ``.venv/bin/python bench/bench_start.py [--starts N] [--idle-s S] [--quick]
[--no-compile]``
(``--quick``: two starts of each kind, one second idle).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zenoh  # noqa: E402

from tests.integration.harness import free_port  # noqa: E402

TOKEN = "robots/mini/alive/dms"
USERS = "robots/mini/users/*"
BARE = "import numpy, sqlalchemy, zenoh, pydantic"
"""What any process of the daemon's stack imports: the floor of its start time."""
PACKAGES = ("dms", "activities", "agenda", "managers", "memory", "motivation", "sim")
"""The project's packages, compiled before timing."""


def compile_project() -> None:
    """Write the bytecode of :data:`PACKAGES`, as an installation does."""
    command = [sys.executable, "-m", "compileall", "-q", *PACKAGES]
    subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)


def bare_import_s() -> float:
    """Seconds of one ``python -c BARE``, from exec to exit."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", BARE], check=True)
    return time.perf_counter() - t0


def watcher_session(port: int) -> zenoh.Session:
    """A peer that keeps trying to connect to ``port`` every 20 ms, so that the token is
    seen as soon as the daemon listens (Zenoh's default retry, 1 s then doubling, would
    add up to a second of the watcher's own to the figure)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5(
        "connect/retry", "{period_init_ms: 20, period_max_ms: 20, period_increase_factor: 1}"
    )
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


def rss_mb(pid: int) -> float:
    """Resident set size of ``pid`` in MB (VmRSS of /proc/PID/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError(f"no VmRSS for {pid}")


def start_daemon(tmp: Path, port: int) -> subprocess.Popen[bytes]:
    """Exec ``dms run`` quietly on ``port`` with a fresh SQLite file in ``tmp``."""
    db = f"sqlite:///{tmp / 'dms.db'}"
    command = [sys.executable, "-m", "dms.cli", "run", "--quiet", "--db", db]
    command += ["--listen", f"tcp/127.0.0.1:{port}", "--seed", "1"]
    # the users/ query of the store's figure is answered only with profiles served
    env = {**os.environ, "DMS_PRIVACY__SERVE_PROFILES": "true"}
    return subprocess.Popen(
        command,
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=(tmp / "daemon.log").open("wb"),
    )


def one_start(
    timeout: float, folder: Any = None
) -> tuple[float, float, subprocess.Popen[bytes], Any, Any]:
    """Seconds from exec to the token and to the answer of a ``users/*`` query asked
    then, in ``folder`` (a TemporaryDirectory; a new one by default); the process, its
    session and the folder are returned still open (the caller measures memory, then
    stops them)."""
    folder = folder or tempfile.TemporaryDirectory()
    tmp = Path(folder.name)
    port = free_port()
    session = watcher_session(port)  # waits for the daemon before it exists
    seen = threading.Event()

    def on_token(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            seen.set()

    subscriber = session.liveliness().declare_subscriber(TOKEN, on_token, history=True)
    t0 = time.perf_counter()
    proc = start_daemon(tmp, port)
    if not seen.wait(timeout):
        proc.kill()
        raise RuntimeError(f"no {TOKEN} within {timeout}s:\n{(tmp / 'daemon.log').read_text()}")
    elapsed = time.perf_counter() - t0
    subscriber.undeclare()
    answers = [reply.ok for reply in session.get(USERS, timeout=timeout) if reply.ok]
    if not answers:
        proc.kill()
        raise RuntimeError(f"no answer to {USERS}:\n{(tmp / 'daemon.log').read_text()}")
    store = time.perf_counter() - t0
    return elapsed, store, proc, session, folder


def stop(proc: subprocess.Popen[bytes], session: Any, folder: Any, keep: bool = False) -> None:
    proc.terminate()
    try:
        proc.wait(30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(10)
    session.close()
    if not keep:
        folder.cleanup()


def paired(starts: list[float], bares: list[float]) -> float:
    """The median of each start over the bare import run just before it: on a shared
    machine whose load drifts during the run, each pair shares its moment."""
    return round(statistics.median(t / b for t, b in zip(starts, bares, strict=True)), 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=10, help="starts timed (default 10)")
    parser.add_argument(
        "--idle-s", type=float, default=600.0, help="idle time before the last RSS (default 600)"
    )
    parser.add_argument("--timeout", type=float, default=60.0, help="readiness wait per start")
    parser.add_argument("--quick", action="store_true", help="2 starts each, 1 s idle (smoke)")
    parser.add_argument(
        "--no-compile", action="store_true", help="do not compile the project's bytecode first"
    )
    args = parser.parse_args()
    if args.quick:
        args.starts, args.idle_s = 2, 1.0
    if not args.no_compile:
        compile_project()

    times: list[float] = []
    stores: list[float] = []
    ready_rss: list[float] = []
    bare: list[float] = []
    for _ in range(args.starts):
        bare.append(bare_import_s())
        elapsed, store, proc, session, folder = one_start(args.timeout)
        times.append(elapsed)
        stores.append(store)
        ready_rss.append(rss_mb(proc.pid))
        stop(proc, session, folder)

    restarts: list[float] = []
    _, _, proc, session, kept = one_start(args.timeout)  # creates the database, not timed
    stop(proc, session, kept, keep=True)
    for _ in range(args.starts):
        bare.append(bare_import_s())
        elapsed, _, proc, session, kept = one_start(args.timeout, kept)
        restarts.append(elapsed)
        stop(proc, session, kept, keep=True)
    kept.cleanup()

    elapsed, _, proc, session, folder = one_start(args.timeout)
    at_ready = rss_mb(proc.pid)
    samples: list[tuple[float, float]] = []
    t0 = time.monotonic()
    while (waited := time.monotonic() - t0) < args.idle_s:
        time.sleep(min(5.0, args.idle_s - waited))
        samples.append((round(time.monotonic() - t0, 1), round(rss_mb(proc.pid), 1)))
    after = rss_mb(proc.pid)
    stop(proc, session, folder)

    result: dict[str, Any] = {
        "benchmark": "start",
        "cpus": os.cpu_count(),
        "load_1min": round(os.getloadavg()[0], 2),
        "starts": args.starts,
        "compiled": not args.no_compile,
        "ready_s_median": round(statistics.median(times), 3),
        "ready_s_max": round(max(times), 3),
        "ready_s_all": [round(t, 3) for t in times],
        "store_s_median": round(statistics.median(stores), 3),
        "restart_s_median": round(statistics.median(restarts), 3),
        "restart_s_max": round(max(restarts), 3),
        "bare_import_s_median": round(statistics.median(bare), 3),
        "ready_vs_bare": round(statistics.median(times) / statistics.median(bare), 2),
        "restart_vs_bare": round(statistics.median(restarts) / statistics.median(bare), 2),
        "ready_vs_bare_paired": paired(times, bare[: args.starts]),
        "restart_vs_bare_paired": paired(restarts, bare[args.starts :]),
        "rss_mb_at_ready_median": round(statistics.median(ready_rss), 1),
        "idle_s": args.idle_s,
        "rss_mb_at_ready": round(at_ready, 1),
        "rss_mb_after_idle": round(after, 1),
        "rss_mb_idle_peak": max((mb for _, mb in samples), default=round(after, 1)),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
