"""systemd's notify protocol (``sd_notify``): one datagram to ``$NOTIFY_SOCKET`` a state.

Under ``Type=notify`` systemd waits for ``READY=1`` before it counts the service as
started, and with ``WatchdogSec=`` it restarts a service that has not sent
``WATCHDOG=1`` for that long. The daemon says READY once ``alive/dms`` is declared and
feeds the watchdog from its tick loop, so a loop that hangs is restarted
(deploy/dms.service, docs/configuration.md). Outside systemd (no ``NOTIFY_SOCKET``)
every call does nothing.

The protocol is a few newline-separated ``NAME=VALUE`` lines in one datagram on a
unix socket (an abstract one when the address starts with ``@``); the standard
library's socket is all it needs.
"""

from __future__ import annotations

import logging
import os
import socket
import time
from collections.abc import Callable, Mapping

log = logging.getLogger(__name__)


def _address(value: str) -> str | bytes:
    """``$NOTIFY_SOCKET`` as a socket address: ``@name`` is the abstract ``\\0name``."""
    return "\0" + value[1:] if value.startswith("@") else value


def watchdog_period_s(env: Mapping[str, str]) -> float | None:
    """systemd's watchdog period for this process (``$WATCHDOG_USEC``), or None when
    there is no watchdog or it is meant for another process (``$WATCHDOG_PID``)."""
    usec = env.get("WATCHDOG_USEC", "")
    pid = env.get("WATCHDOG_PID", "")
    if pid and pid != str(os.getpid()):
        return None
    try:
        period = int(usec) / 1_000_000
    except ValueError:
        return None
    return period if period > 0 else None


class Notifier:
    """Sends notify states to systemd; every method is a no-op outside systemd."""

    def __init__(
        self,
        env: Mapping[str, str] | None = None,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        env = os.environ if env is None else env
        raw = env.get("NOTIFY_SOCKET", "")
        self._address: str | bytes | None = _address(raw) if raw else None
        self._socket: socket.socket | None = None
        self._monotonic = monotonic
        period = watchdog_period_s(env) if self._address is not None else None
        self.watchdog_every_s: float | None = period / 4 if period is not None else None
        """How often :meth:`watchdog` actually sends: a quarter of systemd's period, so
        that even sent only on a tick (2 Hz) the gap stays under half of it, as
        ``sd_watchdog_enabled(3)`` advises."""
        self._last_watchdog: float | None = None
        self.sent = 0
        self.failures = 0

    @property
    def enabled(self) -> bool:
        return self._address is not None

    def send(self, **states: str | int) -> bool:
        """Send ``NAME=VALUE`` lines in one datagram; False when there is nowhere to send
        or the socket refused (the first refusal is logged as a warning)."""
        if self._address is None:
            return False
        message = "\n".join(f"{name}={value}" for name, value in states.items())
        try:
            if self._socket is None:
                self._socket = socket.socket(
                    socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC
                )
            self._socket.sendto(message.encode(), self._address)
        except OSError as error:
            self.failures += 1
            level = logging.WARNING if self.failures == 1 else logging.DEBUG  # once, not a tick
            log.log(level, "systemd notify failed: %s", error, extra={"notify": message})
            return False
        self.sent += 1
        return True

    def ready(self, status: str = "") -> bool:
        """``READY=1``: the service has started (with a STATUS line systemctl shows)."""
        states: dict[str, str | int] = {"READY": 1, "MAINPID": os.getpid()}
        if status:
            states["STATUS"] = status
        return self.send(**states)

    def watchdog(self) -> bool:
        """``WATCHDOG=1`` when the watchdog is on and a quarter of its period has passed since
        the last one; call it as often as you like (each tick)."""
        if self.watchdog_every_s is None:
            return False
        now = self._monotonic()
        if self._last_watchdog is not None and now - self._last_watchdog < self.watchdog_every_s:
            return False
        self._last_watchdog = now
        return self.send(WATCHDOG=1)

    def stopping(self) -> bool:
        """``STOPPING=1``: the service is shutting down."""
        return self.send(STOPPING=1)

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None
