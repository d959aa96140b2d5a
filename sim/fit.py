"""``dms sim fit``: the simulated participants' inputs estimated from recorded sessions.

The sessions' interaction events (:mod:`memory.interactions`: ``dms sessions export
--events``, or the daemon's database itself) say when each menu, question and rating
was offered and first answered, by voice or on the screen, what the recogniser made of
each utterance, when the person touched the robot to stop an activity and what they
answered to "continue or stop?". From them, for the inputs of :mod:`sim.calibration`
that :class:`sim.user.SimulatedUser` draws:

- ``answer_delay_s``: the first spoken or tapped input after a general question or
  "continue or stop?", a uniform range fitted to its quartiles (a few late answers, as
  after a retry, do not stretch it as they would its moments);
- ``menu_delay_s``, ``rating_delay_s``: the first input after a menu or a rating is the
  later of an answer delay and the reading time (as the simulated user answers), so
  the reading time's range is the one whose later-of with the fitted answer delay has
  the delays' quartiles;
- ``stop_after_s``: from an activity's start to the touch on the right shoulder (a
  touch that an activity's end came before is never seen: short activities bias it low);
- ``continue_rate``: "continue" among the answers to "continue or stop?";
- ``error_rate``: utterances the recogniser got under the confidence the daemon takes;
- ``no_answer_rate``: questions, ratings and "continue or stop?" left unanswered;
- ``screen_rate``: first answers to menus, ratings and "continue or stop?" tapped;
- ``decline_menu_rate`` (proactivity): menus answered without naming an activity
  ("you choose"), which leaves the choice to the robot;
- ``session_min``: the sessions' length, arrival to departure (reported; the study's
  session length is its protocol's, ``--minutes``).

Each estimate has an interval from a bootstrap over people (everyone's sessions are
resampled together, so a person's habits count once): its percentiles for a range's
bounds and the session length; for a rate, Wilson's score interval on the number of
chances shrunk by the design effect the bootstrap shows (a rate seen rarely or never
would get a point from the percentiles). ``bench/bench_fit.py`` measures how often
the true inputs of simulated people fall inside their intervals.

The participants file (YAML, :func:`write_participants`) holds each input with its
estimate, interval, count and source; ``dms sim study|compare --participants FILE``
draw participants from it (:func:`load_participants`).
"""

from __future__ import annotations

import csv
import math
import random
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from activities.synonyms import match_activity
from sim.calibration import DEFAULT, INPUTS, Calibration
from sim.errors import SpecError

FORMAT = "dms-participants/1"
"""The participants file's ``format`` line."""
BOOTSTRAP = 400
"""Resamples of the people, by default."""
LEVEL = 0.95
"""The intervals' coverage, by default."""
ANSWERED_OFFERS = frozenset({"question", "confirm"})
"""Offers whose first answer is the answer delay alone (nothing to read first)."""
CHOICE_OFFERS = frozenset({"menu", "rating", "confirm"})
"""Offers that always show their choices on the screen."""
DIALOGS = frozenset({"question", "rating", "confirm"})
"""Offers that expire unanswered (a menu is asked again by itself)."""
RANGES = ("answer_delay_s", "menu_delay_s", "rating_delay_s", "stop_after_s")
RATES = ("error_rate", "no_answer_rate", "screen_rate", "continue_rate", "decline_menu_rate")
FITTED: tuple[str, ...] = (*RANGES, *RATES, "session_min")
"""Every input ``dms sim fit`` estimates, in the file's order."""
UNITS = {name: "s" for name in RANGES} | {name: "share" for name in RATES} | {"session_min": "min"}
MAX_ROWS = 2_000_000
"""Events read from one table: beyond it the file is refused (a deployment's years)."""

Estimate = float | tuple[float, float]


@dataclass
class Person:
    """What one person's sessions show, as plain lists of observations."""

    answer: list[float] = field(default_factory=list)
    menu: list[float] = field(default_factory=list)
    rating: list[float] = field(default_factory=list)
    stop_after: list[float] = field(default_factory=list)
    session_min: list[float] = field(default_factory=list)
    counts: dict[str, list[int]] = field(default_factory=lambda: defaultdict(lambda: [0, 0]))
    """Per rate: [events, chances]."""


@dataclass(frozen=True, slots=True)
class Fitted:
    """One input's estimate and its interval (per bound for a range)."""

    name: str
    estimate: Estimate | None
    interval: tuple[tuple[float, float], ...]
    """One (low, high) for a number; two for a range, its min's and its max's."""
    n: int
    source: str

    def covers(self, truth: Estimate) -> list[bool]:
        """Whether each part of ``truth`` lies in its interval."""
        values = truth if isinstance(truth, tuple) else (truth,)
        return [
            low - 1e-9 <= value <= high + 1e-9
            for value, (low, high) in zip(values, self.interval, strict=True)
        ]


# ------------------------------------------------------------------ reading the table


def read_table(path: Path) -> list[dict[str, Any]]:
    """The rows of an exported events table (CSV, ``dms sessions export --events
    --format csv``); SpecError naming what is wrong."""
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle)
            needed = {"session", "user", "t_s", "event", "offer", "offer_kind", "channel"}
            missing = needed - set(reader.fieldnames or ())
            if missing:
                raise SpecError(
                    f"{path}: not an events table (no column {sorted(missing)[0]!r}); "
                    "export one with: dms sessions export --events --format csv"
                )
            rows: list[dict[str, Any]] = []
            for row in reader:
                if len(rows) >= MAX_ROWS:
                    raise SpecError(f"{path}: more than {MAX_ROWS} events; export with --since")
                rows.append({key: (value if value != "" else None) for key, value in row.items()})
            return rows
    except OSError as error:
        raise SpecError(f"{path}: cannot read it ({error.strerror or error})") from None
    except (csv.Error, UnicodeDecodeError) as error:
        raise SpecError(f"{path}: not a CSV table ({error})") from None


def _float(row: Mapping[str, Any], key: str) -> float | None:
    value = row.get(key)
    if value is None:
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SpecError(f"{key}: not a number: {value!r:.40}") from None
    return number if math.isfinite(number) else None


def people(rows: Iterable[Mapping[str, Any]]) -> dict[str, Person]:
    """Each person's observations (by user id), from the events in their order."""
    sessions: dict[tuple[str, str], list[Mapping[str, Any]]] = defaultdict(list)
    for row in rows:
        user, session = row.get("user"), row.get("session")
        if user is None or session is None:
            continue  # an event of no stored session: no times to measure from
        sessions[(str(user), str(session))].append(row)
    out: dict[str, Person] = defaultdict(Person)
    for (user, _session), events in sessions.items():
        _observe(out[user], events)
    return dict(out)


def _observe(person: Person, events: Sequence[Mapping[str, Any]]) -> None:
    """One session's events, in order, into ``person``'s observations."""
    first: dict[str, Mapping[str, Any]] = {}
    kinds: dict[str, str] = {}
    unanswered: set[str] = set()
    started: float | None = None
    touched = False
    counts = person.counts
    for row in events:
        event, t = row.get("event"), _float(row, "t_s")
        offer, channel = row.get("offer"), row.get("channel")
        if event == "offered" and offer is not None:
            kinds[str(offer)] = str(row.get("offer_kind"))
        elif event == "unanswered" and offer is not None:
            unanswered.add(str(offer))
        elif event == "input" and channel == "voice":
            counts["error_rate"][0] += row.get("understood") in (False, "False", "false", "0")
            counts["error_rate"][1] += 1
        if event == "input" and channel in ("voice", "screen") and offer is not None:
            first.setdefault(str(offer), row)
        if event == "started" and row.get("activity") not in ("menu", None):
            started, touched = t, False
        elif event in ("completed", "cancelled", "failed"):
            started = None
        elif (
            event == "input"
            and channel == "touch"
            and row.get("value") == "right_shoulder"
            and started is not None
            and t is not None
            and not touched
        ):
            person.stop_after.append(t - started)
            touched = True
        elif event == "left" and t is not None:
            person.session_min.append(t / 60.0)
    for offer, kind in kinds.items():
        answer = first.get(offer)
        if kind in DIALOGS and (answer is not None or offer in unanswered):
            counts["no_answer_rate"][0] += answer is None
            counts["no_answer_rate"][1] += 1
        if answer is not None:
            _answered(person, kind, answer)


def _answered(person: Person, kind: str, row: Mapping[str, Any]) -> None:
    """The first spoken or tapped input to an offer of ``kind``."""
    counts = person.counts
    delay = _float(row, "delay_s")
    if delay is not None and kind == "menu":
        person.menu.append(delay)
    elif delay is not None and kind == "rating":
        person.rating.append(delay)
    elif delay is not None and kind in ANSWERED_OFFERS:
        person.answer.append(delay)
    if kind in CHOICE_OFFERS:
        counts["screen_rate"][0] += row.get("channel") == "screen"
        counts["screen_rate"][1] += 1
    understood = row.get("understood") not in (False, "False", "false", "0")
    value = str(row.get("value") or "").strip().lower()
    if kind == "confirm" and understood and value in ("continue", "stop"):
        counts["continue_rate"][0] += value == "continue"
        counts["continue_rate"][1] += 1
    if kind == "menu" and understood and value:
        counts["decline_menu_rate"][0] += match_activity(value) is None
        counts["decline_menu_rate"][1] += 1


# ------------------------------------------------------------------ the estimators


QUARTILES = (0.25, 0.75)
"""A range is fitted to the delays' quartiles: a few late answers (a menu asked again
after nobody answered it, a question answered after a retry) would stretch its moments."""


def uniform_range(values: Sequence[float]) -> tuple[float, float] | None:
    """The uniform range with the values' quartiles."""
    if len(values) < 4:
        return None
    low, high = (float(q) for q in np.quantile(values, QUARTILES))
    return max(0.0, 1.5 * low - 0.5 * high), 1.5 * high - 0.5 * low


def _later_quartiles(a: tuple[float, float], r: tuple[float, float]) -> Any:
    """The quartiles of the later of two uniform draws on ``a`` and ``r``."""
    x = np.linspace(0.0, max(a[1], r[1]) + 1e-6, 4001)

    def cdf(span: tuple[float, float]) -> Any:
        low, high = span
        if high - low < 1e-9:
            return (x >= low).astype(float)
        return np.clip((x - low) / (high - low), 0.0, 1.0)

    later = cdf(a) * cdf(r)
    return x[np.minimum(np.searchsorted(later, QUARTILES), len(x) - 1)]


def later_range(
    delays: Sequence[float], answer: tuple[float, float] | None
) -> tuple[float, float] | None:
    """The reading time's uniform range whose later-of with the ``answer`` delay has
    the ``delays``' quartiles (without an answer delay: their own range)."""
    plain = uniform_range(delays)
    if plain is None or answer is None:
        return plain
    from scipy.optimize import least_squares

    seen = np.quantile(delays, QUARTILES)
    scale = max(float(seen[1]), 1e-6)

    def misfit(p: Any) -> Any:
        centre, half = float(p[0]), abs(float(p[1]))
        return (_later_quartiles(answer, (max(0.0, centre - half), centre + half)) - seen) / scale

    start = [(plain[0] + plain[1]) / 2.0, max(0.1, (plain[1] - plain[0]) / 2.0)]
    found = least_squares(misfit, start, bounds=([0.0, 0.0], [np.inf, np.inf]), diff_step=1e-2)
    centre, half = float(found.x[0]), float(found.x[1])
    return max(0.0, centre - half), centre + half


def estimates(group: Sequence[Person]) -> dict[str, Estimate | None]:
    """Every input from the observations of ``group`` (one resample of the people)."""

    def pooled(pick: Callable[[Person], list[float]]) -> list[float]:
        return [value for person in group for value in pick(person)]

    answer = uniform_range(pooled(lambda p: p.answer))
    out: dict[str, Estimate | None] = {
        "answer_delay_s": answer,
        "menu_delay_s": later_range(pooled(lambda p: p.menu), answer),
        "rating_delay_s": later_range(pooled(lambda p: p.rating), answer),
        "stop_after_s": uniform_range(pooled(lambda p: p.stop_after)),
    }
    for name in RATES:
        hits = sum(p.counts[name][0] for p in group)
        chances = sum(p.counts[name][1] for p in group)
        out[name] = hits / chances if chances else None
    lengths = pooled(lambda p: p.session_min)
    out["session_min"] = float(np.mean(lengths)) if lengths else None
    return out


def _count(name: str, group: Sequence[Person]) -> int:
    if name in RATES:
        return sum(p.counts[name][1] for p in group)
    pick = {
        "answer_delay_s": "answer",
        "menu_delay_s": "menu",
        "rating_delay_s": "rating",
        "stop_after_s": "stop_after",
        "session_min": "session_min",
    }[name]
    return sum(len(getattr(p, pick)) for p in group)


SOURCES = {
    "answer_delay_s": "first answer to general questions and 'continue or stop?'",
    "menu_delay_s": "first answer to menus, later of the answer delay and the reading time",
    "rating_delay_s": "first answer to ratings, later of the answer delay and the reading time",
    "stop_after_s": "activity start to the touch on the right shoulder",
    "error_rate": "utterances under the confidence the daemon takes",
    "no_answer_rate": "questions, ratings and 'continue or stop?' left unanswered",
    "screen_rate": "first answers to menus, ratings and 'continue or stop?' tapped",
    "continue_rate": "'continue' among the answers to 'continue or stop?'",
    "decline_menu_rate": "menus answered without naming an activity ('you choose')",
    "session_min": "sessions' length, arrival to departure",
}


def fit(
    persons: Mapping[str, Person],
    *,
    bootstrap: int = BOOTSTRAP,
    level: float = LEVEL,
    seed: int = 0,
    origin: str = "recorded sessions",
) -> list[Fitted]:
    """Each input of :data:`FITTED` with its percentile interval (``level``) from
    ``bootstrap`` resamples of the people; ``origin`` names the data in each source."""
    group = [persons[name] for name in sorted(persons)]
    if not group:
        raise SpecError("no sessions with events to fit: record some, or check --since")
    point = estimates(group)
    rng = random.Random(seed)
    draws: dict[str, list[Estimate]] = defaultdict(list)
    for _ in range(bootstrap):
        resample = [group[rng.randrange(len(group))] for _ in group]
        for name, value in estimates(resample).items():
            if value is not None:
                draws[name].append(value)
    tail = (1.0 - level) / 2.0 * 100.0
    out = []
    for name in FITTED:
        n = _count(name, group)
        value = point[name]
        source = (
            f"fitted by dms sim fit from {origin}: {SOURCES[name]}"
            f" ({n} observations of {len(group)} people)"
        )
        if value is None:
            out.append(Fitted(name, None, (), n, source + "; too few to estimate"))
            continue
        samples = np.array(draws[name], dtype=float)
        if samples.ndim == 1:
            samples = samples[:, None]
        bounds = [
            (float(np.percentile(column, tail)), float(np.percentile(column, 100.0 - tail)))
            for column in samples.T
        ]
        if name in RATES and n:
            bounds = [_wilson(float(value), samples[:, 0], n, level)]  # type: ignore[arg-type]
        out.append(
            Fitted(name, _rounded(value), tuple(_rounded_pair(b) for b in bounds), n, source)
        )
    return out


def _wilson(value: float, draws: Any, n: int, level: float) -> tuple[float, float]:
    """A rate's interval: Wilson's score interval on the effective number of chances
    (``n`` shrunk by the design effect the bootstrap over people shows: one person's
    answers are alike). It stays sound for a rate seen rarely or never, where the
    bootstrap's percentiles collapse to a point."""
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + level / 2.0))
    binomial = value * (1.0 - value) / n
    spread = float(np.var(draws, ddof=1)) if len(draws) > 1 else 0.0
    effective = n / max(1.0, spread / binomial) if binomial > 0 else float(n)
    centre = (value + z * z / (2 * effective)) / (1 + z * z / effective)
    half = (
        z
        / (1 + z * z / effective)
        * math.sqrt(value * (1 - value) / effective + z * z / (4 * effective * effective))
    )
    return max(0.0, centre - half), min(1.0, centre + half)


def _rounded(value: Estimate) -> Estimate:
    if isinstance(value, tuple):
        return round(value[0], 4), round(value[1], 4)
    return round(value, 4)


def _rounded_pair(pair: tuple[float, float]) -> tuple[float, float]:
    return round(pair[0], 4), round(pair[1], 4)


# ------------------------------------------------------------------ the participants file


def entry(item: Fitted) -> dict[str, Any]:
    """One input as the participants file holds it."""
    out: dict[str, Any] = {"unit": UNITS[item.name], "n": item.n, "source": item.source}
    if isinstance(item.estimate, tuple):
        out["estimate"] = list(item.estimate)
        out["interval"] = {"min": list(item.interval[0]), "max": list(item.interval[1])}
    elif item.estimate is not None:
        out["estimate"] = item.estimate
        out["interval"] = list(item.interval[0])
    return out


def write_participants(path: Path, fitted: Sequence[Fitted], persons: int, origin: str) -> None:
    """The participants file: each input with its estimate, interval, count and source."""
    document = {
        "format": FORMAT,
        "people": persons,
        "origin": origin,
        "level": LEVEL,
        "inputs": {item.name: entry(item) for item in fitted},
    }
    try:
        path.write_text(
            yaml.safe_dump(document, sort_keys=False, width=100, default_flow_style=None),
            encoding="utf-8",
        )
    except OSError as error:
        raise SpecError(f"{path}: cannot write it ({error.strerror or error})") from None


def write_events(path: Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """The events table as ``dms sessions export --events --format csv`` writes it."""
    from memory.interactions import COLUMNS

    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(COLUMNS), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if v is None else v for k, v in row.items()})
    return path


def table(fitted: Sequence[Fitted], persons: int) -> str:
    """The estimates as a plain table, one line per input."""
    lines = [f"{'input':<18} {'estimate':>20} {'95 % interval':>34} {'n':>6}"]
    for item in fitted:
        if item.estimate is None:
            lines.append(f"{item.name:<18} {'-':>20} {'too few to estimate':>34} {item.n:>6}")
            continue
        if isinstance(item.estimate, tuple):
            shown = f"{item.estimate[0]:.2f}-{item.estimate[1]:.2f}"
            spans = "  ".join(f"[{low:.2f}, {high:.2f}]" for low, high in item.interval)
        else:
            shown = f"{item.estimate:.3f}"
            spans = f"[{item.interval[0][0]:.3f}, {item.interval[0][1]:.3f}]"
        lines.append(f"{item.name:<18} {shown:>20} {spans:>34} {item.n:>6}")
    lines.append(f"{persons} people; intervals from a bootstrap over people")
    return "\n".join(lines)


def load_participants(path: Path, base: Calibration = DEFAULT) -> tuple[Calibration, list[str]]:
    """``base`` with the estimates of the participants file at ``path``, and the inputs
    it set; SpecError naming the file and what is wrong. Inputs without an estimate keep
    ``base``'s value (and source)."""
    try:
        document = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise SpecError(f"{path}: cannot read it ({error.strerror or error})") from None
    except yaml.YAMLError as error:
        raise SpecError(f"{path}: not YAML ({str(error).splitlines()[0]})") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise SpecError(
            f"{path}: not a participants file (format: {FORMAT}); make one with dms sim fit"
        )
    inputs = document.get("inputs")
    if not isinstance(inputs, dict):
        raise SpecError(f"{path}: inputs: must be a mapping of input names")
    values = dict(base.values)
    used: list[str] = []
    for name, entry in inputs.items():
        if name not in FITTED:
            raise SpecError(
                f"{path}: inputs: unknown input {name!r:.40} (known: {', '.join(FITTED)})"
            )
        if not isinstance(entry, dict) or entry.get("estimate") is None:
            continue
        value = _checked(path, name, entry["estimate"])
        if name == "session_min":
            continue  # the study's session length is its protocol's (--minutes)
        values[name] = value
        used.append(name)
    return Calibration(tuple(values.items())), used


def _checked(path: Path, name: str, raw: Any) -> Estimate:
    """An estimate as the calibration holds it; SpecError when it is not one."""

    def number(value: Any) -> float:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise SpecError(f"{path}: inputs.{name}.estimate: must be a number (got {value!r:.40})")
        if value < 0:
            raise SpecError(f"{path}: inputs.{name}.estimate: must not be negative")
        return float(value)

    if name in RANGES:
        if not isinstance(raw, list) or len(raw) != 2:
            raise SpecError(f"{path}: inputs.{name}.estimate: must be [min, max] in seconds")
        low, high = number(raw[0]), number(raw[1])
        if high < low:
            raise SpecError(f"{path}: inputs.{name}.estimate: max is below min")
        return low, high
    value = number(raw)
    if name in RATES and value > 1.0:
        raise SpecError(f"{path}: inputs.{name}.estimate: a share must be at most 1")
    return value


def truth_of(calibration: Calibration, name: str) -> Estimate | None:
    """The value of input ``name`` that ``calibration`` gives the simulated people."""
    if name == "session_min":
        return None
    if name == "decline_menu_rate":
        return calibration.optional("decline_menu_rate")
    value = calibration[name] if name in INPUTS else None
    if isinstance(value, tuple):
        return float(value[0]), float(value[1])
    return None if value is None else float(value)
