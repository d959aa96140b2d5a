"""The bridge: one dms robot's keys on Zenoh, carried out by a Reachy Mini.

It is the daemon's robot (``dms run --robot zenoh``): it executes each ``robot/command``
and answers on ``robot/feedback`` (``started``, then ``done``, ``interrupted`` or
``failed``), publishes the measured head on ``robot/joints`` ten times a second, and
declares ``alive/robot/feedback`` and ``alive/robot/joints`` while Reachy Mini answers.
It also answers the studio's asks to pose the robot by hand (:mod:`dms_reachy.by_hand`).

One control thread (:meth:`Bridge.run`) owns the SDK: every 20 ms it takes the commands
that came, steps the :class:`~dms_reachy.motion.Mixer` and sends the posture. Zenoh's
threads only queue commands and note the daemon's state.

When Reachy Mini's daemon is gone, the bridge withdraws its tokens, reports the
commands that were moving it as ``failed``, and leaves the ones that come meanwhile
unanswered: the daemon times them out (the activity is told), marks the robot offline
after a few, and reports it on ``dms/errors``. The bridge tries again every second; once
Reachy answers, the tokens are back and the daemon at once treats the robot as online.
"""

from __future__ import annotations

import contextlib
import heapq
import json
import math
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime
from typing import Any

import zenoh

from dms_reachy import body, by_hand, commands, faces, gestures
from dms_reachy.commands import Command
from dms_reachy.motion import Mixer
from dms_reachy.robot import Measured, Reachy, RobotGone
from dms_reachy.speech import Voice, words_seconds

CONTROL_PERIOD_S = 0.02
JOINTS_PERIOD_S = 0.1
FACES_PERIOD_S = 0.2
"""How often ``--faces`` publishes ``perception/user`` (a perception module's pace)."""
RETRY_S = 1.0
QUEUE_MAX = 256
"""Commands waiting for the control thread; past it the oldest is dropped (and said)."""
LONGEST_MEDIA_S = 3600.0
LONGEST_GESTURE_S = 60.0
"""A gesture's ``duration_s`` past this (or not a finite number) is not taken."""
DEFAULT_MEDIA_S = 30.0
SLEEP_ACTIVITY = "sleep"
UNKNOWN = "?"
"""The daemon's activity before a state has come (never an activity's name)."""
SETTLE_S = 1.5
"""The longest an aim waits for the measured head to reach its target (a head held back
by a hand, or by the daemon's own limits, is done after this all the same)."""
ARRIVED_RAD = 0.03
APPLY_WAIT_S = 3.0
"""How long an ask to pose by hand waits for the control thread to switch the motors (a
sleeping robot wakes first, which the SDK takes about two seconds over)."""
MOVED_BY_HAND = "the robot is being posed by hand (the studio's Take the robot's pose)"


def log(line: str) -> None:
    print(f"dms reachy: {line}", file=sys.stderr, flush=True)


def iso_now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


class Bridge:
    """The robot ``robot_id`` on ``session``, carried out by ``reachy``."""

    def __init__(
        self,
        robot_id: str,
        session: zenoh.Session,
        reachy: Reachy,
        voice: Voice | None = None,
        clock: Callable[[], float] = time.monotonic,
        publish_faces: bool = False,
    ) -> None:
        """``publish_faces``: publish the face the robot's daemon tracks as ``perception/user``."""
        self.robot_id = robot_id
        self.session = session
        self.reachy = reachy
        self.voice = voice or Voice()
        self.clock = clock
        self.mixer = Mixer()
        self.presence = faces.Presence() if publish_faces else None
        self.connected = False
        self.asleep = False
        self._slept = False
        """True once the daemon's state showed the sleep activity while the robot slept:
        its end (a state that names another activity, or none) then wakes the robot."""
        self._lock = threading.Lock()
        self._queue: deque[Command] = deque()
        self._dropped = 0
        self._activity: str | None = UNKNOWN
        self._timed: list[tuple[float, str]] = []
        self._settling: dict[str, tuple[body.Posture, float]] = {}
        """Aims and poses the plan has reached, until the measured head has too."""
        self._handles: list[Any] = []
        self._tokens: list[Any] = []
        self._told_away = False
        self._lease = by_hand.Lease()
        self._switched = threading.Condition(self._lock)
        self.by_hand = False
        """True while the head's motors are in gravity compensation (the control
        thread's to change, under the lock)."""
        self.stats = {"commands": 0, "feedback": 0, "joints": 0, "connections": 0}

    def key(self, suffix: str) -> str:
        return f"robots/{self.robot_id}/{suffix}"

    # -- Zenoh's threads -------------------------------------------------------------

    def listen(self) -> None:
        self._handles.append(
            self.session.declare_subscriber(self.key("robot/command"), self._on_command)
        )
        self._handles.append(self.session.declare_subscriber(self.key("dms/state"), self._on_state))
        self._handles.append(
            self.session.declare_queryable(self.key(by_hand.KEY), self._on_by_hand)
        )

    def _on_command(self, sample: zenoh.Sample) -> None:
        try:
            command = commands.parse(sample.payload.to_bytes())
        except commands.BadCommand as error:
            log(f"robot/command ignored: {error}")
            return
        with self._lock:  # one lock with _lost: a command is acknowledged only while connected
            if self.connected and command.action != "interrupt":
                # acknowledged here, not by the control thread, which a sleep or a wake
                # holds for seconds: the daemon's ack timeout measures the robot's reach
                self._feedback(command.id, "started")
            self._queue.append(command)
            if len(self._queue) > QUEUE_MAX:
                self._queue.popleft()
                self._dropped += 1

    def _on_by_hand(self, query: zenoh.Query) -> None:
        """An ask to pose by hand: answered once the control thread has switched."""
        try:
            raw = query.payload.to_bytes() if query.payload is not None else None
            ask = by_hand.parse(raw)
        except by_hand.BadAsk as error:
            query.reply_err(json.dumps({"error": str(error)}).encode())
            return
        with self._lock:
            if not self.connected:
                reply: dict[str, Any] = {"error": f"Reachy Mini at {self.reachy.where} unreachable"}
            else:
                self._lease.take(ask, self.clock())
                wanted = self._lease.wanted(self.clock())
                self._switched.wait_for(
                    lambda: self.by_hand == wanted or not self.connected, APPLY_WAIT_S
                )
                if self.by_hand != wanted:
                    reply = {"error": "Reachy Mini did not switch its motors in time; ask again"}
                else:
                    reply = {"by_hand": self.by_hand, "lease_s": self._lease.left(self.clock())}
        if "error" in reply:
            query.reply_err(json.dumps(reply).encode())
        else:
            query.reply(query.key_expr, json.dumps(reply).encode())

    def _on_state(self, sample: zenoh.Sample) -> None:
        try:
            state = json.loads(sample.payload.to_bytes())
        except ValueError:
            return
        activity = state.get("activity") if isinstance(state, dict) else None
        name = activity.get("name") if isinstance(activity, dict) else None
        with self._lock:
            self._activity = name if isinstance(name, str) else None

    # -- the control thread ----------------------------------------------------------

    def run(self, stop: threading.Event) -> None:
        """Drive the robot until ``stop`` is set; returns with the tokens withdrawn."""
        deadline = next_joints = next_faces = self.clock()
        next_try = deadline
        try:
            while not stop.is_set():
                now = self.clock()
                if not self.connected and now >= next_try:
                    self._connect(now)
                    next_try = now + RETRY_S
                if self.connected:
                    try:
                        self._switch_by_hand(now)
                        self._tick(now)
                        if now >= next_joints:
                            next_joints = now + JOINTS_PERIOD_S
                            self._publish_joints()
                        if self.presence is not None and now >= next_faces:
                            next_faces = now + FACES_PERIOD_S
                            self._publish_user(now)
                    except RobotGone as error:
                        self._lost(str(error))
                        next_try = self.clock() + RETRY_S
                else:
                    self._drop_unanswered()
                deadline += CONTROL_PERIOD_S
                if deadline < self.clock():  # late (a blocking sleep or wake): no catch-up
                    deadline = self.clock() + CONTROL_PERIOD_S
                stop.wait(max(0.0, deadline - self.clock()))
        finally:
            if self.by_hand and self.connected:  # never left limp by a bridge that stops
                with contextlib.suppress(RobotGone):
                    self.reachy.gravity_compensation(False)
            self._withdraw_tokens()
            for handle in self._handles:
                handle.undeclare()
            self._handles.clear()
            self.voice.close()

    def _connect(self, now: float) -> None:
        try:
            self.reachy.connect()
            measured = self.reachy.measure()
        except RobotGone as error:
            if not self._told_away:  # said once, not every second
                log(f"Reachy Mini at {self.reachy.where} unreachable ({error}); retrying every 1 s")
                self._told_away = True
            self.reachy.close()
            return
        self._told_away = False
        if self.presence is not None:
            try:
                self.reachy.track_faces()
            except RobotGone as error:
                log(f"face tracking not started ({error}); retrying on the next connection")
                self.reachy.close()
                return
        # antennas folded past what the bridge uses: the robot is in the SDK's sleep pose
        # (its daemon put it to sleep); it stays so until a gesture, an aim or a wake_up
        folded = max(abs(measured.left), abs(measured.right)) > body.ANTENNA
        self.asleep = self._slept = folded
        with self._lock:
            self._activity = UNKNOWN  # until the daemon's next state says
            self.connected = True
            self.mixer.hold(measured.posture(), now)
            self._queue.clear()  # commands from while it was away were never acknowledged
        self._tokens = [
            self.session.liveliness().declare_token(self.key("alive/robot/feedback")),
            self.session.liveliness().declare_token(self.key("alive/robot/joints")),
        ]
        self.stats["connections"] += 1
        log(f"Reachy Mini at {self.reachy.where} reached: carrying robot {self.robot_id}")

    def _lost(self, reason: str) -> None:
        log(f"Reachy Mini at {self.reachy.where} lost ({reason}); retrying every 1 s")
        self._told_away = True
        self._withdraw_tokens()
        with self._lock:
            self.connected = False
            self._lease = by_hand.Lease()
            self.by_hand = False  # the robot's daemon resets its motors on a new client
            self._switched.notify_all()
            running = self.mixer.running() + [command_id for _, command_id in self._timed]
            running += list(self._settling)
            # acknowledged while it was there, not carried out: failed, not left waiting
            running += [c.id for c in self._queue if c.action != "interrupt"]
            self._queue.clear()
            self._timed.clear()
            self._settling.clear()
            self.mixer = Mixer()
        for command_id in running:
            self._feedback(command_id, "failed", f"the Reachy Mini went away ({reason})")
        self.reachy.close()

    def _withdraw_tokens(self) -> None:
        for token in self._tokens:
            token.undeclare()
        self._tokens.clear()

    def _drop_unanswered(self) -> None:
        """Commands that come while Reachy is away are left unanswered (the daemon's
        silent-robot handling); each is logged once."""
        with self._lock:
            waiting = list(self._queue)
            self._queue.clear()
        for command in waiting:
            log(f"{command.channel} {command.action} {command.id}: Reachy Mini unreachable")

    def _tick(self, now: float) -> None:
        with self._lock:
            waiting = list(self._queue)
            self._queue.clear()
            dropped, self._dropped = self._dropped, 0
            activity = self._activity
        if dropped:
            log(f"robot/command: {dropped} commands dropped (more than {QUEUE_MAX} waiting)")
        for command in waiting:
            self.stats["commands"] += 1
            try:
                self._carry_out(command, now)
            except RobotGone:
                raise
            except Exception as error:  # a fault in one command fails it, not the bridge
                log(f"{command.channel} {command.action} {command.id}: {error!r}")
                self._feedback(command.id, "failed", f"the bridge failed: {error}"[:500])
        if self.asleep and activity == SLEEP_ACTIVITY:
            self._slept = True
        elif self.asleep and self._slept and activity is not UNKNOWN and not waiting:
            self._wake(self.clock())  # the sleep activity ended: the robot wakes too
        with self._lock:
            stance_command, target = self.mixer.stance_command, self.mixer.target
            posture, done = self.mixer.step(self.clock())
        if stance_command in done:  # planned there: done once the robot is there too
            done.remove(stance_command)
            self._settling[stance_command] = (target, now + SETTLE_S)
        if self._settling:
            measured = self.reachy.measure()
            for command_id, (there, until) in list(self._settling.items()):
                if _arrived(measured, there) or now >= until:
                    del self._settling[command_id]
                    done.append(command_id)
        while self._timed and self._timed[0][0] <= now:
            done.append(heapq.heappop(self._timed)[1])
        if not self.asleep and not self.by_hand:
            self.reachy.send(posture)
        for command_id in done:
            self._feedback(command_id, "done")

    # -- commands --------------------------------------------------------------------

    def _carry_out(self, command: Command, now: float) -> None:
        if command.action == "interrupt":
            self._interrupt(command.args.get("target"), now)
            return
        handler = {
            "motion": self._motion,
            "aim": self._aim,
            "led": self._led,
            "speech": self._speech,
            "screen": self._screen,
            "media": self._media,
        }[command.channel]
        if self.by_hand and command.channel in ("motion", "aim"):
            self._feedback(command.id, "failed", MOVED_BY_HAND)
            return
        problem = handler(command, now)
        if problem is not None:
            self._feedback(command.id, "failed", problem)

    def _interrupt(self, target: object, now: float) -> None:
        if not isinstance(target, str):
            return
        with self._lock:
            stopped = self.mixer.stop(target, now)
        timed = [item for item in self._timed if item[1] == target]
        if timed:
            self._timed = [item for item in self._timed if item[1] != target]
            heapq.heapify(self._timed)
            self.reachy.stop_sound()
        if stopped or timed:
            self._feedback(target, "interrupted")

    def _motion(self, command: Command, now: float) -> str | None:
        if command.action == "gesture":
            return self._gesture(command, now)
        if command.action == "pose":
            return self._stance(
                command,
                body.from_contract(commands.joints_of(command.args), self.mixer.target),
                now,
            )
        if command.action == "look_at":
            return self._aim(command, now)
        return f"motion {command.action!r}: Reachy Mini knows gesture, pose and look_at"

    def _gesture(self, command: Command, now: float) -> str | None:
        name = str(command.args.get("name", ""))
        if name == "sleep_pose":
            self._sleep(now)
            self._feedback(command.id, "done")
            return None
        if name == "wake_up":
            self._wake(now)
            self._feedback(command.id, "done")
            return None
        keyframes = gestures.GESTURES.get(name)
        if keyframes is None:
            return f"unknown gesture {name!r}"
        if self.asleep:
            self._wake(now)
            now = self.clock()
        seconds = commands.seconds_of(command.args.get("duration_s"), 0.0, LONGEST_GESTURE_S)
        timeline = gestures.scaled(keyframes, seconds or None)
        with self._lock:
            replaced = self.mixer.play(command.id, timeline, now)
        if replaced is not None:
            self._feedback(replaced, "interrupted")
        return None

    def _aim(self, command: Command, now: float) -> str | None:
        joints = commands.joints_of(command.args)
        target = body.from_contract(joints, self.mixer.target)
        position = commands.position_of(command.args)
        if position is not None and command.action in ("look_at", "point_at"):
            yaw, pitch = body.aim_at(*position, body_yaw=target.body_yaw)
            hip = target.body_yaw
            if abs(yaw - hip) > body.YAW_DELTA:  # past what the neck turns: the body too
                hip = yaw - math.copysign(body.YAW_DELTA, yaw - hip)
            target = replace(target, yaw=yaw, pitch=pitch, body_yaw=hip)
        if self.asleep:
            self._wake(now)
            now = self.clock()
        return self._stance(command, target, now)

    def _stance(self, command: Command, target: body.Posture, now: float) -> str | None:
        with self._lock:
            replaced = self.mixer.aim(command.id, target, now)
        if replaced is not None:
            self._feedback(replaced, "interrupted")
        return None

    def _led(self, command: Command, now: float) -> str | None:
        pattern = gestures.pattern_for(command.args.get("color"), command.args.get("pattern"))
        with self._lock:
            self.mixer.light(pattern, now)
        self._feedback(command.id, "done")
        return None

    def _speech(self, command: Command, now: float) -> str | None:
        text = str(command.args.get("text", ""))[:4096]
        rate = command.args.get("rate_wpm")
        seconds = words_seconds(text, rate)
        if self.reachy.media and self.voice.available and text.strip():
            try:
                sound, seconds = self.voice.synthesize(text, rate, command.args.get("language"))
            except OSError as error:
                return f"cannot speak: {error}"
            self.reachy.play(sound)
        else:
            print(f"say: {text}", flush=True)
        heapq.heappush(self._timed, (now + seconds, command.id))
        return None

    def _screen(self, command: Command, now: float) -> str | None:
        # Reachy Mini has no screen: a tablet or a face page shows robot/command itself.
        self._feedback(command.id, "done")
        return None

    def _media(self, command: Command, now: float) -> str | None:
        seconds = commands.seconds_of(
            command.args.get("duration_s"), DEFAULT_MEDIA_S, LONGEST_MEDIA_S
        )
        print(f"media: {command.args.get('title', '')} ({seconds:.0f} s)", flush=True)
        heapq.heappush(self._timed, (now + seconds, command.id))
        return None

    # -- posed by hand -----------------------------------------------------------------

    def _switch_by_hand(self, now: float) -> None:
        """Turn gravity compensation on or off as the lease says. On, what moves the
        robot stops (the hand moves it); off, the robot holds where the hand left it."""
        with self._lock:
            wanted = self._lease.wanted(now)
        if wanted == self.by_hand:
            return
        if wanted:
            self._wake(now)
            with self._lock:
                ended = self.mixer.hold(self.mixer.stance, now)
            for command_id in ended:
                self._feedback(command_id, "interrupted")
        self.reachy.gravity_compensation(wanted)
        if not wanted:
            measured = self.reachy.measure()
            with self._lock:
                self.mixer.hold(measured.posture(), self.clock())
        with self._lock:
            self.by_hand = wanted
            self._switched.notify_all()
        log(f"gravity compensation {'on: posed by hand' if wanted else 'off: holding the pose'}")

    # -- sleep and wake ----------------------------------------------------------------

    def _sleep(self, now: float) -> None:
        """The SDK's own sleep: head down, antennas folded; the control loop then holds
        still (sending nothing) until the robot wakes."""
        if self.asleep:
            return
        with self._lock:
            ended = self.mixer.hold(self.mixer.stance, now)
        for command_id in ended:
            self._feedback(command_id, "interrupted")
        self.reachy.goto_sleep()
        self.asleep, self._slept = True, False
        log("asleep (goto_sleep)")

    def _wake(self, now: float) -> None:
        if not self.asleep:
            return
        self.reachy.wake_up()
        self.asleep = False
        measured = self.reachy.measure()
        with self._lock:
            self.mixer.hold(replace(measured.posture(), z=0.0), self.clock())
        log("awake (wake_up)")

    # -- out -------------------------------------------------------------------------

    def _feedback(self, command_id: str, status: str, detail: str | None = None) -> None:
        self.session.put(
            self.key("robot/feedback"),
            commands.feedback(command_id, status, detail),
            encoding=zenoh.Encoding.APPLICATION_JSON,
        )
        self.stats["feedback"] += 1

    def _publish_joints(self) -> None:
        measured = self.reachy.measure()
        positions = body.to_contract(measured.body_yaw, measured.yaw, measured.pitch)
        self.session.put(
            self.key("robot/joints"),
            json.dumps({"positions": positions, "time": iso_now()}).encode(),
            encoding=zenoh.Encoding.APPLICATION_JSON,
        )
        self.stats["joints"] += 1

    def _publish_user(self, now: float) -> None:
        """``perception/user`` from the face the robot's daemon tracks (``--faces``)."""
        assert self.presence is not None
        found = self.reachy.tracked_face()
        point = faces.face_position(*found, self.reachy.head_pose()) if found else None
        self.session.put(
            self.key("perception/user"),
            json.dumps(self.presence.user(point, now)).encode(),
            encoding=zenoh.Encoding.APPLICATION_JSON,
        )


def _arrived(measured: Measured, target: body.Posture) -> bool:
    """True when the measured body and head are within ``ARRIVED_RAD`` of ``target``."""
    return all(
        abs(getattr(measured, axis) - getattr(target, axis)) <= ARRIVED_RAD
        for axis in ("body_yaw", "yaw", "pitch")
    )
