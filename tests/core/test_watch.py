"""The file watch of hot reload: what counts as a change, when it asks for a reload, and
a prompt stop (the daemon's hot reload is in tests/integration/test_hot_reload.py)."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

from dms.watch import FileWatch, fingerprint


def _folder(tmp_path: Path) -> tuple[Path, Path]:
    folder = tmp_path / "behaviors"
    (folder / "drafts").mkdir(parents=True)
    (folder / "jokes.yaml").write_text("name: jokes\n")
    rules = tmp_path / "decisions.dmsl"
    rules.write_text('component C [ activate "jokes" ]\n')
    return folder, rules


def test_the_fingerprint_changes_with_a_behavior_or_rules_file_and_not_with_a_draft(
    tmp_path: Path,
) -> None:
    folder, rules = _folder(tmp_path)
    first = fingerprint(folder, [rules])
    assert [entry[0] for entry in first] == [str(folder / "jokes.yaml"), str(rules)]
    assert fingerprint(folder, [rules]) == first

    (folder / "drafts" / "jokes.draft.yaml").write_text("name: jokes\nbroken")
    (folder / "notes.txt").write_text("not a behavior")
    assert fingerprint(folder, [rules]) == first

    (folder / "jokes.yaml").write_text("name: jokes\nstates: {}\n")
    second = fingerprint(folder, [rules])
    assert second != first
    rules.write_text('component C [ activate "news" ]\n')
    assert fingerprint(folder, [rules]) != second


def test_a_same_size_save_in_the_same_mtime_is_a_change(tmp_path: Path) -> None:
    folder, _rules = _folder(tmp_path)
    path = folder / "jokes.yaml"
    stat = path.stat()
    first = fingerprint(folder, [])
    saved = folder / "jokes.yaml.tmp"  # an atomic save: a new file renamed over it
    saved.write_text("name: jokez\n")
    os.utime(saved, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    saved.replace(path)
    assert fingerprint(folder, []) != first


def test_new_removed_and_missing_files_are_changes(tmp_path: Path) -> None:
    folder, rules = _folder(tmp_path)
    first = fingerprint(folder, [rules])
    (folder / "quiz.yaml").write_text("name: quiz\n")
    with_quiz = fingerprint(folder, [rules])
    assert with_quiz != first
    rules.unlink()
    gone = fingerprint(folder, [rules])
    assert gone != with_quiz and gone[-1] == (str(rules), -1, -1, -1)
    assert fingerprint(None, [rules]) == ((str(rules), -1, -1, -1),)
    assert fingerprint(tmp_path / "no such folder", []) == ()


def test_a_change_asks_for_one_reload_once_it_holds_still(tmp_path: Path) -> None:
    folder, rules = _folder(tmp_path)
    asked: list[int] = []
    watch = FileWatch(folder, [rules], lambda: asked.append(1), period_s=60.0)
    assert not watch.poll() and asked == []

    (folder / "jokes.yaml").write_text("name: jokes\nhalf")
    assert not watch.poll()  # seen once: it may still be written
    (folder / "jokes.yaml").write_text("name: jokes\nhalf and the rest\n")
    assert not watch.poll()  # it changed again: wait once more
    assert watch.poll() and asked == [1]  # held still: one reload
    assert not watch.poll() and not watch.poll() and asked == [1]


def test_a_change_a_reload_already_read_is_not_reloaded_again(tmp_path: Path) -> None:
    folder, rules = _folder(tmp_path)
    asked: list[int] = []
    watch = FileWatch(folder, [rules], lambda: asked.append(1), period_s=60.0)
    rules.write_text('component C [ activate "news" ]\n')
    assert not watch.poll()
    watch.mark()  # a SIGHUP's reload reads the files as they are now
    assert not watch.poll() and not watch.poll()
    assert asked == []


def test_the_thread_polls_and_stops_at_once(tmp_path: Path) -> None:
    folder, rules = _folder(tmp_path)
    asked = threading.Event()
    watch = FileWatch(folder, [rules], asked.set, period_s=0.02)
    watch.start()
    try:
        (folder / "jokes.yaml").write_text("name: jokes\nnew\n")
        assert asked.wait(10)
    finally:
        started = time.monotonic()
        watch.stop()
    assert time.monotonic() - started < 0.5
    assert not any(t.name == "dms-watch" and t.is_alive() for t in threading.enumerate())


def test_a_long_period_does_not_hold_the_stop(tmp_path: Path) -> None:
    folder, rules = _folder(tmp_path)
    watch = FileWatch(folder, [rules], lambda: None, period_s=3600.0)
    watch.start()
    started = time.monotonic()
    watch.stop()
    assert time.monotonic() - started < 0.5


def test_it_is_off_at_zero_or_with_nothing_to_watch(tmp_path: Path) -> None:
    folder, rules = _folder(tmp_path)
    assert FileWatch(folder, [rules], lambda: None, period_s=1.0).on
    assert FileWatch(None, [rules], lambda: None, period_s=1.0).on
    assert not FileWatch(folder, [rules], lambda: None, period_s=0.0).on
    idle = FileWatch(None, [], lambda: None, period_s=1.0)
    assert not idle.on
    idle.start()
    idle.mark()
    idle.stop()
    assert not any(t.name == "dms-watch" and t.is_alive() for t in threading.enumerate())
