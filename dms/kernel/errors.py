"""The root of the daemon's own exceptions.

``DmsError`` is what a command or the daemon reports to a person as one line.
Each package subclasses it (``RulesError``, ``ProfileError``, ``AgendaError``,
``BehaviorError``, ...) and, where the meaning matches, a built-in too
(``ProfileNotFound(ProfileError, KeyError)``). The CLI catches ``DmsError`` and
prints ``dms: <message>`` with a non-zero exit, never a traceback.
"""

from __future__ import annotations


class DmsError(Exception):
    """A problem to report to a person in one line."""


class ConfigError(DmsError, ValueError):
    """A configuration file, flag or value is wrong."""
