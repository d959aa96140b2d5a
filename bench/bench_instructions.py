"""Instructions the long-term simulation executes: one JSON object on stdout.

Wall time on a shared machine moves by a tenth within the hour (the same commit ran the
30-day simulation in 9.9 s and in 12.2 s an hour apart), which hides any change
smaller than that. The instructions a run executes move by about 0.1 % between runs,
so two commits can be compared by them, provided the hashes of strings are the same in
both: Python picks a random hash seed per process, which moves the count by up to 1 %
(dictionaries and sets lay out differently), so the runs use ``PYTHONHASHSEED=0``
(``--hash-seed``). Counted by valgrind's cachegrind, with no cache simulation; a run
takes about fifty times its wall time (some 9 minutes for 30 days).

- ``imports``: importing the simulator (what ``bench_sim.py`` does before it times);
- ``run``: ``run_longterm`` itself, the part ``bench_sim.py`` times as
  ``longterm_30d_3u_s``, its stack's own imports included (the difference of two runs).

Run: ``.venv/bin/python bench/bench_instructions.py [--days 30] [--seed 0] [--hash-seed 0]``
(needs ``valgrind``: ``apt install valgrind``; without it the object says it was skipped).
``--quick``: one simulated day, run without valgrind (not counted): a smoke test.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys

IMPORTS = "import sim.harness, sim.longterm, sim.persona, sim.study, sim.user"
RUN = (
    IMPORTS + "\nfrom sim.longterm import run_longterm\n"
    "result = run_longterm(days={days}, users=3, seed={seed})\n"
    "print('decisions', result.decisions, 'ticks', result.ticks)"
)
REFS = re.compile(r"I\s+refs:\s+([\d,]+)")


def instructions(code: str, hash_seed: int) -> tuple[int, str]:
    """The instructions ``python -c code`` executes under cachegrind, and its stdout."""
    done = subprocess.run(
        [
            "valgrind",
            "--tool=cachegrind",
            "--cache-sim=no",
            "--cachegrind-out-file=/dev/null",
            sys.executable,
            "-c",
            code,
        ],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "PYTHONHASHSEED": str(hash_seed)},
    )
    found = REFS.search(done.stderr)
    if done.returncode != 0 or found is None:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"bench_instructions: the run failed: {last}")
    return int(found.group(1).replace(",", "")), done.stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--days", type=int, default=30, help="simulated days (default 30)")
    parser.add_argument("--seed", type=int, default=0, help="the run's seed (default 0)")
    parser.add_argument(
        "--hash-seed",
        type=int,
        default=0,
        help="PYTHONHASHSEED of the runs (default 0): the same in runs to compare",
    )
    parser.add_argument(
        "--quick", action="store_true", help="run the counted day once, uncounted (smoke)"
    )
    args = parser.parse_args()
    if args.days < 1:
        parser.error("--days: must be at least 1")
    if args.quick:
        # Counting takes minutes under valgrind: the smoke test runs what would be counted.
        done = subprocess.run(
            [sys.executable, "-c", RUN.format(days=1, seed=args.seed)],
            capture_output=True,
            text=True,
            check=True,
            env={**os.environ, "PYTHONHASHSEED": str(args.hash_seed)},
        )
        words = done.stdout.split()
        ticks = int(words[words.index("ticks") + 1])
        print(json.dumps({"benchmark": "instructions", "quick": True, "days": 1, "ticks": ticks}))
        return
    if shutil.which("valgrind") is None:
        skipped = "valgrind not found (apt install valgrind)"
        print(json.dumps({"benchmark": "instructions", "skipped": skipped}))
        return
    if not 0 <= args.hash_seed <= 4294967295:
        parser.error("--hash-seed: must be in [0, 4294967295]")
    imports, _ = instructions(IMPORTS, args.hash_seed)
    total, printed = instructions(RUN.format(days=args.days, seed=args.seed), args.hash_seed)
    words = printed.split()
    print(
        json.dumps(
            {
                "benchmark": "instructions",
                "days": args.days,
                "seed": args.seed,
                "hash_seed": args.hash_seed,
                "imports_g": round(imports / 1e9, 3),
                "run_g": round((total - imports) / 1e9, 3),
                "decisions": int(words[words.index("decisions") + 1]),
                "ticks": int(words[words.index("ticks") + 1]),
            }
        )
    )


if __name__ == "__main__":
    main()
