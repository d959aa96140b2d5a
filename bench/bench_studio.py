"""How fast ``dms studio``'s page is ready, and how soon a trial lights its first state.

Starts ``dms studio`` on a copy of the shipped behaviors, opens the page in Debian's
Chromium (Playwright) with ``?open=quiz``, and measures, each run in a fresh page:
``page_ready_ms``, from the navigation to the palette, the canvas and the properties
drawn (the page's ``data-ready``); ``first_lit_ms``, from the click on Run to the first
state lit on the canvas (the trial started on the simulated Mini and drawn). Prints one
JSON object with the median and the worst of each.

    .venv/bin/python bench/bench_studio.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from activities.library import BEHAVIORS_DIR
from tests.integration.test_studio import running_studio
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS

RUNS = 10
WAIT_MS = 30_000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two runs (smoke)")
    quick = parser.parse_args().quick
    runs = 2 if quick else RUNS
    from playwright.sync_api import sync_playwright

    ready_ms: list[float] = []
    lit_ms: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "behaviors"
        shutil.copytree(BEHAVIORS_DIR, folder)
        with running_studio(folder) as studio, sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            try:
                for _ in range(runs):
                    page = browser.new_page(viewport={"width": 1400, "height": 900})
                    page.set_default_timeout(WAIT_MS)
                    began = time.perf_counter()
                    page.goto(studio.url + "&open=quiz")
                    page.wait_for_selector("body[data-ready='1']")
                    page.wait_for_selector('.state[data-path="INTRO"]')
                    ready_ms.append((time.perf_counter() - began) * 1000)
                    began = time.perf_counter()
                    page.click("#run-button")
                    page.wait_for_selector(".state.lit")
                    lit_ms.append((time.perf_counter() - began) * 1000)
                    page.click("#stop-button")
                    page.close()
            finally:
                browser.close()
    print(
        json.dumps(
            {
                "runs": runs,
                "quick": quick,
                "page_ready_ms_median": round(statistics.median(ready_ms), 1),
                "page_ready_ms_max": round(max(ready_ms), 1),
                "first_lit_ms_median": round(statistics.median(lit_ms), 1),
                "first_lit_ms_max": round(max(lit_ms), 1),
            }
        )
    )


if __name__ == "__main__":
    main()
