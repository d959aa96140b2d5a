"""Waiting: for some seconds, or for a touch, a spoken keyword or a screen choice.

Both keep the time left across a pause, and say what they wait for so that the machine
sleeps (:class:`activities.engine.Wake`).
"""

from __future__ import annotations

from datetime import datetime

from pydantic import (
    Field,
)

from activities.blocks.base import Block, Countdown
from activities.blocks.params import BlockParams
from activities.containers import words
from activities.engine import Event, Status, Wake
from dms.kernel.messages import ScreenChoice, Speech, Touch


class WaitParams(BlockParams):
    seconds: float | None = Field(None, description="How long; null: until cancelled.")


class Wait(Block[WaitParams]):
    NAME = "wait"
    DOC = "Wait some seconds (null: until cancelled); the time left survives a pause."
    PARAMS = WaitParams

    def begin(self, now: datetime) -> None:
        self.countdown = Countdown(now, self.args.seconds)

    def on_pause(self, now: datetime) -> None:
        self.countdown.pause(now)

    def on_resume(self, now: datetime) -> None:
        self.countdown.resume(now)

    def update(self, now: datetime) -> Status:
        if self.countdown.over(now):
            return self.finish("done")
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        if self._preempt_requested or not self.updates_as(Wait):
            return None
        return Wake(self.countdown.deadline)  # ``over`` is ``now >= deadline``


class WaitEventParams(BlockParams):
    touch: list[str] = Field([], description="Touched parts that end the wait.")
    keywords: list[str] = Field([], description="Words or phrases said that end it.")
    screen: list[str] = Field([], description="Screen choices that end it.")
    timeout_s: float | None = Field(None, description="Then the outcome is timeout.")
    key: str | None = Field(None, description="Userdata key that receives what happened.")


class WaitEvent(Block[WaitEventParams]):
    NAME = "wait_event"
    DOC = "Wait for a touch, a spoken keyword or a screen choice (or a timeout)."
    OUTCOMES = ("event", "timeout")
    PARAMS = WaitEventParams

    def begin(self, now: datetime) -> None:
        self.countdown = Countdown(now, self.args.timeout_s)
        self.got: str | None = None

    def on_pause(self, now: datetime) -> None:
        self.countdown.pause(now)

    def on_resume(self, now: datetime) -> None:
        self.countdown.resume(now)

    def on_event(self, event: Event) -> bool:
        if self.got is not None:
            return False
        if isinstance(event, Touch) and event.part in self.args.touch:
            self.got = event.part
        elif isinstance(event, ScreenChoice):
            wanted = {s.lower() for s in self.args.screen}
            if event.choice.strip().lower() in wanted:
                self.got = event.choice
        elif isinstance(event, Speech):
            spoken = words(event.text)
            hit = next((k for k in self.args.keywords if words(k) in spoken), None)
            self.got = hit
        return self.got is not None

    def update(self, now: datetime) -> Status:
        if self.got is not None:
            if self.args.key:
                self.ud[self.args.key] = self.got
            return self.finish("event")
        if self.countdown.over(now):
            return self.finish("timeout")
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        """It waits for its timeout, or for an event it takes (taking one wakes it)."""
        if self._preempt_requested or not self.updates_as(WaitEvent):
            return None
        return Wake(self.countdown.deadline)
