"""Decisions and data: a DMSL component decides, userdata and profiles change, tests."""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from datetime import datetime
from typing import Any

from pydantic import (
    Field,
)

from activities.blocks.base import Block
from activities.blocks.params import BlockParams
from activities.engine import Status
from activities.template import as_text


class DecideParams(BlockParams):
    component: str = Field(description="The DMSL component whose activation decides.")
    outcomes: list[str] = Field(description="The outcomes (activations taken).")
    default: str = Field("random", description="An outcome, or random.")


class Decide(Block[DecideParams]):
    NAME = "decide"
    DOC = (
        "Outcome = the first activation of a DMSL component that is one of `outcomes`; "
        "`default` (an outcome, or `random`) when no rule defines it or it activates none."
    )
    PARAMS = DecideParams

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        outcomes = params.get("outcomes")
        return tuple(str(o) for o in outcomes) if isinstance(outcomes, list) else ()

    def update(self, now: datetime) -> Status:
        outcomes = list(self.outcomes)
        rules = self.rt.ctx.rules
        result = (
            rules.evaluate(self.args.component, self.rt.ctx.params()) if rules is not None else None
        )
        if result is not None:
            for activation in result.activate:
                if activation in outcomes:
                    self.ud["decision"] = activation
                    return self.finish(activation)
        default = self.args.default
        choice = self.rt.ctx.rng.choice(outcomes) if default == "random" else default
        self.ud["decision"] = choice
        return self.finish(choice)


class SetParamParams(BlockParams):
    name: str = Field(description="The profile parameter.")
    value: Any = Field(description="Its new value.")


class SetParam(Block[SetParamParams]):
    NAME = "set_param"
    DOC = "Store a value in the present user's profile."
    PARAMS = SetParamParams

    def update(self, now: datetime) -> Status:
        # a copy: the value as written is shared by every entry of the state
        self.rt.ctx.set_user_param(self.args.name, copy.deepcopy(self.args.value))
        return self.finish("done")


class SetDataParams(BlockParams):
    values: dict[str, Any] = Field({}, description="Keys set to these values.")
    add: dict[str, Any] = Field({}, description="Numbers added to these keys.")
    append: dict[str, Any] = Field({}, description="Values appended to these lists.")


class SetData(Block[SetDataParams]):
    NAME = "set_data"
    DOC = "Change userdata: `values` sets keys, `add` adds numbers, `append` appends to lists."
    PARAMS = SetDataParams

    def update(self, now: datetime) -> Status:
        # copies: the values as written are shared by every entry of the state
        for key, value in self.args.values.items():
            self.ud[key] = copy.deepcopy(value)
        for key, amount in self.args.add.items():
            current = self.ud.get(key, 0)
            self.ud[key] = _number(current) + _number(amount)
        for key, value in self.args.append.items():
            self.ud[key] = [*list(self.ud.get(key, []) or []), copy.deepcopy(value)]
        return self.finish("done")


def _number(value: Any) -> float | int:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return value
    try:
        return int(str(value))
    except ValueError:
        try:
            return float(str(value))
        except ValueError:
            return 0


class SampleParams(BlockParams):
    items: list[Any] | None = Field(
        None, description="A list, or a placeholder such as {content.quiz.questions}."
    )
    range: list[int] | None = Field(None, description="[first, last] instead of items.")
    count: int | None = Field(None, description="How many; null: all, shuffled.")
    key: str = Field(description="Userdata key that receives the list drawn.")


class Sample(Block[SampleParams]):
    NAME = "sample"
    DOC = "Draw `count` items at random (all, shuffled, when null) into userdata `key`."
    PARAMS = SampleParams

    def update(self, now: datetime) -> Status:
        span = self.args.range
        if span is not None and len(span) == 2:
            pool: list[Any] = list(range(span[0], span[1] + 1))
        else:
            pool = list(self.args.items or [])
        if not pool:
            return self.fail("nothing to draw from")
        count = self.args.count
        count = len(pool) if count is None else max(0, min(count, len(pool)))
        self.ud[self.args.key] = self.rt.ctx.rng.sample(pool, count)
        return self.finish("done")


class CheckParams(BlockParams):
    value: Any = Field(description="What is tested (usually a placeholder).")
    in_: Any = Field(None, alias="in", description="met if value is one of these.")
    all_in: Any = Field(None, description="met if every item of value is one of these.")
    equals: Any = Field(None, description="met if value equals this.")
    at_least: float | None = Field(None, description="met if value is at least this.")


class Check(Block[CheckParams]):
    NAME = "check"
    DOC = "Test userdata: `value` in `in`, all of `value` in `all_in`, equal, or at least."
    OUTCOMES = ("met", "not_met")
    PARAMS = CheckParams

    def update(self, now: datetime) -> Status:
        args = self.args
        value = args.value
        tests: list[Callable[[], bool]] = []
        if args.in_ is not None:
            tests.append(lambda: _norm(value) in [_norm(v) for v in _list(args.in_)])
        if args.all_in is not None:
            among = {_norm(v) for v in _list(args.all_in)}
            tests.append(lambda: all(_norm(v) in among for v in _list(value)))
        if args.equals is not None:
            tests.append(lambda: _norm(value) == _norm(args.equals))
        if args.at_least is not None:
            at_least = args.at_least
            tests.append(lambda: _number(value) >= at_least)
        return self.finish("met" if all(test() for test in tests) else "not_met")


def _list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, list | tuple) else [value]


def _norm(value: Any) -> str:
    return as_text(value).strip().lower()
