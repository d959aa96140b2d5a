"""The preference model's own solver and encoder against scikit-learn's.

memory/preferences.py solves the model without scikit-learn (which would cost 0.6 s of
the daemon's start and 100 MB resident); these tests hold it to scikit-learn's answers:
the same columns as ``DictVectorizer``, an optimum at least as good as
``LogisticRegression(C=1.0)``'s, the same rankings.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from memory.preferences import (
    ACTIVITIES,
    PAIRS,
    PreferenceModel,
    encode,
    fit_logistic,
    load_seed,
    vectorize,
)
from memory.seed_data import make_personas

sklearn_linear = pytest.importorskip("sklearn.linear_model")
sklearn_features = pytest.importorskip("sklearn.feature_extraction")


def _objective(weights: np.ndarray, intercept: float, x: np.ndarray, y: np.ndarray) -> float:
    z = x @ weights + intercept
    return float(np.sum(np.logaddexp(0.0, z) - y * z) + 0.5 * weights @ weights)


def test_the_encoding_is_dict_vectorizers() -> None:
    data = [encode(features) for features, _ in load_seed()]
    vectorizer = sklearn_features.DictVectorizer(sparse=False)
    expected = vectorizer.fit_transform(data)
    model = PreferenceModel.fit(load_seed())
    assert list(model.columns) == list(vectorizer.feature_names_)
    index = {name: k for k, name in enumerate(model.columns)}
    assert np.array_equal(np.array([vectorize(row, index) for row in data]), expected)


def test_newton_reaches_scikit_learns_optimum_or_better() -> None:
    rows = load_seed()
    data = [(encode(features), liking) for features, liking in rows]
    model = PreferenceModel.fit(rows)
    index = {name: k for k, name in enumerate(model.columns)}
    matrix = np.array([vectorize(features, index) for features, _ in data])
    for i, j in PAIRS:
        a, b = ACTIVITIES[i], ACTIVITIES[j]
        chosen = [r for r, (_, lk) in enumerate(data) if a in lk and b in lk and lk[a] != lk[b]]
        labels = np.array([1.0 if data[r][1][a] > data[r][1][b] else 0.0 for r in chosen])
        if len(set(labels)) < 2:
            continue
        ours = fit_logistic(matrix[chosen], labels)
        theirs = sklearn_linear.LogisticRegression(C=1.0, max_iter=500)
        theirs.fit(matrix[chosen], labels)
        mine = _objective(ours[0], ours[1], matrix[chosen], labels)
        reference = _objective(theirs.coef_[0], theirs.intercept_[0], matrix[chosen], labels)
        assert mine <= reference + 1e-9


def test_the_win_scores_are_those_of_the_scikit_learn_model() -> None:
    """On unseen personas the scores match scikit-learn's within 0.01 (lbfgs stops near,
    not at, the optimum)."""
    rows = load_seed()
    ours = PreferenceModel.fit(rows)
    data = [(encode(features), liking) for features, liking in rows]
    vectorizer = sklearn_features.DictVectorizer(sparse=False)
    matrix = vectorizer.fit_transform([features for features, _ in data])
    models = []
    for i, j in PAIRS:
        a, b = ACTIVITIES[i], ACTIVITIES[j]
        chosen = [r for r, (_, lk) in enumerate(data) if a in lk and b in lk and lk[a] != lk[b]]
        labels = [1 if data[r][1][a] > data[r][1][b] else 0 for r in chosen]
        models.append(sklearn_linear.LogisticRegression(C=1.0, max_iter=500))
        models[-1].fit(matrix[chosen], labels)
    for persona in make_personas(100, seed=77):
        scores = ours.win_scores(persona.features)
        assert scores is not None
        row = vectorizer.transform([encode(persona.features)])
        wins = np.zeros(len(ACTIVITIES))
        for (i, j), model in zip(PAIRS, models, strict=True):
            first = model.predict_proba(row)[0][1]
            wins[i] += first
            wins[j] += 1.0 - first
        wins /= len(ACTIVITIES) - 1
        assert max(abs(scores[name] - wins[k]) for k, name in enumerate(ACTIVITIES)) < 0.01


def test_the_preference_model_does_not_import_scikit_learn() -> None:
    code = (
        "import sys; from memory import PreferenceModel, ActivityChooser;"
        " PreferenceModel.from_seed().predict_ranking({'age': 80}, __import__('random').Random());"
        " print(sorted(m for m in ('sklearn', 'scipy', 'matplotlib') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
