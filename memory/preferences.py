"""Preference prediction by label ranking, and the choice of the next activity.

:class:`PreferenceModel` learns, from users' features and their rankings of the
entertainment activities, to predict a new user's ranking: ranking by pairwise
comparison (one logistic regression per pair of activities, which also learns from
partial rankings; the predicted ranking sorts activities by their summed
probabilities of winning). With no usable features the ranking is random, as in the
paper. :class:`ActivityChooser` holds, per activity, a belief about how much the user
likes it (a distribution over 0..1 on a grid): the prediction is its prior, and the
user's own evidence updates it, each kind for what it says. A rating (the feedback
question) is the liking plus noise; a completion says only that the user did not stop
it, a cancellation that they probably disliked it (neither says how much more), so an
activity completed often but rated low stays low. The ranking is by expected liking;
the choice samples one liking from each belief (Thompson sampling), which tries
activities it knows little about and settles on favorites as evidence comes in.

Only numpy is imported here: the pairwise models are L2-regularized logistic
regressions (scikit-learn's ``LogisticRegression(C=1.0)`` objective) solved by Newton's
method in :func:`fit_logistic`, and features are one-hot encoded as scikit-learn's
``DictVectorizer`` does. Importing scikit-learn cost the daemon 0.6 s of its start and
100 MB of resident memory for 28 problems of a few hundred rows and 23 columns, which
Newton's method solves exactly in a few milliseconds.
"""

from __future__ import annotations

import csv
import itertools
import logging
import random
import threading
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from functools import cache
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from dms.kernel.activity_names import (
    SHIPPED_ENTERTAINMENT,
    ActivityEntry,
    Catalogue,
    current,
)
from memory.profile import ActivityScore, Profile
from memory.seed_data import FEATURE_COLUMNS, SEED_CSV

if TYPE_CHECKING:
    from memory.store import ProfileStore

log = logging.getLogger(__name__)

ACTIVITIES: tuple[str, ...] = SHIPPED_ENTERTAINMENT
"""What the pairwise model ranks: the shipped entertainment activities, those the seed
personas rated. A declared activity's first guess is :func:`first_guess`."""
PAIRS: tuple[tuple[int, int], ...] = tuple(itertools.combinations(range(len(ACTIVITIES)), 2))

Features = Mapping[str, Any]
Liking = Mapping[str, float]
"""A (possibly partial) preference: higher is better liked."""


def encode(features: Features) -> dict[str, float | str]:
    """Features as DictVectorizer input: age scaled, booleans 0/1, text lower case."""
    out: dict[str, float | str] = {}
    for name, value in features.items():
        if value is None or name in ("name", "user_id", "id"):
            continue
        if isinstance(value, bool):
            out[name] = 1.0 if value else 0.0
        elif isinstance(value, int | float):
            out[name] = float(value) / 100.0 if name == "age" else float(value)
        elif isinstance(value, str) and value.strip():
            out[name] = value.strip().lower()
    return out


def ranking_to_liking(ranking: Iterable[str]) -> dict[str, float]:
    """A full ranking as scores: first gets the highest."""
    names = list(ranking)
    return {name: float(len(names) - index) for index, name in enumerate(names)}


def load_seed() -> list[tuple[dict[str, Any], dict[str, float]]]:
    """The shipped seed dataset (simulated personas), as (features, liking) rows."""
    rows = []
    with SEED_CSV.open(newline="", encoding="utf-8") as handle:
        for record in csv.DictReader(handle):
            features: dict[str, Any] = {}
            for column in FEATURE_COLUMNS:
                raw = record[column]
                if column == "age":
                    features[column] = int(raw)
                elif column == "lives_alone":
                    features[column] = raw == "True"
                else:
                    features[column] = raw
            rows.append((features, ranking_to_liking(record["ranking"].split(">"))))
    return rows


Vector = np.ndarray[Any, np.dtype[np.float64]]

C_REGULARIZATION = 1.0
"""Inverse strength of the L2 penalty on the weights (scikit-learn's ``C``)."""


def feature_name(name: str, value: float | str) -> str:
    """The column of one encoded feature: ``name`` for a number, ``name=value`` for text
    (one-hot, as scikit-learn's ``DictVectorizer``)."""
    return f"{name}={value}" if isinstance(value, str) else name


def vectorize(encoded: Mapping[str, float | str], columns: Mapping[str, int]) -> Vector:
    """One encoded feature dict as a row over ``columns``; unknown features are ignored."""
    row = np.zeros(len(columns))
    for name, value in encoded.items():
        column = columns.get(feature_name(name, value))
        if column is not None:
            row[column] = 1.0 if isinstance(value, str) else value
    return row


def fit_logistic(
    matrix: Vector, labels: Vector, c: float = C_REGULARIZATION
) -> tuple[Vector, float]:
    """Weights and intercept minimizing ``c * sum(log loss) + ||w||^2 / 2`` (the intercept
    is not penalized): scikit-learn's ``LogisticRegression(C=c)``, solved by Newton's
    method to full precision (the objective is strictly convex; a few steps suffice).

    ``labels`` are 0 or 1 and hold both values.
    """
    rows, width = matrix.shape
    design = np.hstack([matrix, np.ones((rows, 1))])
    penalty = np.eye(width + 1) / c
    penalty[width, width] = 0.0
    theta = np.zeros(width + 1)
    for _ in range(100):
        z = design @ theta
        p = np.exp(-np.logaddexp(0.0, -z))  # the logistic function, without overflow
        gradient = design.T @ (p - labels) + penalty @ theta
        hessian = (design.T * (p * (1.0 - p))) @ design + penalty
        step = np.linalg.solve(hessian, gradient)
        theta -= step
        if float(np.max(np.abs(step))) < 1e-10:
            break
    return theta[:width], float(theta[width])


class PreferenceModel:
    """Label ranking of the entertainment activities from user features."""

    def __init__(
        self,
        columns: Sequence[str],
        weights: Vector,
        intercepts: Vector,
        training_size: int,
    ) -> None:
        """``columns``: the encoded features (:func:`feature_name`), in weight order;
        ``weights[k]`` and ``intercepts[k]``: the logistic model of ``PAIRS[k]``
        (probability that the first activity of the pair is preferred)."""
        self.columns: tuple[str, ...] = tuple(columns)
        self._index = {name: k for k, name in enumerate(self.columns)}
        self._weights = weights
        self._intercepts = intercepts
        self.training_size = training_size

    @classmethod
    def fit(cls, rows: Iterable[tuple[Features, Liking]]) -> PreferenceModel:
        """Learn from (features, liking) rows; a liking may leave activities out."""
        data = [(encode(features), liking) for features, liking in rows]
        data = [(features, liking) for features, liking in data if features]
        if not data:
            return cls.untrained()
        columns = sorted({feature_name(n, v) for features, _ in data for n, v in features.items()})
        index = {name: k for k, name in enumerate(columns)}
        matrix = np.array([vectorize(features, index) for features, _ in data])
        weights = np.zeros((len(PAIRS), len(columns)))
        intercepts = np.zeros(len(PAIRS))
        for k, (i, j) in enumerate(PAIRS):
            a, b = ACTIVITIES[i], ACTIVITIES[j]
            chosen, labels = [], []
            for row, (_, liking) in enumerate(data):
                if a in liking and b in liking and liking[a] != liking[b]:
                    chosen.append(row)
                    labels.append(1.0 if liking[a] > liking[b] else 0.0)
            if len(set(labels)) < 2:
                # One-sided or no evidence: a constant, kept away from certainty.
                share = (sum(labels) + 1) / (len(labels) + 2)
                intercepts[k] = float(np.log(share / (1 - share)))
                continue
            weights[k], intercepts[k] = fit_logistic(matrix[chosen], np.array(labels))
        return cls(columns, weights, intercepts, len(data))

    @classmethod
    def untrained(cls) -> PreferenceModel:
        """A model that learnt nothing: it predicts nothing (:meth:`win_scores` is None),
        so the chooser's beliefs start flat, as for a user of unknown features."""
        return cls((), np.zeros((len(PAIRS), 0)), np.zeros(len(PAIRS)), 0)

    @classmethod
    def from_seed(cls) -> PreferenceModel:
        """The model learnt from the shipped seed personas only (cached)."""
        return _seed_model()

    @classmethod
    def train(cls, store: ProfileStore) -> PreferenceModel:
        """The seed personas plus every stored user with scores for two activities or more.

        Reads the store each time, so an erased user is no longer learnt from.

        Raises:
            ProfileError: the store cannot be read (StoreUnavailable).
        """
        stored = store.training_rows()
        if not stored:
            return cls.from_seed()
        return cls.fit([*load_seed(), *stored])

    def usable(self, features: Features) -> bool:
        """Whether ``features`` holds anything this model learnt from."""
        return any(feature_name(n, v) in self._index for n, v in encode(features).items())

    def win_scores(self, features: Features) -> dict[str, float] | None:
        """Each activity's mean probability of being preferred to another (0..1);
        None when the features are empty or unknown to the model."""
        if not self.columns or not self.usable(features):
            return None
        vector = vectorize(encode(features), self._index)
        first_wins = 1.0 / (1.0 + np.exp(-(self._weights @ vector + self._intercepts)))
        wins = np.zeros(len(ACTIVITIES))
        for k, (i, j) in enumerate(PAIRS):
            wins[i] += first_wins[k]
            wins[j] += 1.0 - first_wins[k]
        wins /= len(ACTIVITIES) - 1
        return {name: float(wins[k]) for k, name in enumerate(ACTIVITIES)}

    def predict_ranking(self, features: Features, rng: random.Random) -> list[str]:
        """The predicted ranking, best first; random when there are no usable features."""
        scores = self.win_scores(features)
        names = list(ACTIVITIES)
        rng.shuffle(names)  # random order, and random tie-breaking below
        if scores is None:
            return names
        return sorted(names, key=lambda name: -scores[name])


FIRST_GUESS_LOW = 0.3
FIRST_GUESS_HIGH = 0.7
"""A declared activity's first guess runs from LOW (the user matches none of the
features it names) to HIGH (all of them): a guess worth :data:`PRIOR_STRENGTH`
observations, which the user's own ratings soon outweigh."""


def _matches(feature: str, wanted: tuple[str | int | bool, ...], value: Any) -> bool:
    if feature == "age" and len(wanted) == 2 and isinstance(value, int | float):
        low, high = wanted
        return isinstance(low, int) and isinstance(high, int) and low <= value <= high
    if isinstance(value, int | float):  # bool is an int: true and false match as such
        return value in wanted
    return str(value).strip().lower() in wanted


def first_guess(entry: ActivityEntry, features: Features) -> float:
    """How much a user of ``features`` may like the declared activity ``entry`` before
    any evidence: the share of its named features the user matches, between
    :data:`FIRST_GUESS_LOW` and :data:`FIRST_GUESS_HIGH`; 0.5 when the user has none of
    them (nothing to go on, as for a shipped activity and an unknown user)."""
    known = [(name, wanted) for name, wanted in entry.features.items() if name in features]
    known = [(name, wanted) for name, wanted in known if features[name] is not None]
    if not known:
        return 0.5
    share = sum(_matches(n, w, features[n]) for n, w in known) / len(known)
    return FIRST_GUESS_LOW + (FIRST_GUESS_HIGH - FIRST_GUESS_LOW) * share


@cache
def _seed_model() -> PreferenceModel:
    return PreferenceModel.fit(load_seed())


PRIOR_STRENGTH = 2.0
"""How many observations the prediction is worth against the user's own evidence (the
concentration of its Beta prior on the user's liking)."""

NOVELTY_PROBABILITY = 0.15
"""Chance to pick an activity the user has never done, while there is one (the
``explore`` policy only)."""

ChooserPolicy = Literal["ranking", "explore"]
"""How the robot picks an activity by itself (``[controller] chooser``):

- ``ranking``, the paper's: the best of the user's predicted ranking (expected liking,
  from the features refined by her ratings, completions and stops) not just done;
- ``explore``: with :data:`NOVELTY_PROBABILITY` an activity the user never did,
  otherwise Thompson sampling from each belief, so that little-known activities get
  tried. Beyond the paper: it learns a better ranking at the cost of worse choices
  meanwhile (docs/paper.md)."""

GRID: Vector = np.linspace(0.0125, 0.9875, 40)
"""The liking values (0..1) a belief is held on: the midpoints of 40 equal bins."""
FEEDBACK_SD = 0.15
"""Spread of a rating around the user's liking (a 1-5 answer is a noisy, rounded
liking: 0.25 apart)."""
STOP_AT = 0.4
"""Liking under which a user tends to stop an activity (the middle of the step)."""
STOP_WIDTH = 0.1
"""How gradual that step is (logistic scale, in liking)."""
STOP_SLIP = 0.1
"""Chance that a stop or a completion says nothing of the liking (a call, a mood)."""


def _stop_chance() -> Vector:
    """P(the user stops the activity | liking) on :data:`GRID`."""
    step = 1.0 / (1.0 + np.exp(-(STOP_AT - GRID) / STOP_WIDTH))
    result: Vector = STOP_SLIP + (1.0 - 2.0 * STOP_SLIP) * step
    return result


_LOG_STOP: Vector = np.log(_stop_chance())
_LOG_FINISH: Vector = np.log(1.0 - _stop_chance())


def posterior(prior_mean: float, score: ActivityScore | None) -> Vector:
    """The belief about one activity's liking, as probabilities over :data:`GRID`.

    The prior is a Beta of mean ``prior_mean`` worth :data:`PRIOR_STRENGTH`
    observations. Each rating (feedback, 0..1) is the liking plus noise of
    :data:`FEEDBACK_SD`; each completion and each cancellation is a draw of the
    stop-or-finish step (:data:`STOP_AT`): a completion says "not disliked", a
    cancellation "probably disliked", and neither says how much more.
    """
    m = min(0.95, max(0.05, prior_mean))
    log = (PRIOR_STRENGTH * m - 1.0) * np.log(GRID) + (PRIOR_STRENGTH * (1 - m) - 1.0) * np.log(
        1.0 - GRID
    )
    if score is not None:
        if score.feedback_count:
            n, total = score.feedback_count, score.feedback_sum
            log = log - (n * GRID * GRID - 2.0 * total * GRID) / (2.0 * FEEDBACK_SD**2)
        log = log + score.completions * _LOG_FINISH + score.cancellations * _LOG_STOP
    weights = np.exp(log - float(np.max(log)))
    result: Vector = weights / float(np.sum(weights))
    return result


@dataclass(frozen=True, slots=True)
class ChoiceDraw:
    """What one :meth:`ActivityChooser.choose` picked and the random draws behind it,
    for the decision's explanation."""

    activity: str
    """What was picked."""
    candidates: tuple[str, ...]
    """What it was picked among (every activity but the excluded ones)."""
    untried: tuple[str, ...]
    """The candidates the user never did (the novelty draw's choice)."""
    novelty_draw: float | None
    """The novelty coin (uniform in 0..1; below :data:`NOVELTY_PROBABILITY`, a novelty
    pick); None when every candidate had been tried and no coin was tossed."""
    samples: Mapping[str, float] | None
    """Thompson sampling's draw of a liking per candidate (the highest won); None for a
    novelty pick or a ranking's."""
    novelty_probability: float = NOVELTY_PROBABILITY
    """The novelty coin's threshold."""
    explained: bool = True
    """False for another chooser put in this one's place (a study's baseline): its
    draws are its own, and only ``activity`` and ``candidates`` say anything."""
    ranking: tuple[str, ...] | None = None
    """The ``ranking`` policy: the candidates by expected liking, best first (the first
    won); None for a draw."""

    @property
    def novelty(self) -> bool:
        """The novelty coin picked: an untried activity, at random."""
        return self.samples is None and self.ranking is None


RETRAIN_EVERY_S = 600.0
"""Shortest time between two retrainings of the chooser's model (its clock's seconds)."""


def _in_thread(work: Callable[[], None]) -> threading.Thread:
    thread = threading.Thread(target=work, name="dms-retrain", daemon=True)
    thread.start()
    return thread


class ActivityChooser:
    """Picks the next entertainment activity for a user (the autonomous choice).

    Its model is retrained from the store in the background (:meth:`session_ended`),
    so new evidence is learnt and an erased user is forgotten while the daemon runs.
    """

    def __init__(
        self,
        model: PreferenceModel,
        store: ProfileStore | None = None,
        retrain_every_s: float = RETRAIN_EVERY_S,
        start: Callable[[Callable[[], None]], threading.Thread] = _in_thread,
        policy: ChooserPolicy = "ranking",
    ) -> None:
        """``start`` runs a retraining off the caller's thread (tests may replace it);
        ``policy``: how :meth:`choose` picks (:data:`ChooserPolicy`)."""
        self.model = model
        self.policy = policy
        self.store = store
        self.retrain_every_s = retrain_every_s
        self._start = start
        self._lock = threading.Lock()
        self._training: threading.Thread | None = None
        self._last_retrain: datetime | None = None
        self._last_beliefs: (
            tuple[Profile, PreferenceModel, dict[str, tuple[float, float]], Catalogue] | None
        ) = None
        """The last profile asked about, the model that answered, its beliefs and the
        catalogue they cover: a choice asks twice (to choose, then to explain), of the
        same frozen profile."""

    def session_ended(self, now: datetime) -> bool:
        """When a user leaves: retrain if none ran for :attr:`retrain_every_s`.

        Returns at once; True if a retraining started.
        """
        last = self._last_retrain
        if self.retrain_every_s == float("inf"):
            return False  # never (the simulator: a seeded run must not depend on threads)
        if last is not None and (now - last).total_seconds() < self.retrain_every_s:
            return False
        started = self.retrain() is not None
        if started:
            self._last_retrain = now
        return started

    def retrain(self) -> threading.Thread | None:
        """Start retraining from the store in the background; the new model replaces
        :attr:`model` (one attribute swap) when it is ready.

        Returns the training's thread, or None when there is no store or one runs.
        """
        store = self.store
        if store is None:
            return None
        with self._lock:
            if self._training is not None and self._training.is_alive():
                return None

            def work() -> None:
                try:
                    model = PreferenceModel.train(store)
                except Exception as error:  # contained: the old model stays in use
                    log.warning("retraining the preference model failed: %s", error)
                    return
                self.model = model

            self._training = self._start(work)
            return self._training

    def wait_retrained(self, timeout: float | None = None) -> bool:
        """Wait for a running retraining (at shutdown, in tests); False on timeout."""
        training = self._training
        if training is not None:
            training.join(timeout)
        return training is None or not training.is_alive()

    def priors(
        self, model: PreferenceModel, profile: Profile, catalogue: Catalogue | None = None
    ) -> dict[str, float]:
        """Per entertainment activity of ``catalogue`` (default: the one in force), the
        first guess of the user's liking: the model's prediction from features, a
        declared activity's :func:`first_guess`."""
        features = profile.features()
        prior = model.win_scores(features) or dict.fromkeys(ACTIVITIES, 0.5)
        catalogue = catalogue or current()
        for entry in catalogue.declared:
            if entry.name in catalogue.entertainment:
                prior[entry.name] = first_guess(entry, features)
        return {name: prior[name] for name in catalogue.entertainment}

    def posteriors(self, profile: Profile) -> dict[str, Vector]:
        """Per activity, the belief about the user's liking over :data:`GRID`: the
        prediction from features as the prior, updated with the user's own evidence."""
        prior = self.priors(self.model, profile)
        return {name: posterior(mean, profile.scores.get(name)) for name, mean in prior.items()}

    def beliefs(self, profile: Profile) -> dict[str, tuple[float, float]]:
        """Per activity, Beta(alpha, beta) with the mean and spread of the belief about how
        much the user likes it (:meth:`posteriors`): alpha / (alpha + beta) is the
        expected liking. Without evidence it is the prior itself."""
        model, last, catalogue = self.model, self._last_beliefs, current()
        if last is not None and last[0] is profile and last[1] is model and last[3] is catalogue:
            return dict(last[2])
        prior = self.priors(model, profile, catalogue)
        out = {}
        for name in prior:
            score = profile.scores.get(name)
            if score is None or not score.evidence:
                m = min(0.95, max(0.05, prior[name]))
                out[name] = (PRIOR_STRENGTH * m, PRIOR_STRENGTH * (1.0 - m))
                continue
            belief = posterior(prior[name], score)
            mean = float(belief @ GRID)
            spread = max(float(belief @ (GRID - mean) ** 2), 1e-6)
            size = max(mean * (1.0 - mean) / spread - 1.0, 1e-3)
            out[name] = (mean * size, (1.0 - mean) * size)
        self._last_beliefs = (profile, model, out, catalogue)
        return dict(out)

    def ranking(self, profile: Profile, rng: random.Random) -> list[str]:
        """The blended ranking (expected liking), best first; ties at random."""
        means = {name: a / (a + b) for name, (a, b) in self.beliefs(profile).items()}
        names = list(means)
        rng.shuffle(names)
        return sorted(names, key=lambda name: -means[name])

    def choose(
        self, profile: Profile, rng: random.Random, exclude: Collection[str] = ()
    ) -> ChoiceDraw:
        """One activity not in ``exclude``, with what picked it (the decision's ``why``
        names it).

        ``ranking`` (the paper's): the best candidate by expected liking, ties at random.
        ``explore``: with probability :data:`NOVELTY_PROBABILITY` one the user never did;
        otherwise the best of one draw from each belief (Thompson sampling, from the Beta
        of the belief's mean and spread), so little-known activities still get tried and
        favorites win as evidence grows.
        """
        # ``profile`` is the controller's cached one, kept current by the store's writer:
        # the tick never reads the database here.
        beliefs = self.beliefs(profile)  # one catalogue for the whole choice, even mid-reload
        every = list(beliefs)
        names = [name for name in every if name not in exclude] or every
        untried = [name for name in names if name not in profile.scores]
        if self.policy == "ranking":
            ranked = tuple(n for n in self.ranking(profile, rng) if n in names)
            return ChoiceDraw(ranked[0], tuple(names), tuple(untried), None, None, ranking=ranked)
        coin = rng.random() if untried else None  # the novelty coin, only while one is untried
        if coin is not None and coin < NOVELTY_PROBABILITY:
            return ChoiceDraw(rng.choice(untried), tuple(names), tuple(untried), coin, None)
        draws = {name: rng.betavariate(*beliefs[name]) for name in names}
        pick = max(names, key=lambda name: draws[name])
        return ChoiceDraw(pick, tuple(names), tuple(untried), coin, draws)
