"""Putting the parts together: the same controller stack for the daemon and the simulator.

:func:`build_stack` opens the store and the agenda, loads behaviors and rules, builds
the motivation model, the expression arbiter over a robot port and the controller.
The daemon adds Zenoh and a real clock around it; the simulator a virtual clock and
simulated users.
"""

from __future__ import annotations

import logging
import math
import random
import zoneinfo
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field
from datetime import datetime
from typing import TYPE_CHECKING, Any

from activities import BehaviorError, BehaviorLibrary, decision_warnings
from dms.config import Settings
from dms.controller import Controller, ControllerDeps
from dms.inputs import InputBoard
from dms.kernel.errors import ConfigError
from dms.kernel.expression import ExpressionArbiter
from dms.kernel.messages import RobotCommand
from dms.kernel.ports import JointReporter, RobotPort
from dms.scene import Scene
from motivation import MotivationConfigError, MotivationModel, load_config

if TYPE_CHECKING:
    from agenda import Agenda
    from dms.interactions import InteractionLog
    from dms.profiles import ProfileService
    from dms.rules import LiveRules
    from memory import ActivityChooser, ProfileStore, QuestionBank

log = logging.getLogger(__name__)

AGENDA_POLL_S = 10.0
"""How often a robot's agenda looks for items added elsewhere (another robot, the CLI):
the agenda's own default (``agenda.service.POLL_S``), written here so that this module
does not import the agenda, which the daemon loads after it is ready."""
WRITER_BUSY_TIMEOUT_S = 1.0
"""SQLite lock wait of the daemon's store writer: past it the writes are spooled."""
TRAINING_STOP_WAIT_S = 10.0
"""How long closing waits for a retraining under way (it reads the store being closed)."""


@dataclass
class Memory:
    """The store, the agenda and what the controller reads from them."""

    store: ProfileStore
    profiles: ProfileService
    chooser: ActivityChooser
    questions: QuestionBank
    agenda: Agenda


@dataclass
class Stack:
    """A ready controller and the parts it holds, to close in order."""

    controller: Controller
    inputs: InputBoard
    expression: ExpressionArbiter
    store: ProfileStore | None
    agenda: Agenda | None
    rules: LiveRules | None
    library: BehaviorLibrary
    warnings: list[tuple[str, str]] = field(default_factory=list)
    """``(key, line)`` found while loading, for ``dms/errors`` once the bus is open."""
    chooser: ActivityChooser | None = None
    train_when_ready: bool = False
    """The chooser has an untrained model until :meth:`when_ready` trains it from the store."""
    open_when_ready: Callable[[], Memory] | None = None
    """Opens the store and the agenda in :meth:`when_ready` (the daemon: after ready)."""

    def attach(self, memory: Memory) -> None:
        """Give the controller its store, agenda, chooser and questions."""
        self.store, self.agenda, self.chooser = memory.store, memory.agenda, memory.chooser
        deps = self.controller.deps
        deps.profiles, deps.agenda = memory.profiles, memory.agenda
        deps.chooser, deps.questions = memory.chooser, memory.questions
        deps.interactions = interaction_log(
            memory.profiles, self.controller.settings.min_speech_confidence
        )

    def when_ready(self, lock: AbstractContextManager[Any] | None = None) -> None:
        """Once the daemon is ready (``alive/dms`` declared), the work that can wait.

        First the store and the agenda, when :func:`build_stack` left them for now: their
        database layer is a third of what ``dms run`` imports. They are attached under
        ``lock`` (the daemon's, which its queries take). Until then the controller runs as
        without a memory; the daemon's ready tick comes before any input is heard, and its
        next tick after this. Raises ConfigError (one line) when either cannot be opened.

        Then the preference model is trained from the seed personas and the store in a
        background thread; the chooser swaps it in when done (tens of milliseconds
        later). Until then the chooser's beliefs start flat, as for a user of unknown
        features, so a restarted daemon is back at once.
        """
        if self.open_when_ready is not None:
            memory = self.open_when_ready()
            self.open_when_ready = None
            with lock or nullcontext():
                self.attach(memory)
        if self.train_when_ready and self.chooser is not None:
            self.train_when_ready = False
            self.chooser.retrain()

    def close(self) -> None:
        # A retraining under way reads the store and runs native code (LAPACK): it ends
        # before the store closes and before the interpreter is torn down around it.
        if self.chooser is not None and not self.chooser.wait_retrained(TRAINING_STOP_WAIT_S):
            log.warning(
                "closing while the preference model still trains (past %.0f s)",
                TRAINING_STOP_WAIT_S,
            )
        # The profile writes first: what cannot be written is spooled and reported.
        profiles = self.controller.deps.profiles
        if profiles is not None:
            profiles.close()
        if self.store is not None:
            self.store.close()
        if self.agenda is not None:
            close = getattr(self.agenda, "close", None)
            if close is not None:
                close()


def interaction_log(profiles: ProfileService, min_confidence: float) -> InteractionLog:
    """The sessions' interaction events, written through the profile store's writer
    (each write once, by its id, also when replayed from the spool)."""
    from dms.interactions import InteractionLog

    return InteractionLog(
        profiles.record_interactions, min_confidence, whole_sessions=not profiles.writer.threaded
    )


def zone_of(timezone: str) -> zoneinfo.ZoneInfo:
    """The robot's time zone; its wall clock drives the circadian rhythm and ``params.env.time``."""
    try:
        return zoneinfo.ZoneInfo(timezone)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ConfigError(f"timezone: unknown time zone {timezone!r}") from None


def hour_in(timezone: str) -> Callable[[datetime], int]:
    """The hour of day in ``timezone``, for ``params.env.time``."""
    zone = zone_of(timezone)
    return lambda t: t.astimezone(zone).hour


def build_stack(
    settings: Settings,
    robot: RobotPort,
    on_command: Callable[[RobotCommand], None],
    report_error: Callable[[str, str], None],
    rng: random.Random | None = None,
    with_memory: bool = True,
    robot_state: Callable[[], dict[str, Any]] = dict,
    retrain: bool = True,
    background_io: bool = True,
    agenda_poll_s: float | None = AGENDA_POLL_S,
    memory_when_ready: bool = False,
) -> Stack:
    """Open everything ``settings`` names; raise DmsError with one line if anything is wrong.

    ``retrain=False`` trains the preference model here, once, and keeps it (the simulator:
    retraining runs in a thread, and a seeded run must not depend on thread timing).
    With ``retrain=True`` (the daemon) the chooser starts untrained and
    :meth:`Stack.when_ready` trains from the seed and the store in the background.
    ``agenda_poll_s``: how often the agenda looks for items added elsewhere (None: never,
    for a database nobody else writes, such as a simulation's own).
    ``background_io=False`` runs the store's and the agenda's database work inline, not on
    their threads (the simulator, for the same reason).
    ``memory_when_ready=True`` checks the database now (:func:`check_database`) and leaves
    opening the store and the agenda to :meth:`Stack.when_ready` (the daemon: their ORM
    is not imported before it is ready).
    """
    rng = rng or random.Random(settings.seed)
    try:
        library = BehaviorLibrary.load(settings.behaviors.folder)
    except BehaviorError as error:
        raise ConfigError(f"behaviors: {error}") from None
    # the shipped activities and those the folder declares, in force before the
    # motivation's drives name their behaviors (a declared relax activity may be one)
    library.install_catalogue()
    try:
        motivation = MotivationModel(load_config(settings.motivation), zone_of(settings.timezone))
    except MotivationConfigError as error:
        raise ConfigError(str(error)) from None
    hour = hour_in(settings.timezone)
    rules: LiveRules | None = None
    if settings.rules.files:
        # The rules language (its parser) loads only for a robot that has rules files.
        from dms.rules import LiveRules, RulesError

        try:
            rules = LiveRules(settings.rules.files)
        except RulesError as error:
            raise ConfigError(f"rules: {error}") from None
    warnings = [("behaviors", line) for line in decision_warnings(library, rules)]
    expression = ExpressionArbiter(
        robot,
        on_command,
        ack_timeout_s=settings.controller.ack_timeout_s,
        done_timeout_s=settings.controller.done_timeout_s,
        offline_after_unacked=settings.controller.offline_after_unacked,
    )
    inputs = InputBoard(settings.inputs.stale_after_s, settings.inputs.max_param_names)
    deps = ControllerDeps(
        library=library,
        expression=expression,
        motivation=motivation,
        rules=rules,
        report_error=report_error,
        robot_state=robot_state,
        scene=Scene(
            settings.frames.face_live_s,
            settings.frames.object_live_s,
            joints=robot.joints if isinstance(robot, JointReporter) else None,
        ),
    )
    controller = Controller(
        deps, inputs, settings.controller, settings.robot_id, rng, timezone_hour=hour
    )
    stack = Stack(controller, inputs, expression, None, None, rules, library, warnings)
    if not with_memory:
        return stack

    def open_memory() -> Memory:
        return open_store_and_agenda(settings, report_error, retrain, background_io, agenda_poll_s)

    if memory_when_ready:
        check_database(settings.db)
        stack.open_when_ready = open_memory
    else:
        stack.attach(open_memory())
    stack.train_when_ready = retrain
    return stack


def check_database(db: str | None) -> None:
    """Refuse now, in the same words, what opening the store and the agenda would refuse:
    a database that cannot be opened, a schema this dms cannot use, a table missing.

    Reads the schema versions with SQLAlchemy's Core (milliseconds): the daemon says it is
    ready only on a database it can use, and loads the store and the agenda after.
    """
    from sqlalchemy.exc import SQLAlchemyError

    from agenda import AgendaError
    from agenda import migrations as agenda_schema
    from memory import ProfileError
    from memory import migrations as profile_schema
    from memory.db import as_url, default_url
    from memory.errors import one_line

    url = db or default_url()
    try:
        engine, _ = profile_schema.open_checked(as_url(url))
    except ProfileError as error:
        raise ConfigError(f"database {url}: {error}") from None
    try:
        with engine.connect() as connection:
            agenda_schema.needs_tables(connection)
    except AgendaError as error:
        raise ConfigError(f"agenda {url}: {error}") from None
    except SQLAlchemyError as error:
        raise ConfigError(f"database {url}: {one_line(error)}") from None
    finally:
        engine.dispose()


def open_store_and_agenda(
    settings: Settings,
    report_error: Callable[[str, str], None],
    retrain: bool,
    background_io: bool,
    agenda_poll_s: float | None,
) -> Memory:
    """The profile store, its background writer, the chooser and the agenda on
    ``settings.db``; ConfigError (one line) when the database cannot be opened."""
    # Imported here: the daemon opens them after ready (see Stack.when_ready).
    from agenda import Agenda, AgendaError
    from dms.profiles import ProfileService
    from memory import ActivityChooser, PreferenceModel, ProfileError, ProfileStore, QuestionBank
    from memory.db import as_url, default_url, shown_url

    url = settings.db or default_url()
    try:
        store = ProfileStore(url, WRITER_BUSY_TIMEOUT_S if background_io else None)
    except ProfileError as error:
        raise ConfigError(f"database {url}: {error}") from None
    profiles = ProfileService(
        store,
        report_error,
        threaded=background_io,
        owner=settings.robot_id,
        spool_dir=settings.storage.spool_dir,
        memory_bound=settings.storage.memory_bound,
    )
    log.debug(
        "storage: profiles and agenda in %s; writes go through a background writer"
        " (spare spool folder %s, %d writes kept in memory at most)",
        shown_url(as_url(url)),
        settings.storage.spool_dir or "none",
        settings.storage.memory_bound,
    )
    if retrain:
        # Trained after ready (Stack.when_ready): even the seed personas' fit cost
        # the start 20-40 ms.
        chooser = ActivityChooser(
            PreferenceModel.untrained(), store, policy=settings.controller.chooser
        )
    else:  # the simulator: trained here, so that a seeded run never depends on threads
        try:
            model = PreferenceModel.train(store)
        except (ProfileError, ValueError):
            model = PreferenceModel.from_seed()
        chooser = ActivityChooser(
            model, store, retrain_every_s=math.inf, policy=settings.controller.chooser
        )

    def user_exists(user_id: str) -> bool:
        return profiles.met(user_id) or user_id in store.list_ids()

    try:
        agenda = Agenda.open(
            url,
            user_exists=user_exists,
            background=background_io,
            claimer=settings.robot_id,
            poll_s=agenda_poll_s,
            report=report_error,
            spool_dir=settings.storage.spool_dir,
        )
    except AgendaError as error:
        profiles.close()
        store.close()
        raise ConfigError(f"agenda {url}: {error}") from None
    return Memory(store, profiles, chooser, QuestionBank.default(), agenda)
