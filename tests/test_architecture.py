"""The floors of docs/architecture.md hold: import-linter's contract, and no import cycles.

The contract (``[tool.importlinter]`` in pyproject.toml) says which package may import
which; these tests fail when an import breaks it, when a module of ``dms/`` is on no
floor (it would escape the contract), or when two files import each other.
"""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

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
