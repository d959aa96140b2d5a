"""The memory `dms record` takes to read a file: a chunk bomb, and a long recording played.

Builds, in a temporary folder, a chunk bomb (a file of a few kilobytes whose one zstd
chunk inflates to a 300 MB message; ``--quick``: 100 MB) and a recording of 20,000
``dms/state`` messages of 1 KB (``--quick``: 2,000) written by ``dms record``'s
recorder. Each is read by a process of its own, whose peak resident memory is
measured: mcap's own reader going through the bomb (what ``dms record`` did before its
reader was bounded), ``dms record info`` on the bomb (refused), and ``dms record play
--rate 1000000`` of the recording (every message read and published, on a Zenoh session
that reaches nobody). Prints one JSON object.

    .venv/bin/python bench/bench_record_read.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from sim.mcap_read import MIB  # noqa: E402
from sim.recording import McapRecorder  # noqa: E402
from tests.integration.test_record_bounds import (  # noqa: E402
    T0,
    chunk_bomb,
    isolated_zenoh,
)

MCAP_OWN_READER = """
import sys
from mcap.stream_reader import StreamReader
with open(sys.argv[1], "rb") as stream:
    for record in StreamReader(stream).records:
        pass
"""


def peak_of(argv: list[str]) -> tuple[int, float, int, str]:
    """(exit status, seconds, peak RSS in MiB, last line of stderr) of ``argv`` run in a
    process of its own (its peak alone: a wrapper process waits for it)."""
    wrapper = (
        "import json, resource, subprocess, sys, time\n"
        "began = time.perf_counter()\n"
        "done = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
        "took = time.perf_counter() - began\n"
        "peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss // 1024\n"
        "lines = done.stderr.strip().splitlines()\n"
        "print(json.dumps([done.returncode, took, peak, lines[-1] if lines else '']))\n"
    )
    out = subprocess.run([sys.executable, "-c", wrapper, *argv], capture_output=True, text=True)
    code, took, peak, last = json.loads(out.stdout)
    return int(code), float(took), int(peak), str(last)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller files (smoke)")
    quick = parser.parse_args().quick
    bomb_mib = 100 if quick else 300
    messages = 2_000 if quick else 20_000
    dms = [sys.executable, "-m", "dms.cli"]
    result: dict[str, object] = {"bomb_inflated_mib": bomb_mib, "messages": messages}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        bomb = folder / "bomb.mcap"
        bomb.write_bytes(chunk_bomb(bomb_mib * MIB))
        result["bomb_file_bytes"] = bomb.stat().st_size
        long = folder / "long.mcap"
        recorder = McapRecorder(long, "mini")
        filler = "x" * 1000
        for tick in range(messages):
            payload = json.dumps({"tick": tick, "filler": filler}).encode()
            recorder.write("robots/mini/dms/state", payload, T0 + tick * 500_000_000)
        recorder.close()
        result["long_file_bytes"] = long.stat().st_size
        alone = str(isolated_zenoh(folder))

        code, took, peak, _ = peak_of([sys.executable, "-c", MCAP_OWN_READER, str(bomb)])
        result["mcap_reader_on_bomb"] = {"exit": code, "s": round(took, 2), "peak_rss_mib": peak}
        code, took, peak, said = peak_of([*dms, "record", "info", str(bomb)])
        result["record_info_on_bomb"] = {
            "exit": code,
            "s": round(took, 2),
            "peak_rss_mib": peak,
            "refused": "over the" in said,
        }
        play = [*dms, "record", "play", str(long), "--rate", "1000000", "--zenoh-config", alone]
        code, took, peak, said = peak_of(play)
        result["record_play_long"] = {
            "exit": code,
            "s": round(took, 2),
            "peak_rss_mib": peak,
            "played": said,
        }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
