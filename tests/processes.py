"""Child processes a module's fixture owns, for the leak check of tests/conftest.py."""

from __future__ import annotations

import subprocess
import threading

MODULE_OWNED: set[int] = set()
"""Child processes a module's fixture owns and ends after the module, started again by
one of its tests (a robot's simulator restarted to test a reconnection): not a leak."""
MODULE_THREADS: set[threading.Thread] = set()
"""The threads that read those processes' output (they end with them)."""


def owned_by_module(process: subprocess.Popen[str], *readers: threading.Thread) -> None:
    """Say that ``process`` (and the ``readers`` of its output), started in a test, is its
    module fixture's to end."""
    MODULE_OWNED.add(process.pid)
    MODULE_THREADS.update(readers)
