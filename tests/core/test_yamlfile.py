"""The one YAML loader with line numbers (dms/kernel/yamlfile.py)."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from dms.kernel.yamlfile import (
    MAX_ALIAS_NODES,
    Located,
    line_of_key,
    lines_by_path,
    load_located,
    load_plain,
    plain,
    yaml_error,
)

TEXT = """\
name: s
timeline:
  - {at: 1, say: hello}
  - at: 2
    touch: right_shoulder
"""


def test_every_key_and_item_keeps_its_line() -> None:
    data = load_located(TEXT)
    assert isinstance(data, Located) and line_of_key(data, "timeline") == 2
    lines = lines_by_path(data)
    assert lines[("name",)] == 1
    assert lines[("timeline", 0)] == 3 and lines[("timeline", 0, "say")] == 3
    assert lines[("timeline", 1)] == 4 and lines[("timeline", 1, "touch")] == 5
    assert plain(data) == yaml.safe_load(TEXT)
    assert type(plain(data)["timeline"]) is list


def test_a_key_given_twice_is_an_error_with_its_place() -> None:
    with pytest.raises(yaml.YAMLError) as caught:
        load_located("name: a\nseed: 1\nname: b\n")
    message = yaml_error(caught.value, "x.yaml")
    assert message.startswith("x.yaml:3:1: not valid YAML: duplicate key 'name'"), message


def alias_bomb(levels: int = 9) -> str:
    """Each list holds nine aliases of the previous one: nine to the ninth strings."""
    lines = ["name: bomb", "outcomes: [done]", "userdata:", "  a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    for i in range(1, levels):
        lines.append(f"  a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]")
    lines += ["states:", "  S:", "    wait: {seconds: 1}"]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("load", [load_located, load_plain])
def test_an_alias_bomb_is_refused_before_anything_walks_it(load: Callable[[str], Any]) -> None:
    text = alias_bomb()
    assert len(text) < 600
    started = time.monotonic()
    with pytest.raises(yaml.YAMLError) as caught:
        load(text)
    assert time.monotonic() - started < 1
    message = yaml_error(caught.value, "b.yaml")
    assert message == (
        f"b.yaml:8:7: not valid YAML: aliases written out add more than {MAX_ALIAS_NODES} nodes"
    )


def test_an_alias_inside_the_node_it_names_is_refused() -> None:
    with pytest.raises(yaml.YAMLError) as caught:
        load_located("a: &x [1, *x]\n")
    assert "an alias refers to a node that contains it" in yaml_error(caught.value, "r.yaml")


def test_a_few_aliases_load_and_their_lines_are_walked_once() -> None:
    text = "base: &b {voice: soft, speed: 1}\nfirst: *b\nsecond: *b\n"
    data = load_located(text)
    assert plain(data) == yaml.safe_load(text) == load_plain(text)
    lines = lines_by_path(data)
    assert lines[("base", "voice")] == 1
    # the shared mapping is walked at its first place only; a later use has its key's line
    assert lines[("second",)] == 3 and ("second", "voice") not in lines


def test_dms_behavior_check_refuses_an_alias_bomb_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(alias_bomb())
    started = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "dms.cli", "behavior", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    elapsed = time.monotonic() - started
    assert done.returncode != 0
    out = (done.stdout + done.stderr).strip()
    assert len(out.splitlines()) == 1 and "aliases written out add more than" in out, out
    assert str(path) in out
    assert elapsed < 5, f"took {elapsed:.1f} s"
