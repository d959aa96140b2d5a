"""The rules of docs/architecture.md hold: the floors, file sizes and wording.

The contract (``[tool.importlinter]`` in pyproject.toml) says which package may import
which; these tests fail when an import breaks it, when a module of ``dms/`` is on no
floor (it would escape the contract), or when two files import each other. They also
fail on a file of the product over 600 lines that does not say why at its top, and on
words that belong to the project's history rather than to its code (work item numbers,
helper names, a diary, files outside the repository) in code, docs and ``--help``.
"""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import typer
from typer.testing import CliRunner

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("dms", "managers", "activities", "motivation", "memory", "agenda", "sim")


def _layers() -> list[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    (contract,) = config["tool"]["importlinter"]["contracts"]
    layers: list[str] = contract["layers"]
    return layers


def _floor_modules() -> set[str]:
    names: set[str] = set()
    for layer in _layers():
        names.update(part.strip() for part in layer.replace("|", ":").split(":"))
    return names


def test_lint_imports_keeps_the_floors() -> None:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert exe is not None, "import-linter is in the dev extra: pip install -e '.[dev]'"
    done = subprocess.run(
        [exe, "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_every_module_of_dms_is_on_a_floor() -> None:
    floors = _floor_modules()
    here = {
        f"dms.{path.stem if path.is_file() else path.name}"
        for path in (ROOT / "dms").iterdir()
        if (path.suffix == ".py" and path.stem != "__init__")
        or (path.is_dir() and (path / "__init__.py").exists())
    }
    assert here - floors == set(), "put the new module on a floor in pyproject.toml"


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """What a file imports of the project; ``from pkg import sub`` imports ``pkg.sub``."""
    name = _module(path)
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1])
                source = f"{base}.{node.module}" if node.module else base
            else:
                source = node.module or ""
            subs = [f"{source}.{alias.name}" for alias in node.names]
            if all(sub in modules for sub in subs):
                found.update(subs)
            else:
                found.add(source)
                found.update(sub for sub in subs if sub in modules)
    return {target for target in found if target in modules and target != name}


def test_no_two_files_import_each_other() -> None:
    files = {_module(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}
    modules = set(files)
    graph = {name: _imports(path, modules) for name, path in files.items()}
    pairs = sorted(
        (a, b) for a, targets in graph.items() for b in targets if a < b and a in graph[b]
    )
    assert pairs == []


def test_the_kernel_imports_only_the_kernel() -> None:
    files = {_module(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}
    modules = set(files) | set(PACKAGES)
    outside = {
        (name, target)
        for name, path in files.items()
        if name.startswith("dms.kernel")
        for target in _imports(path, modules)
        if not target.startswith("dms.kernel")
    }
    assert outside == set()


def _foreign_writes(source: str) -> list[tuple[int, str]]:
    """``x.attr = ...`` (also ``+=``, annotated, in a tuple) where ``x`` is not ``self``:
    a write to another object's field, with its line."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Assign):
            targets = list(node.targets)
        elif isinstance(node, ast.AugAssign | ast.AnnAssign):
            targets = [node.target]
        else:
            continue
        while targets:
            target = targets.pop()
            if isinstance(target, ast.Tuple | ast.List | ast.Starred):
                targets.extend(
                    target.elts if not isinstance(target, ast.Starred) else [target.value]
                )
            elif isinstance(target, ast.Attribute) and not (
                isinstance(target.value, ast.Name) and target.value.id == "self"
            ):
                found.append((target.lineno, ast.unparse(target)))
    return sorted(found)


def test_the_foreign_write_check_sees_what_it_means() -> None:
    source = (
        "self.a = 1\n"
        "self.runner.current = None\n"
        "session.mode, self.b = m, 2\n"
        "self.counters.ticks += 1\n"
        "x: int = 1\n"
    )
    assert _foreign_writes(source) == [
        (2, "self.runner.current"),
        (3, "session.mode"),
        (4, "self.counters.ticks"),
    ]


def test_each_piece_of_the_controllers_state_is_written_by_its_owner() -> None:
    """An object of the controller writes only its own fields: the runner clears the
    activity it ends, the dialogs open and drop their dialogs, a session keeps its own
    record; the others ask them (a method) or receive (a return value, a queue)."""
    writes = [
        f"{path.relative_to(ROOT)}:{line}: {target}"
        for path in sorted((ROOT / "dms" / "controller").glob("*.py"))
        for line, target in _foreign_writes(path.read_text(encoding="utf-8"))
    ]
    assert writes == [], "ask the owner to change its state (a method), do not assign it"


SHARED_OPTIONS = ("--connect", "--zenoh-config", "--robot", "--robot-id", "--db")
"""Options every command spells alike, from dms/kernel/cli_options.py."""
OWN_VARIANTS = {
    "dms/cli.py": "dms run: each flag's help names its setting and variable",
    "dms/viewer/cli.py": "--robot: several robots, every robot by default",
    "dms/foxglove_cli.py": "--robot: '*' for every robot",
    "dms/studio/cli.py": "--connect: no daemon by default, the simulated Mini only",
    "sim/record_cli.py": "play --robot: the recorded robot by default",
}
"""Files that define one of them differently, on purpose, and why."""


def test_shared_options_are_defined_once() -> None:
    spelt = set()
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            name = str(path.relative_to(ROOT))
            if name == "dms/kernel/cli_options.py":
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if (
                    isinstance(node, ast.Call)
                    and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "Option"
                    and any(
                        isinstance(arg, ast.Constant) and arg.value in SHARED_OPTIONS
                        for arg in node.args
                    )
                ):
                    spelt.add(name)
    assert spelt <= set(OWN_VARIANTS), "use the option of dms/kernel/cli_options.py"
    assert set(OWN_VARIANTS) <= spelt, "a variant is gone: drop it from OWN_VARIANTS"


MAX_LINES = 600
REASON = "Over 600 lines: "
REASON_WITHIN = 15  # the reason line sits at the top: a comment or the docstring's start


def _reason_given(lines: list[str]) -> bool:
    return any(line.strip().lstrip("#\"' ").startswith(REASON) for line in lines[:REASON_WITHIN])


def test_a_long_file_says_why_at_its_top() -> None:
    long = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if "migrations" in path.relative_to(ROOT).parts:
                continue
            lines = path.read_text(encoding="utf-8").splitlines()
            if len(lines) > MAX_LINES and not _reason_given(lines):
                long.append(f"{path.relative_to(ROOT)}: {len(lines)} lines")
    assert long == [], f"split these, or say why in a line starting {REASON!r} at the top"


# Words that tell the project's history, not what the code does: they belong in git.
PROCESS_WORDS = re.compile(
    "|".join(
        (
            r"\bissue \d+",
            r"\bseed 00[0-2]\b",
            r"\b00[0-2]_[0-9a-f]{16}\b",
            r"\bhelper-\d+",
            r"\bthe night before\b",
            r"\bafter midnight\b",
            r"(?-i:\b(?:DESIGN|CONTRACT|STYLE)\.md\b)",  # docs/contract.md is ours
        )
    ),
    re.IGNORECASE,
)
THIS_FILE = Path(__file__).resolve()


def _worded_files() -> list[Path]:
    """The code (product, tests, benchmarks), docs, README and deployment files."""
    files = [path for pkg in (*PACKAGES, "tests", "bench") for path in (ROOT / pkg).rglob("*.py")]
    files += sorted((ROOT / "docs").glob("*.md"))
    files.append(ROOT / "README.md")
    files += [path for path in (ROOT / "deploy").rglob("*") if path.is_file()]
    return [path for path in files if path.resolve() != THIS_FILE]


def _process_words(text: str) -> list[str]:
    return sorted({found.group(0) for found in PROCESS_WORDS.finditer(text)})


def test_process_words_patterns_catch_what_they_mean() -> None:
    said = "as issue 14 asks, " + "seed " + "001 " + "says; see DESIGN" + ".md, helper-3"
    assert len(_process_words(said)) == 4
    ours = "the paper's Table 4, seed 0 and --seed 7; one issue at a time; docs/contract.md"
    assert _process_words(ours) == []


def test_code_and_docs_name_no_work_items_helpers_or_outside_files() -> None:
    found = {}
    for path in _worded_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        words = _process_words(text)
        if words:
            found[str(path.relative_to(ROOT))] = words
    assert found == {}, "history belongs in git: name the concept or the paper instead"


def _command_paths(command: object, path: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """``path`` and the paths of every sub-command under it (a group has ``commands``; a
    sub-app imported only when it runs has ``load``)."""
    load = getattr(command, "load", None)
    if callable(load):
        command = load()
    paths = [path]
    commands: dict[str, object] = getattr(command, "commands", {})
    for name, sub in sorted(commands.items()):
        paths += _command_paths(sub, (*path, name))
    return paths


def test_the_command_lines_help_names_no_work_items() -> None:
    from dms.cli import app

    runner = CliRunner()
    paths = _command_paths(typer.main.get_command(app))
    assert len(paths) > 20  # every sub-command, not just the top
    found = {}
    for path in paths:
        result = runner.invoke(app, [*path, "--help"], env={"COLUMNS": "200"})
        assert result.exit_code == 0, (path, result.output)
        words = _process_words(result.output)
        if words:
            found[" ".join(("dms", *path))] = words
    assert found == {}
