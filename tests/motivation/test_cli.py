"""``dms motivation plot|show`` through ``dms.cli.main``: files written, one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dms.cli import main
from motivation import MotivationConfig, load_config

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["motivation", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture
def daemon_toml(tmp_path: Path) -> Path:
    path = tmp_path / "daemon.toml"
    path.write_text(
        'robot_id = "mini"\n'
        'timezone = "Europe/Madrid"\n'
        "[controller]\n"
        "feedback_probability = 0.5\n"
        "[motivation]\n"
        "hysteresis = 5\n"
        "[motivation.drives.rest]\n"
        "threshold = 65\n"
        "[motivation.drives.play]\n"
        "enabled = false\n",
        encoding="utf-8",
    )
    return path


def test_plot_writes_a_png(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "days.png"
    code, stdout, stderr = run(
        capsys, "plot", "--hours", "48", "--out", str(out), "--start", "2026-11-23T08:00"
    )
    assert (code, stderr) == (0, "")
    data = out.read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 10_000
    assert stdout.startswith(f"wrote {out}: ")
    assert "asleep" in stdout


def test_plot_with_a_daemon_file_its_zone_and_an_svg(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, daemon_toml: Path
) -> None:
    out = tmp_path / "days.svg"
    code, stdout, stderr = run(
        capsys,
        "plot",
        "--config",
        str(daemon_toml),
        "--out",
        str(out),
        "--hours",
        "30",
        "--start",
        "2026-03-28T12:00:00+00:00",  # across Madrid's change to summer time
    )
    assert (code, stderr) == (0, "")
    text = out.read_text(encoding="utf-8")
    assert text.startswith("<?xml") and "<svg" in text and len(text) > 10_000
    assert stdout.startswith(f"wrote {out}: ")


def test_plot_of_a_few_seconds(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "short.png"
    code, _, stderr = run(
        capsys, "plot", "--hours", "0.0001", "--out", str(out), "--timezone", "UTC"
    )
    assert (code, stderr) == (0, "")
    assert out.read_bytes().startswith(PNG_MAGIC)


def test_show_prints_the_effective_configuration(
    capsys: pytest.CaptureFixture[str], daemon_toml: Path
) -> None:
    code, stdout, stderr = run(capsys, "show", "--config", str(daemon_toml))
    assert (code, stderr) == (0, "")
    shown = json.loads(stdout)
    assert shown["hysteresis"] == 5
    assert shown["drives"]["rest"]["threshold"] == 65
    assert shown["drives"]["rest"]["rate_per_hour"] == 4.5  # the default kept
    assert shown["drives"]["play"]["enabled"] is False
    assert load_config(shown) == load_config(
        {"hysteresis": 5, "drives": {"rest": {"threshold": 65}, "play": {"enabled": False}}}
    )


def test_show_without_a_file_prints_the_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    code, stdout, _ = run(capsys, "show")
    assert code == 0
    assert load_config(json.loads(stdout)) == MotivationConfig()


def write(tmp_path: Path, text: str) -> str:
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    return str(path)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["plot", "--hours", "0", "--out", "{tmp}/a.png"], "dms: --hours: must be in (0, 1440]"),
        (["plot", "--hours", "-3", "--out", "{tmp}/a.png"], "dms: --hours: must be in (0, 1440]"),
        (["plot", "--out", "{tmp}/missing/a.png"], "dms: --out: {tmp}/missing is not a directory"),
        (["plot", "--out", "{tmp}"], "dms: --out: {tmp}: the name must end in one of"),
        (["plot", "--out", "{tmp}/a.png", "--start", "soon"], "dms: --start: not an ISO date"),
        (["plot", "--out", "{tmp}/a.png", "--timezone", "Mars/Base"], "dms: --timezone: unknown"),
        (["show", "--config", "{tmp}/none.toml"], "dms: {tmp}/none.toml: cannot read"),
        (["show", "--config", "{toml:[motivation}"], "dms: {tmp}/bad.toml: not valid TOML"),
        (
            ["show", "--config", "{toml:[motivation.drives.rest]\nthreshold = 150}"],
            "dms: {tmp}/bad.toml: motivation.drives.rest.threshold: must be in [0, 100] (got 150)",
        ),
        (
            ["show", "--config", "{toml:[motivation.drives.rest]\nbehavior = 'fly'}"],
            "dms: {tmp}/bad.toml: motivation.drives.rest.behavior: unknown behavior 'fly'",
        ),
        (
            ["show", "--config", "{toml:[motivation]\nmood = 1}"],
            "dms: {tmp}/bad.toml: motivation.mood: Extra inputs are not permitted",
        ),
        (["show", "--config", "{toml:motivation = 3}"], "dms: {tmp}/bad.toml: motivation: must be"),
        (
            ["plot", "--out", "{tmp}/a.png", "--config", "{toml:timezone = 'Moon'}"],
            "dms: {tmp}/bad.toml: timezone: unknown time zone 'Moon'",
        ),
    ],
)
def test_bad_input_is_one_line_and_a_failure(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str], expected: str
) -> None:
    def fill(arg: str) -> str:
        if arg.startswith("{toml:"):
            return write(tmp_path, arg.removeprefix("{toml:").removesuffix("}"))
        return arg.replace("{tmp}", str(tmp_path))

    code, stdout, stderr = run(capsys, *[fill(a) for a in args])
    assert code != 0
    assert stdout == ""
    assert stderr.startswith(expected.replace("{tmp}", str(tmp_path)))
    assert stderr.count("\n") == 1 and "Traceback" not in stderr
    assert not (tmp_path / "a.png").exists()


def test_an_unwritable_out_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    target = tmp_path / "taken.png"
    target.mkdir()  # a directory where the file should go: no permissions needed to fail
    code, _, stderr = run(capsys, "plot", "--hours", "1", "--out", str(target))
    assert code == 1
    assert stderr.startswith(f"dms: --out: cannot write {target}: ")
    assert stderr.count("\n") == 1
