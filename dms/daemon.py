"""``dms run``: the controller stack on a real clock, over Zenoh, until a signal.

The loop ticks at 2 Hz against monotonic deadlines and at once when an urgent input
(a touch, a request, a screen choice, speech) arrives. Each tick's decisions are
published on ``dms/decision`` and printed, then the state on ``dms/state``. The
``alive/dms`` token is declared once the daemon has published its first state and hears
its inputs, on a database it has checked; the profile store and the agenda open right
after (their ORM is a third of what it imports), before the next tick, and the
``users/`` and ``agenda/`` queries asked meanwhile wait for them. SIGINT and SIGTERM
stop the running activity and flush the store; the exit code is then 130 after SIGINT
(Ctrl-C, as a shell reports it) and 0 after SIGTERM (a supervisor's stop). SIGHUP
reloads the rules and the behaviors, and so does saving them (:mod:`dms.watch`).

Under systemd (``Type=notify``) it says READY once ``alive/dms`` is declared and feeds
the watchdog from the tick loop (:mod:`dms.notify`). Its log goes to stderr at
``--log-level`` in ``--log-format`` (:mod:`dms.logs`); ticks the loop missed are logged.
"""

from __future__ import annotations

import contextlib
import faulthandler
import gc
import logging
import random
import signal
import threading
import time
from collections import deque
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from types import FrameType
from typing import Any

from activities import BehaviorLibrary, reload_rules_and_behaviors
from dms.assembly import Stack, build_stack
from dms.bus import ZenohBus, make_config
from dms.config import Settings
from dms.console import format_decision
from dms.controller import TickRecord
from dms.inputs import InputRejected, parse_input
from dms.kernel import keys
from dms.kernel.clock import Clock, RealClock, Ticker, WallSteps, describe_step, iso
from dms.kernel.errors import ConfigError, DmsError
from dms.kernel.ids import InvalidIdentifier, check_identifier, printable
from dms.kernel.messages import (
    DmsState,
    ErrorReport,
    Request,
    RobotCommand,
    RobotFeedback,
)
from dms.kernel.ports import JointReporter, RobotPort
from dms.local_bus import InMemoryBus
from dms.logs import setup_logging
from dms.notify import Notifier
from dms.rate_caps import RateCaps
from dms.reloader import Reloader
from dms.robot_link import ZenohRobot
from dms.studio.daemon_try import TRY_KEY, DaemonTry
from dms.watch import FileWatch

log = logging.getLogger(__name__)


QueryHandler = Callable[[str, bytes | None], tuple[bool, Any]]

CONFIG_KEY = "dms/config"
"""The queryable that answers with :func:`config_snapshot` (``dms record`` stores it)."""
DECISIONS_KEY = "dms/decisions"
"""The queryable that answers with the last :data:`RECENT_DECISIONS` decisions (a viewer
opened mid-session shows them)."""
RECENT_DECISIONS = 50
MEMORY_WAIT_S = 5.0
"""How long a ``users/`` or ``agenda/`` query asked right after ready waits for the
store and the agenda to open, before its error reply says to ask again."""

NOT_SERVED = (
    "personal data is not served to other processes: set [privacy] serve_profiles = true"
    " (and secure the bus: dms secure init)"
)


class QueryRefused(DmsError):
    """A query the daemon answers with an error reply saying why (not a fault)."""


def config_snapshot(settings: Settings, library: BehaviorLibrary) -> dict[str, Any]:
    """What a replay needs besides the messages: the seed, the versions, the settings (not
    the database URL, which may hold a password) and the text of the rule, behavior and
    content files in force, named as ``dms record`` stores them (``rules/0/x.dmsl``,
    ``behaviors/quiz.yaml``, ``content/quiz.yaml``: the first content file of a name, in
    the library's search order)."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    files: list[dict[str, Any]] = []

    def add(name: str, path: Path) -> None:
        try:
            files.append({"name": name, "path": str(path), "text": path.read_text("utf-8")})
        except (OSError, UnicodeDecodeError) as error:
            log.warning("dms/config: %s not stored: %s", path, error)

    for index, path in enumerate(settings.rules.files):
        add(f"rules/{index}/{path.name}", path)
    if settings.rules.schema_file is not None:
        add(f"rules/schema/{settings.rules.schema_file.name}", settings.rules.schema_file)
    if library.directory is not None and library.directory.is_dir():
        for path in sorted(library.directory.glob("*.yaml")):
            add(f"behaviors/{path.name}", path)
    seen: set[str] = set()
    for folder in library.content_dirs():
        for path in sorted(folder.glob("*.yaml")) if folder.is_dir() else ():
            if path.name not in seen:
                seen.add(path.name)
                add(f"content/{path.name}", path)
    try:
        dms_version = version("dms")
    except PackageNotFoundError:
        dms_version = "unknown"
    return {
        "robot_id": settings.robot_id,
        "seed": settings.seed,
        "versions": {"dms": dms_version, "python": platform.python_version()},
        "settings": settings.model_dump(mode="json", exclude={"db", "source"}),
        "files": files,
    }


class Daemon:
    """The live daemon: a controller stack, a Zenoh bus and a ticking loop."""

    def __init__(
        self,
        settings: Settings,
        print_decisions: bool = True,
        bus: ZenohBus | InMemoryBus | None = None,
        clock: Clock | None = None,
        sim_robot: Callable[[int], RobotPort] | None = None,
        notifier: Notifier | None = None,
    ) -> None:
        """``sim_robot`` makes the in-process robot from the seed when ``settings.robot`` is
        not ``zenoh``: the composition root (dms/cli.py) passes the simulated Mini.
        ``notifier`` tells systemd (READY, WATCHDOG); by default from ``$NOTIFY_SOCKET``."""
        self.settings = settings
        self.notifier = notifier or Notifier()
        self._missed_logged = 0
        self._said: list[str] = []  # what the robot said this tick, printed after the decisions
        self._recent: deque[dict[str, Any]] = deque(maxlen=RECENT_DECISIONS)
        self.clock: Clock = clock or RealClock()
        self.started = iso(self.clock.now())
        """When this daemon started (the state's ``started``)."""
        self.print_decisions = print_decisions
        self.bus = bus or ZenohBus(
            settings.robot_id,
            make_config(settings.zenoh.listen, settings.zenoh.connect, settings.zenoh.config_file),
        )
        self.ticker = Ticker(self.clock, settings.controller.tick_period_s)
        self.wall_steps = WallSteps()
        """Notices the wall clock being set, to say so once."""
        self._lock = threading.Lock()
        self.rate_caps = RateCaps(settings.inputs.rate_caps())
        self.report_caps = RateCaps(
            settings.inputs.report_caps(), label="report cap", noun="reports"
        )
        """How many rejected messages a second are reported one by one, per key."""
        self.errors_published = 0
        robot: RobotPort
        self.zenoh_robot: ZenohRobot | None = None
        if settings.robot == "zenoh":
            self.zenoh_robot = ZenohRobot(self._publish_command)
            robot = self.zenoh_robot
        elif sim_robot is not None:
            robot = sim_robot(settings.seed or 0)
        else:
            raise ConfigError(f"robot = {settings.robot!r} needs an in-process robot: use dms run")
        self.body: JointReporter | None = robot if isinstance(robot, JointReporter) else None
        """The in-process robot's joints, published on ``robot/joints`` each tick."""
        self.watch = FileWatch(  # made before the files are read: it sees every change
            settings.behaviors.folder,
            settings.rules.files,
            lambda: self.reloader.request(),
            settings.behaviors.watch_s,
        )
        self.stack: Stack = build_stack(
            settings,
            robot,
            on_command=self._publish_command,
            report_error=self.report_error,
            rng=random.Random(settings.seed),
            memory_when_ready=True,
        )
        self._memory_opened = threading.Event()
        """Set once :meth:`start` has opened the store and the agenda (or failed to)."""
        library, rules = self.stack.library, self.stack.rules

        def reload() -> list[tuple[str, str]]:
            self.watch.mark()  # the files this reload reads: the watch lets them be
            return reload_rules_and_behaviors(library, rules)

        self.reloader = Reloader(reload, self.report_error)
        self.trying = DaemonTry(self.stack, self._lock, self.bus.publish, self.clock.now)
        """A behavior tried from the studio (only while nobody is in a session)."""

    # -------------------------------------------------------------- bus callbacks

    def _publish_command(self, command: RobotCommand) -> None:
        self.bus.publish(keys.ROBOT_COMMAND, command.model_dump(mode="json"))
        if self.print_decisions and command.channel == "speech" and command.action == "say":
            said = printable(str(command.args.get("text", "")), 500)
            self._said.append(f"  {self.settings.robot_id} says {said!r}")

    def report_error(self, key: str, error: str) -> None:
        """Publish one problem on ``dms/errors`` (thread-safe)."""
        self.errors_published += 1
        report = ErrorReport(key=key, error=error, time=iso(self.clock.now()))
        log.warning("%s: %s", key, printable(error, 1000))
        self.bus.publish(keys.DMS_ERRORS, report.model_dump(mode="json"))

    def on_input(self, key: str, raw: bytes) -> None:
        """Validate one input (Zenoh thread); wake the loop for urgent ones.

        Over its key's rate cap a message is dropped unread (counted, reported once a
        second by the loop). A ``reload_rules`` request only asks the reloader, which
        serves any number of them with one reload in the background.
        """
        if not self.rate_caps.admit(key, self.clock.monotonic()):
            log.debug("%s: over its rate cap, dropped", key)
            return
        try:
            self._take_input(key, raw)
        except Exception as error:  # a Zenoh callback must never die on one message
            if self.report_caps.admit(key, self.clock.monotonic()):
                log.exception("input on %s", key)
                self.report_error(key, f"not handled: {type(error).__name__}: {error}")

    def _take_input(self, key: str, raw: bytes) -> None:
        try:
            message = parse_input(key, raw)
        except InputRejected as error:
            self.stack.inputs.reject()
            if self.report_caps.admit(key, self.clock.monotonic()):
                self.report_error(key, str(error))
            return
        if isinstance(message, RobotFeedback):
            if self.zenoh_robot is not None:
                self.zenoh_robot.feed(message)
            return
        if isinstance(message, Request) and message.action == "reload_rules":
            log.debug("request: reload asked by %s", message.by or "request")
            self.reloader.request()
            return
        self.stack.inputs.accept(key, message, self.clock.monotonic())
        urgent = key in keys.URGENT_INPUTS
        log.debug("%s accepted%s", key, ": urgent, the tick runs now" if urgent else "")
        if urgent:
            self.ticker.wake()

    def on_liveliness(self, key: str, alive: bool) -> None:
        if key != "dms":
            log.debug("token alive/%s %s", key, "declared" if alive else "gone: input missing")
            self.stack.inputs.liveliness(key, alive)
        if key == keys.ROBOT_FEEDBACK and alive:  # the robot's token: it is reachable again
            self.stack.expression.robot_seen()
            self.ticker.wake()

    def _query_state(self, _key: str, _payload: bytes | None) -> tuple[bool, Any]:
        state = self.stack.controller.state
        if state is None:
            return False, {"error": "no tick yet"}
        return True, self._stamped(state).model_dump(mode="json")

    def _opened(self) -> None:
        """Wait for the store and the agenda, which open right after ready."""
        if not self._memory_opened.wait(MEMORY_WAIT_S):
            raise QueryRefused("the profile store and the agenda are still opening: ask again")

    def _query_users(self, key: str, _payload: bytes | None) -> tuple[bool, Any]:
        user_id = self._personal_subject(key, keys.USERS_PREFIX)
        self._opened()
        store = self.stack.store
        if store is None:
            return False, {"error": "no profile store"}
        if user_id in keys.ALL_USERS:
            return True, {"users": store.list_ids()}
        return True, store.export(user_id)

    def _query_agenda(self, key: str, payload: bytes | None) -> tuple[bool, Any]:
        user_id = self._personal_subject(key, keys.AGENDA_PREFIX)
        self._opened()
        agenda = self.stack.agenda
        if agenda is None:
            return False, {"error": "no agenda"}
        from agenda.zenoh_api import handle_query  # loaded with the agenda, after ready

        # The agenda has its own lock and does its database work off it: holding the
        # daemon's lock here would make the tick wait for the database.
        return handle_query(agenda, user_id, payload, self.clock.now())

    def _personal_subject(self, key: str, prefix: str) -> str:
        """Whose data a ``users/`` or ``agenda/`` query asks for (``*``: everyone's).

        Raises:
            QueryRefused: personal data is not served (``[privacy] serve_profiles``).
            InvalidIdentifier: the key's id breaks the id rule.
        """
        if not self.settings.privacy.serve_profiles:
            raise QueryRefused(NOT_SERVED)
        user_id = key[len(prefix) :]
        return user_id if user_id in keys.ALL_USERS else check_identifier(user_id, "user id")

    def _guarded(self, key: str, handler: QueryHandler) -> QueryHandler:
        """``handler`` that answers every query: an exception becomes an error reply
        (and one line on ``dms/errors``), never silence and never a dead callback."""

        capped = key + "*" if key.endswith("/") else key  # users/* for every users/<id>

        def serve(query_key: str, payload: bytes | None) -> tuple[bool, Any]:
            if not self.rate_caps.admit(capped, self.clock.monotonic()):
                return False, {"error": f"rate cap {self.rate_caps.cap(capped):g}/s: refused"}
            try:
                return handler(query_key, payload)
            except (DmsError, InvalidIdentifier) as refused:  # QueryRefused among them
                return False, {"error": str(refused)}
            except RecursionError:
                return False, {"error": "payload nested too deeply"}
            except Exception as error:
                if self.report_caps.admit(capped, self.clock.monotonic()):
                    log.exception("query %s", query_key)
                    self.report_error(key, f"query failed: {type(error).__name__}: {error}")
                return False, {"error": f"internal error: {type(error).__name__}"}

        return serve

    def _query_decisions(self, _key: str, _payload: bytes | None) -> tuple[bool, Any]:
        # A copy in one C call: the loop appends from its own thread.
        return True, {"decisions": list(self._recent)}

    def _query_config(self, _key: str, _payload: bytes | None) -> tuple[bool, Any]:
        return True, config_snapshot(self.settings, self.stack.library)

    def _query_behavior(self, _key: str, _payload: bytes | None) -> tuple[bool, Any]:
        with self._lock:
            controller = self.stack.controller
            activity = controller.running_activity
            if activity is None:
                return True, {"activity": None}
            return True, {
                "activity": controller.current.name if controller.current else None,
                "structure": activity.structure(),
            }

    # -------------------------------------------------------------- the loop

    def start(self) -> None:
        """Open Zenoh and run the ready tick (before any input is heard, so that it meets
        nobody), then listen, declare ``alive/dms`` and open the store and the agenda."""
        queries: dict[str, QueryHandler] = {
            keys.DMS_STATE: self._query_state,
            keys.USERS_PREFIX: self._query_users,
            keys.AGENDA_PREFIX: self._query_agenda,
            keys.DMS_BEHAVIOR: self._query_behavior,
            CONFIG_KEY: self._query_config,
            DECISIONS_KEY: self._query_decisions,
            TRY_KEY: self.trying.serve,
        }
        self.bus.start({key: self._guarded(key, handler) for key, handler in queries.items()})
        self.reloader.start()
        self.watch.start()
        for key, warning in self.stack.warnings:
            self.report_error(key, warning)
        self._run_tick(urgent=False)
        self.bus.listen(self.on_input, self.on_liveliness)
        log.debug(
            "bus: subscribed to %d input keys and the alive/** tokens under robots/%s/; serving %s",
            len(keys.INPUT_KEYS),
            self.settings.robot_id,
            ", ".join(queries),
        )
        self.bus.declare_alive()
        self.notifier.ready(f"robot {self.settings.robot_id} alive")
        self.notifier.watchdog()
        bus_settings = self.settings.zenoh
        log.info(
            "robot %s ready on %s (alive/dms declared); Ctrl-C stops",
            self.settings.robot_id,
            ", ".join(bus_settings.listen) or f"the endpoints of {bus_settings.config_file}",
            extra={"event": "ready", "listen": bus_settings.listen},
        )
        try:
            # what can wait: the store and the agenda, then the preference model's training
            self.stack.when_ready(self._lock)
        finally:
            self._memory_opened.set()
        agenda = self.stack.agenda
        if agenda is not None:
            for item in agenda.recover(self.clock.now()):
                log.info("agenda item %s fell due while the daemon was down", item.item_id)

    def _run_tick(self, urgent: bool) -> TickRecord | None:
        """One tick, published; a fault the controller's own barrier missed is reported
        and the loop goes on (the state of the last good tick stands)."""
        self._report_drops()
        now, monotonic = self.clock.now(), self.clock.monotonic()
        self._report_wall_step(now, monotonic)
        try:
            with self._lock:
                record = self.stack.controller.tick(now, monotonic, urgent)
                self.trying.tick(now)
        except Exception as error:
            log.exception("tick failed")
            self.report_error("tick", f"{type(error).__name__}: {error}; the loop goes on")
            return None
        self._publish(record)
        return record

    def _report_wall_step(self, now: datetime, monotonic: float) -> None:
        """Say once that the wall clock was set; no decision depends on it (the drives and
        the timeouts run on the monotonic clock, schedules follow the new wall time)."""
        step = self.wall_steps.observe(now, monotonic)
        if step is not None:
            self.report_error(
                "clock",
                f"the wall clock was set {describe_step(step)} (now {iso(now)}); drives and"
                " timeouts go on by the monotonic clock, schedules follow the wall clock",
            )

    def _report_drops(self) -> None:
        """Once a second at most, what the input bounds dropped since the last report:
        one line per key, with counts, however large the flood."""
        monotonic = self.clock.monotonic()
        for key, line in self.rate_caps.due_reports(monotonic):
            self.report_error(key, line)
        for key, line in self.report_caps.due_reports(monotonic):
            self.report_error(key, line)
        for drops in self.bus.ignored_tokens.due(monotonic):
            self.report_error(
                drops.key,
                f"ignored {drops.count} liveliness tokens that name no input, the latest"
                f" {drops.latest} ({drops.total} since start)",
            )
        bound = self.stack.inputs.max_param_names
        for drops in self.stack.inputs.params_dropped.due(monotonic):
            self.report_error(
                drops.key,
                f"more than {bound} names: dropped the {drops.count} set longest ago"
                f" ({drops.total} since start)",
            )

    def _publish(self, record: TickRecord) -> None:
        for decision in record.decisions:
            dump = decision.model_dump(mode="json")
            self.bus.publish(keys.DMS_DECISION, dump)
            self._recent.append(dump)
            if self.print_decisions:
                self._echo(format_decision(decision))
        for line in self._said:
            self._echo(line)
        self._said.clear()
        self.bus.publish(keys.DMS_STATE, self._stamped(record.state).model_dump(mode="json"))
        if self.body is not None:
            now = self.clock.now()
            joints = {"positions": self.body.joints(now), "time": iso(now)}
            self.bus.publish(keys.ROBOT_JOINTS, joints)

    def _stamped(self, state: DmsState) -> DmsState:
        """The controller's state with what only the daemon knows (its reloads, the
        writes not stored yet, when it started)."""
        profiles, agenda = self.stack.controller.deps.profiles, self.stack.agenda
        writers = [profiles.writer.health] if profiles is not None else []
        if agenda is not None:
            writers.append(agenda.health)
        degraded = any(health.status == "degraded" for health in writers)
        return state.model_copy(
            update={
                "reloads": self.reloader.reloads,
                "pending_writes": sum(health.pending for health in writers),
                "storage": "degraded" if degraded else "ok",
                "started": self.started,
            }
        )

    def _echo(self, line: str) -> None:
        """One console line; a closed stdout (``| head``) turns printing off, never the daemon."""
        if not self.print_decisions:
            return
        try:
            print(line, flush=True)
        except (BrokenPipeError, ValueError, OSError):
            self.print_decisions = False

    def loop(self) -> None:
        """Tick until :meth:`stop`; each tick feeds systemd's watchdog (when there is one)
        and logs the ticks missed since the last one (the loop fell behind)."""
        for _timing, urgent in self.ticker:
            self._run_tick(urgent)
            self.notifier.watchdog()
            self._log_missed()

    def _log_missed(self) -> None:
        missed = self.ticker.missed
        if missed == self._missed_logged:
            return
        behind = missed - self._missed_logged
        self._missed_logged = missed
        period = self.settings.controller.tick_period_s
        log.warning(
            "missed %d tick(s): the loop fell %.2f s behind (%d missed since start)",
            behind,
            behind * period,
            missed,
            extra={"event": "missed_ticks", "missed": behind, "missed_total": missed},
        )

    def stop(self) -> None:
        self.ticker.stop()

    def request_reload(self) -> None:
        """SIGHUP: reload the rules and behaviors in the background (coalesced)."""
        self.reloader.request()

    def close(self) -> None:
        """Stop hearing inputs, stop the running activity, flush the store, leave Zenoh;
        the log's last line says when each step ended (seconds into the stop)."""
        started, ends = time.monotonic(), []
        self.notifier.stopping()
        self.bus.stop_listening()  # a flood still coming costs the stop nothing
        self.watch.stop()
        self.reloader.stop()
        ends.append(f"inputs {time.monotonic() - started:.2f} s")
        try:
            with self._lock:
                record = self.stack.controller.shutdown(self.clock.now())
            self._publish(record)
            ends.append(f"activity {time.monotonic() - started:.2f} s")
        finally:
            try:
                self.stack.close()
                ends.append(f"storage {time.monotonic() - started:.2f} s")
            finally:
                self.bus.close()
                self.notifier.close()
                log.info("stopped (%s, bus %.2f s)", ", ".join(ends), time.monotonic() - started)


def run_daemon(
    settings: Settings,
    visitor: str | None = None,
    print_decisions: bool = True,
    *,
    sim_robot: Callable[[int], RobotPort] | None = None,
    start_visitor: Callable[[str, Settings], Callable[[], None]] | None = None,
) -> int:
    """Run until SIGINT/SIGTERM; return the exit code (130 after SIGINT, else 0).

    The composition root (dms/cli.py) passes the simulated robot and the visitor starter,
    so that the daemon does not import ``sim``.
    """
    setup_logging(settings.log_level, settings.log_format, robot_id=settings.robot_id)
    # A crash in native code leaves every thread's Python stack in the log (stderr); a
    # stderr that is no file (captured by a caller in the same process) goes without.
    with contextlib.suppress(OSError, ValueError, RuntimeError):
        faulthandler.enable()
    daemon = Daemon(settings, print_decisions=print_decisions, sim_robot=sim_robot)

    stopped_by: list[int] = []

    def on_stop(signum: int, _frame: FrameType | None) -> None:
        stopped_by.append(signum)
        daemon.stop()

    def on_hup(_signum: int, _frame: FrameType | None) -> None:
        daemon.request_reload()

    signal.signal(signal.SIGINT, on_stop)
    signal.signal(signal.SIGTERM, on_stop)
    signal.signal(signal.SIGHUP, on_hup)
    stop_visitor: Callable[[], None] | None = None
    try:
        daemon.start()
        # Start-up ran without the collector (`dms run`: collecting was 40 ms of wasted
        # start); what it built lives as long as the daemon, so it is frozen out of what
        # a full collection walks (45 ms each: a late tick).
        gc.freeze()
        gc.enable()
        if visitor is not None:
            if start_visitor is None:
                raise ConfigError("--visitor needs the simulator: use dms run")
            stop_visitor = start_visitor(visitor, settings)
        daemon.loop()
    finally:
        if stop_visitor is not None:
            stop_visitor()
        daemon.close()
    return 128 + signal.SIGINT if signal.SIGINT in stopped_by else 0
