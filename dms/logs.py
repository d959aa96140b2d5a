"""The daemon's log: a level and a format (text or JSON lines) on stderr.

Every record may carry structured fields, given as ``extra={...}`` to the logging call
(``log.warning("missed ticks", extra={"missed": 3})``); the text format appends them
as ``name=value``, the JSON format as keys of the line's object. A filter adds the
robot's id to every record, so that the lines of several daemons can be told apart.
"""

from __future__ import annotations

import json
import logging
import sys
from datetime import UTC, datetime
from enum import StrEnum
from typing import IO, Any


class LogLevel(StrEnum):
    """``--log-level``: the least severe record that is written."""

    debug = "debug"
    info = "info"
    warning = "warning"
    error = "error"


class LogFormat(StrEnum):
    """``--log-format``: a line of text, or one JSON object a line."""

    text = "text"
    json = "json"


_STANDARD = frozenset(vars(logging.LogRecord("", 0, "", 0, "", None, None))) | {
    "message",
    "asctime",
    "taskName",
}
"""The attributes every record has; any other attribute is a structured field."""


def fields(record: logging.LogRecord) -> dict[str, Any]:
    """The structured fields of ``record`` (what ``extra=`` added), in insertion order."""
    return {k: v for k, v in vars(record).items() if k not in _STANDARD and not k.startswith("_")}


def _time(record: logging.LogRecord) -> str:
    t = datetime.fromtimestamp(record.created, UTC)
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


class TextFormatter(logging.Formatter):
    """``2026-11-24T14:20:31.123Z INFO dms.daemon: message name=value ...``"""

    def format(self, record: logging.LogRecord) -> str:
        extra = " ".join(f"{k}={_text(v)}" for k, v in fields(record).items())
        line = f"{_time(record)} {record.levelname} {record.name}: {record.getMessage()}"
        line = f"{line} {extra}" if extra else line
        if record.exc_info:
            line = f"{line}\n{self.formatException(record.exc_info)}"
        return line


def _text(value: Any) -> str:
    text = str(value)
    return json.dumps(text) if not text or any(c.isspace() or c == '"' for c in text) else text


class JsonFormatter(logging.Formatter):
    """One JSON object a line: ``time``, ``level``, ``logger``, ``message``, the
    structured fields, and ``exception`` (the traceback) when there is one."""

    def format(self, record: logging.LogRecord) -> str:
        line: dict[str, Any] = {
            "time": _time(record),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        for key, value in fields(record).items():
            line.setdefault(key, value)
        if record.exc_info:
            line["exception"] = self.formatException(record.exc_info)
        return json.dumps(line, default=str, ensure_ascii=False)


OWN_PACKAGES = frozenset({"dms", "memory", "agenda", "activities", "managers", "motivation", "sim"})
"""Loggers whose info and debug lines are the daemon's own; other libraries' (alembic,
zenoh) are written from WARNING up, at every level: ``--log-level debug`` is for the
daemon's decisions about its inputs, storage and bus, not for its libraries' chatter."""


class _Quiet(logging.Filter):
    """Drops other libraries' records below WARNING (their info is not the daemon's)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno >= logging.WARNING or record.name.split(".", 1)[0] in OWN_PACKAGES


class _Stamp(logging.Filter):
    """Adds fixed fields (the robot id) to every record that does not set them."""

    def __init__(self, stamp: dict[str, Any]) -> None:
        super().__init__()
        self._stamp = stamp

    def filter(self, record: logging.LogRecord) -> bool:
        for key, value in self._stamp.items():
            if not hasattr(record, key):
                setattr(record, key, value)
        return True


def setup_logging(
    level: LogLevel | str = LogLevel.info,
    fmt: LogFormat | str = LogFormat.text,
    stream: IO[str] | None = None,
    **stamp: Any,
) -> logging.Handler:
    """Send the root logger's records at ``level`` and above to ``stream`` (stderr) in
    ``fmt``; ``stamp`` fields (``robot_id="mini"``) go on every record. Replaces any
    handler set before, so that calling it twice does not write each line twice."""
    handler = logging.StreamHandler(stream if stream is not None else sys.stderr)
    handler.setFormatter(JsonFormatter() if LogFormat(fmt) is LogFormat.json else TextFormatter())
    handler.addFilter(_Quiet())
    if stamp:
        handler.addFilter(_Stamp(stamp))
    root = logging.getLogger()
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    wanted = logging.getLevelName(LogLevel(level).value.upper())
    # Other libraries' records below WARNING are not even made (the filter is the guard
    # for a library that sets its own logger's level).
    root.setLevel(max(wanted, logging.WARNING))
    for package in OWN_PACKAGES:
        logging.getLogger(package).setLevel(wanted)
    return handler
