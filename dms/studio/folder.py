"""The behaviors folder the studio edits: list, open, save, and drafts.

Saving refuses to overwrite a file that changed on disk since it was opened (the page
sends back the hash it got with the open), writes through a temporary file and a
rename (a reader never sees half a file), and writes a behavior that does not load
only as a draft: ``drafts/NAME.draft.yaml`` under the folder, never over the file the
daemon runs. Drafts live in a subfolder because the daemon loads every ``*.yaml`` of
the folder itself and refuses the whole folder when one of them is wrong. The states
placed by hand are kept beside the file (:mod:`dms.studio.placement`), never in it.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from activities.checks import content_shapes
from activities.library import content_dirs
from dms.studio import placement
from dms.studio.check import Report, check_document, folder_specs
from dms.studio.errors import StudioError
from dms.studio.roundtrip import edited_text, load, new_text, to_plain

NAME_RE = re.compile(r"[a-z][a-z0-9_]*")
"""A behavior's name: its file's name, and what the rules and the daemon call it. Matched
whole (``fullmatch``): ``$`` would let a name end in a line break into the file name."""
MAX_NAME = 64
"""The longest name taken: a file system refuses a name of a few hundred bytes, and a
refusal should say so rather than fail on the write."""
DRAFTS = "drafts"


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@dataclass(frozen=True)
class Saved:
    """What a save did: ``saved`` the file, or only a ``draft`` (with the report why)."""

    kind: Literal["saved", "draft"]
    path: Path
    hash: str
    report: Report

    def to_json(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "file": self.path.name,
            "hash": self.hash,
            **self.report.to_json(),
        }


class Folder:
    """A folder of behavior files (and the shipped ones, which a behavior may use)."""

    def __init__(self, directory: Path, shipped: Path) -> None:
        self.directory = directory
        self.shipped = shipped

    def path(self, name: str) -> Path:
        """The file of the behavior ``name``; a name that is not one is a 400."""
        if len(name) > MAX_NAME:
            raise StudioError(
                f"a behavior's name is at most {MAX_NAME} characters: {name[:20]!r}... "
                f"has {len(name)}"
            )
        if not NAME_RE.fullmatch(name):
            raise StudioError(
                f"a behavior's name is a lower-case letter, then lower-case letters, digits "
                f"and _: {name!r}"
            )
        return self.directory / f"{name}.yaml"

    def names(self) -> list[str]:
        return sorted(
            path.stem
            for path in self.directory.glob("*.yaml")
            if len(path.stem) <= MAX_NAME and NAME_RE.fullmatch(path.stem)
        )

    def others(self, name: str) -> dict[str, Any]:
        """The behaviors ``name`` may use as states (the shipped, then this folder's)."""
        specs = folder_specs(self.shipped, self.directory)
        specs.pop(name, None)
        return specs

    def open(self, name: str) -> dict[str, Any]:
        """``{name, doc, hash}``: the document to edit and the hash to send back on save."""
        path = self.path(name)
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            raise StudioError(f"no behavior {name!r} in {self.directory}", 404) from None
        except OSError as error:
            raise StudioError(f"{path.name}: cannot read: {error.strerror or error}", 422) from None
        try:
            doc = to_plain(load(data.decode("utf-8")))
        except Exception as error:  # ruamel's errors share no base but Exception
            raise StudioError(f"{path.name}: not readable YAML: {error}", 422) from None
        if not isinstance(doc, dict):
            raise StudioError(f"{path.name}: not a behavior (a mapping)", 422)
        positions, note = placement.read(path)
        return {
            "name": name,
            "doc": doc,
            "hash": digest(data),
            "layout": placement.to_json(positions),
            "layout_note": note,
        }

    def compare(self, doc: Mapping[str, Any]) -> dict[str, Any]:
        """``{disk, mine, hash}``: the file as it is on disk, what saving ``doc`` over it
        would write, and the file's hash now (to overwrite it knowingly)."""
        path = self.path(str(doc.get("name", "")))
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return {"disk": "", "mine": new_text(doc), "hash": None}
        disk = data.decode("utf-8", errors="replace")
        try:
            mine = edited_text(disk, doc)
        except Exception as error:  # ruamel's errors share no base but Exception
            first = (
                str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
            )
            raise StudioError(f"{path.name}: not readable YAML on disk: {first}", 422) from None
        return {"disk": disk, "mine": mine, "hash": digest(data)}

    def check(self, doc: Mapping[str, Any]) -> Report:
        name = str(doc.get("name", ""))
        content = content_shapes(content_dirs(self.directory))
        return check_document(doc, self.others(name), content)

    def save(
        self,
        doc: Mapping[str, Any],
        opened_hash: str | None,
        positions: placement.Positions | None = None,
    ) -> Saved:
        """Write ``doc`` as its file (its name is the file's), or as a draft if it does
        not load. ``opened_hash``: the file's hash when it was opened, None for a new one.
        ``positions``: the states placed by hand, written beside the file once it is
        saved (None: the sidecar is left as it is)."""
        name = str(doc.get("name", ""))
        path = self.path(name)
        try:
            current: bytes | None = path.read_bytes()
        except FileNotFoundError:
            current = None
        except OSError as error:
            raise StudioError(f"{path.name}: cannot read: {error.strerror or error}", 422) from None
        if current is not None and opened_hash is None:
            raise StudioError(f"{path.name} exists already: open it, or choose another name", 409)
        if current is not None and digest(current) != opened_hash:
            raise StudioError(
                f"{path.name} changed on disk since it was opened: open it again", 409
            )
        if current is None and opened_hash is not None:
            raise StudioError(f"{path.name} was removed since it was opened", 409)
        try:
            original = current.decode("utf-8") if current is not None else None
        except UnicodeDecodeError:
            raise StudioError(f"{path.name}: not UTF-8 text; the file is unchanged", 422) from None
        try:
            text = edited_text(original, doc) if original is not None else new_text(doc)
        except Exception as error:  # ruamel's errors share no base but Exception
            raise StudioError(f"{path.name}: not readable YAML on disk: {error}", 422) from None
        report = self.check(doc)
        try:
            if not report.ok:
                draft = self.directory / DRAFTS / f"{name}.draft.yaml"
                draft.parent.mkdir(exist_ok=True)
                write_atomically(draft, text)
                return Saved("draft", draft, opened_hash or "", report)
            write_atomically(path, text)
            (self.directory / DRAFTS / f"{name}.draft.yaml").unlink(missing_ok=True)
            side = placement.sidecar(path)
            if positions is not None and (positions or side.exists()):
                write_atomically(side, placement.text(positions))
        except OSError as error:
            raise StudioError(f"{path.name}: not saved: {error.strerror or error}", 500) from None
        return Saved("saved", path, digest(text.encode("utf-8")), report)


NEW_FILE_MODE = 0o644


def write_atomically(path: Path, text: str) -> None:
    """Write through a temporary file in the same folder, then rename over (keeping the
    file's permissions)."""
    try:
        mode = path.stat().st_mode & 0o777
    except FileNotFoundError:
        mode = NEW_FILE_MODE
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as out:
            out.write(text)
        os.chmod(temporary, mode)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
