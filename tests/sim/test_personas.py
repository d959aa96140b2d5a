"""Personas: the shipped ones load, and a bad file is reported with file, line and field."""

from __future__ import annotations

from pathlib import Path

import pytest

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from sim.errors import SpecError
from sim.persona import load_persona, shipped_personas


def test_shipped_personas_load_and_differ() -> None:
    names = shipped_personas()
    assert "demo" in names and len(names) >= 6
    personas = [load_persona(name) for name in names]
    assert {p.proactivity for p in personas} == {"low", "moderate", "high"}
    favourites = {p.favourites()[0] for p in personas}
    assert len(favourites) >= 3  # they do not all like the same thing
    for persona in personas:
        assert persona.visits, persona.name
        assert set(persona.favourites()) == set(ENTERTAINMENT_ACTIVITIES)


def test_demo_arrives_quickly() -> None:
    demo = load_persona("demo")
    assert demo.arrive_after_s.max <= 2.0
    assert demo.patience.max_touches == 1


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "p.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "line", "field"),
    [
        ("name: x\nspeech:\n  error_rate: 2\n", 3, "speech.error_rate"),
        ("name: x\npreferences:\n  quiz: 0.5\n  golf: 0.3\n", 4, "preferences.golf"),
        ("name: x\nproactivity: extreme\n", 2, "proactivity"),
        ("name: x\nvisits:\n  - {at: '10:00', minutes: -3}\n", 3, "visits.0.minutes"),
        ("name: x\npatience: {stop_after_s: [9, 3]}\n", 2, "patience.stop_after_s"),
        ("name: Not Valid\n", 1, "name"),
    ],
)
def test_bad_persona_names_file_line_and_field(
    tmp_path: Path, text: str, line: int, field: str
) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(SpecError) as caught:
        load_persona(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: {field}:"), message


def test_broken_yaml_and_missing_file(tmp_path: Path) -> None:
    path = _write(tmp_path, "name: x\nfeatures: {age: 3\n")
    with pytest.raises(SpecError, match=rf"^{path}:\d+:\d+: not valid YAML"):
        load_persona(path)
    with pytest.raises(SpecError, match="cannot read"):
        load_persona(tmp_path / "absent.yaml")
    with pytest.raises(SpecError, match="unknown persona 'nobody'"):
        load_persona("nobody")


def test_visit_time_written_without_quotes_is_a_clock_time(tmp_path: Path) -> None:
    # YAML 1.1 reads 10:30 as the number 630; the persona takes it back as 10:30.
    persona = load_persona(_write(tmp_path, "name: x\nvisits:\n  - {at: 10:30, minutes: 5}\n"))
    assert persona.visits[0].at.hour == 10 and persona.visits[0].at.minute == 30
