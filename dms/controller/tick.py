"""The controller and its tick: the paper's decision loop, one pass at a time.

``Controller.tick(now, monotonic)`` runs the loop once and returns a
:class:`~dms.controller.state.TickRecord`: the decisions taken, with their reasons, and
the state they left. It never reads the clock, never blocks and never touches Zenoh:
the daemon calls it at 2 Hz (and at once on urgent inputs) and publishes the record;
simulations call it on a virtual clock. Each step runs through the fault barrier
(:mod:`dms.faults`): a step that raises is reported and the loop goes on.
"""

from __future__ import annotations

import logging
import random
from collections.abc import Callable, Mapping
from datetime import datetime
from typing import Any

from activities import ActivityContext, reload_rules_and_behaviors
from dms.config import ControllerSettings
from dms.controller.choice import Choice
from dms.controller.decisions import DecisionLog
from dms.controller.deps import ControllerDeps, Counters
from dms.controller.dialogs import Dialogs
from dms.controller.drives import Drives
from dms.controller.events import Events
from dms.controller.requests import Requests
from dms.controller.running import Runner, Running
from dms.controller.sessions import Sessions
from dms.controller.state import TickRecord, UserFacts
from dms.dialog import Dialog
from dms.faults import FaultBarrier
from dms.inputs import InputBoard, InputSnapshot
from dms.kernel.activity_names import ManagerName
from dms.kernel.messages import DmsState, Mode
from managers import Manager

log = logging.getLogger(__name__)


class Controller:
    """The decision loop over managers, activities, motivation, memory and agenda."""

    def __init__(
        self,
        deps: ControllerDeps,
        inputs: InputBoard,
        settings: ControllerSettings | None = None,
        robot_id: str = "mini",
        rng: random.Random | None = None,
        timezone_hour: Callable[[datetime], int] = lambda t: t.hour,
    ) -> None:
        self.deps = deps
        self.inputs = inputs
        self.settings = settings = settings or ControllerSettings()
        self.robot_id = robot_id
        self.rng = rng = rng or random.Random()
        self._hour = timezone_hour
        self.counters = counters = Counters()
        self._tick = 0
        self._now: datetime | None = None
        self._last: TickRecord | None = None
        self._barrier = FaultBarrier(
            deps.report_error, clock=lambda: self._now.timestamp() if self._now else 0.0
        )
        self.drives = Drives(deps.motivation)
        self.sessions = Sessions(deps, settings, counters)
        self.log = DecisionLog(counters, self.drives, self.sessions.account)
        self.runner = Runner(deps, settings, self.log, counters, self._context)
        self.dialogs = Dialogs(deps.expression, settings, self.log, self.sessions, self.runner)
        requests = Requests()  # the events put requests, the choice takes them
        self.events = Events(
            deps,
            settings,
            counters,
            self._barrier,
            self.sessions,
            self.runner,
            self.dialogs,
            requests,
            self.reload_rules,
        )
        self.choice = Choice(
            deps,
            settings,
            rng,
            self.drives,
            self.sessions,
            self.runner,
            self.dialogs,
            requests,
            self._rule,
        )

    # ------------------------------------------------------------------ the tick

    def tick(self, now: datetime, monotonic: float, urgent: bool = False) -> TickRecord:
        """Run the decision loop once at ``now``: the paper's steps, numbered as the paper
        numbers them, in the order below."""
        # Why not the paper's order (1, 2, ... 9): the user is followed (3, 5) and an answer
        # taken (7) before the cancel reasons (2), so that this very tick acts for the user
        # now in front and on the answer just given, instead of one tick later.
        self._now = now
        self._tick += 1
        self.counters.count_tick()
        self.log.begin(self._tick)
        # Before anything can send a command: its timeouts count on the monotonic clock.
        self.deps.expression.set_monotonic(monotonic)
        barrier, sessions, runner, dialogs, choice = (
            self._barrier,
            self.sessions,
            self.runner,
            self.dialogs,
            self.choice,
        )
        # Step 1. Read the inputs: stale and missing ones are left out (not considered).
        snapshot = self.inputs.take(monotonic)
        sessions.see(snapshot, now, monotonic)
        # Step 1, the urgent inputs first: answers to a dialog or to the running activity,
        # the shoulder's "continue or stop?", requests for an activity by name (queued
        # for step 2's reason (b) or for step 4's and 6's choice).
        self.events.handle(snapshot, now)
        # Step 1, the motivation's half: the drives stepped with what is perceived.
        barrier.run("motivation", sessions.user, self._motivate, snapshot, now, monotonic)
        # Step 1, the robot's half: its feedback, the frames, the robot link.
        barrier.run("robot", None, self._follow_robot, snapshot, now, monotonic)
        if self.deps.profiles is not None:
            barrier.run("memory", None, self.deps.profiles.retry, now)
        # Steps 3 and 5. Is a user ready? A session begins (the profile loaded or created)
        # or ends (what runs for the user who left is cut).
        barrier.run("user", sessions.user, choice.follow_user, now)
        # Step 7 (and 8). The answer to an open dialog: feedback, a general question, or
        # "continue or stop?" (its "stop" is step 2's reason (b)).
        dialog = dialogs.dialog
        if dialog is not None and not barrier.run(
            "dialog", dialog.kind.value, dialogs.advance, now
        ):
            self._drop_dialog(now)
        # Step 2, after a cancel: the cancelled activities' cleanup states run on.
        if runner.cleaning:
            barrier.run("cleanup", None, runner.wind_down, now)
        if dialogs.dialog is None:
            # Step 2 (and 7). An activity runs: the reasons (a) to (c) to cancel it, in the
            # paper's order, then what it did (reason (d): it failed or asked for another;
            # after it ends, maybe the rating is asked). An activity cancelled for (a) to
            # (c) is not followed: whatever it did this tick, the earlier reason decided.
            running = runner.current
            if running is not None and not barrier.run(
                "cancel", running.name, choice.check_cancel_reasons, now
            ):
                self._abandon_current(now, "cancel")
            if (
                running is not None
                and runner.current is running
                and not barrier.run("activity", running.name, choice.follow_activity, now)
            ):
                self._abandon_current(now, "activity")
            # Steps 4, 6 and 8. Nothing runs: the motivation's behavior, or with a user an
            # agenda item, a general question, or an activity chosen by their proactivity.
            if runner.current is None and dialogs.dialog is None:
                barrier.run("choose", sessions.ready_user(), choice.choose, now)
        else:
            # Step 2's reason (c) for a dialog: a due agenda item interrupts the question.
            barrier.run("agenda", sessions.ready_user(), choice.check_agenda_in_dialog, now)
        session = sessions.session
        if session is not None and session.account is not None:
            # Step 9's bookkeeping, after the sends of this tick: SessionAccount.on_tick.
            barrier.run("metrics", None, session.account.on_tick, now, self.deps.expression.pending)
        # Step 9. The record of this pass; the daemon publishes it and ticks again.
        return self._record(now, urgent, snapshot)

    def _motivate(self, snapshot: InputSnapshot, now: datetime, monotonic: float) -> None:
        """Step the motivation model with what the robot perceives and does."""
        running = self.runner.current
        active = running.name if running is not None and not running.paused else None
        self.drives.step(snapshot, self.sessions.user, self.events.touches, active, now, monotonic)

    def _follow_robot(self, snapshot: InputSnapshot, now: datetime, monotonic: float) -> None:
        """Update what the robot's feedback, the frames and the robot link say."""
        steady = self.sessions.steady(now)  # what the robot and the frames measure with
        if self.deps.scene is not None:
            self.deps.scene.update(snapshot.values, snapshot.fresh, steady)
        self.deps.expression.update(steady)
        self.runner.check_robot_link(monotonic)

    def shutdown(self, now: datetime) -> TickRecord:
        """Stop what runs (SIGINT/SIGTERM): cancel the activity and any suspended one."""
        self._now = now
        self.log.begin(self._tick)
        runner, barrier = self.runner, self._barrier
        if self.dialogs.dialog is not None:
            self.dialogs.end(now)
        for running in (runner.current, runner.suspended):
            if running is not None:
                barrier.run(
                    "shutdown", running.name, runner.cancel, running, "shutdown", now, cleanup=False
                )
        runner.clear()
        for manager in runner.managers.values():
            barrier.run("shutdown", manager.name, manager.stop_winding_down, now)
        session = self.sessions.session
        if session is not None:
            barrier.run("shutdown", session.user_id, self.sessions.end, now)
        return self._record(now, urgent=False)

    # ------------------------------------------------------------------ after a fault

    def _drop_dialog(self, now: datetime) -> None:
        """After a fault in the dialog step: close the dialog, silence it, go on (the
        dialog is closed first thing, even if silencing it fails)."""
        self._barrier.run("dialog/close", None, self.dialogs.end, now)
        running = self.runner.current
        if running is not None and running.paused and self.runner.suspended is not running:
            self._barrier.run(
                "dialog/resume",
                running.name,
                self.runner.resume,
                running,
                "confirm_cancel",
                now,
                "the dialog failed",
            )

    def _abandon_current(self, now: datetime, step: str) -> None:
        """After a fault while running or checking the activity: stop it as failed, so
        that what the state says and what the robot does agree again."""
        runner, barrier = self.runner, self._barrier
        running = runner.current
        if running is None:
            return
        runner.forget(running)
        barrier.run(f"{step}/stop", running.name, runner.managers[running.manager].cancel, now)
        barrier.run(
            f"{step}/stop",
            running.name,
            self.deps.expression.interrupt_source,
            f"activity:{running.name}",
            now,
        )
        runner.failed(running, f"{step} step failed", now)
        barrier.run(
            f"{step}/record", running.name, self.sessions.record_activity, running, "failed", now
        )
        if runner.suspended is not None and self.dialogs.dialog is None:
            suspended = runner.restore()
            assert suspended is not None
            barrier.run(
                f"{step}/resume",
                suspended.name,
                runner.resume,
                suspended,
                "activity_error",
                now,
                f"after the {running.name}",
            )

    # ------------------------------------------------------------------ what activities see

    def _context(self, name: str) -> ActivityContext:
        scene = self.deps.scene
        return ActivityContext(
            expression=self.deps.expression,
            source=f"activity:{name}",
            params=self.params,
            rules=self.deps.rules,
            rng=self.rng,
            set_user_param=self._set_user_param,
            frames=scene.frames if scene is not None else None,
            joints=scene.joints if scene is not None else {},
            steady=self.sessions.steady,
        )

    def _set_user_param(self, name: str, value: Any) -> None:
        user_id = self.sessions.user_id
        now = self._now
        if user_id is not None and now is not None:
            self.sessions.write(user_id, lambda p: p.update(user_id, now, **{name: value}))

    def params(self) -> Mapping[str, Mapping[str, Any]]:
        """``params.user``, ``params.robot`` and ``params.env`` for rules and behaviors."""
        profile = self.sessions.profile()
        user: dict[str, Any] = dict(profile.params()) if profile is not None else {}
        if self.sessions.user_id is not None:
            user.setdefault("id", self.sessions.user_id)
        snapshot = self.sessions.snapshot
        robot = {**self.deps.robot_state(), **(snapshot.robot_params if snapshot else {})}
        if self.runner.current is not None:  # what the robot is doing, unless params/robot says
            robot.setdefault("currenttask", self.runner.current.name)
        env: dict[str, Any] = dict(snapshot.env_params) if snapshot else {}
        if self._now is not None:
            env["time"] = self._hour(self._now)
        return {"user": user, "robot": robot, "env": env}

    def _rule(self, component: str) -> Any:
        """Evaluate a rule component; a designer's rule that fails never stops the robot."""
        rules = self.deps.rules
        if rules is None:
            return None
        try:
            return rules.evaluate(component, self.params())
        except Exception as error:
            log.exception("rule %s failed", component)
            self.deps.report_error("rules", f"{component}: {error}")
            return None

    def reload_rules(self) -> None:
        """Reload the rules files and the behaviors; each keeps its old version if the new
        one does not verify. Activities started afterwards use the new behaviors."""
        for key, problem in reload_rules_and_behaviors(self.deps.library, self.deps.rules):
            self.deps.report_error(key, problem)

    # ------------------------------------------------------------------ what the tick leaves

    def _record(
        self, now: datetime, urgent: bool, snapshot: InputSnapshot | None = None
    ) -> TickRecord:
        decisions = tuple(self.log.decisions)
        self.counters.count_recorded(len(decisions))
        self._last = record = self.build_record(now, urgent, decisions)
        interactions, session = self.deps.interactions, self.sessions.session
        if interactions is not None:  # what happened, for the sessions' interaction events
            user, key = (session.user_id, session.session_id) if session else (None, None)
            inputs = [event.message for event in snapshot.events] if snapshot else []
            observe = interactions.observe
            self._barrier.run("interactions", None, observe, now, user, decisions, inputs, key)
        return record

    def build_record(
        self, now: datetime, urgent: bool = False, decisions: tuple[Any, ...] = ()
    ) -> TickRecord:
        """What the controller holds at ``now``, as a record."""
        session, runner = self.sessions.session, self.runner
        user: UserFacts | None = None
        mode: Mode = "motivation"
        if session is not None:
            proactivity = str(getattr(self.sessions.profile(), "proactivity", None) or "unknown")
            ready = self.sessions.ready_user() == session.user_id
            user = UserFacts(session.user_id, ready, proactivity, session.p_user)
            mode = session.mode
        snapshot = self.sessions.snapshot
        return TickRecord(
            tick=self._tick,
            time=now,
            urgent=urgent,
            decisions=decisions,
            robot=self.robot_id,
            mode=mode,
            user=user,
            current=runner.published(runner.current),
            suspended=runner.published(runner.suspended),
            inputs=snapshot.status if snapshot is not None else {},
            robot_link="offline" if self.deps.expression.robot_offline else "ok",
            failing_channel=runner.failing,
            motivation_state=self.drives.state,
            model=self.drives.model,
        )

    def build_state(self, now: datetime) -> DmsState:
        """The DmsState for ``now`` from what the controller holds."""
        return self.build_record(now).state

    @property
    def state(self) -> DmsState | None:
        """The state after the last tick."""
        return self._last.state if self._last is not None else None

    # ------------------------------------------------------------------ for readers outside

    @property
    def managers(self) -> dict[ManagerName, Manager]:
        return self.runner.managers

    @property
    def current(self) -> Running | None:
        """The current activity (running or paused), if any."""
        return self.runner.current

    @property
    def suspended(self) -> Running | None:
        """The activity a reminder paused, if any."""
        return self.runner.suspended

    @property
    def dialog(self) -> Dialog | None:
        """The open dialog, if any."""
        return self.dialogs.dialog

    @property
    def running_activity(self) -> Any:
        """The running activity object (for the behavior queryable), or None."""
        running = self.runner.current
        if running is None:
            return None
        return self.runner.managers[running.manager].activity

    @property
    def faults(self) -> int:
        """Exceptions the fault barrier contained since the start."""
        return len(self._barrier.faults)

    def next_motivated_change(self, now: datetime, horizon_s: float) -> float | None:
        """Seconds from ``now`` to the tick at which, with the inputs as they are, the
        motivated behavior would change; None if not within ``horizon_s`` (for
        simulations that skip the ticks of an empty room)."""
        running = self.runner.current
        active = running.name if running is not None and not running.paused else None
        return self.drives.next_change(now, horizon_s, active, self.settings.tick_period_s)
