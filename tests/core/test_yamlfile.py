"""The one YAML loader with line numbers (dms/kernel/yamlfile.py)."""

from __future__ import annotations

import pytest
import yaml

from dms.kernel.yamlfile import Located, line_of_key, lines_by_path, load_located, plain, yaml_error

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
