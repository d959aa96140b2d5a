"""Simulated personas with known true preferences: the seed training data and the
benchmark's ground truth.

Run ``python -m memory.seed_data`` to regenerate ``memory/data/seed_rankings.csv``
(400 personas, seed 2026). Each persona's liking of each entertainment activity is
a logistic function of its features (age, sex, education, occupation, hobbies,
living alone) plus an idiosyncratic part that no feature explains, so a predictor
from features alone is good but not perfect, and feedback must do the rest.
"""

from __future__ import annotations

import csv
import math
import random
from dataclasses import dataclass
from pathlib import Path

from dms.kernel.activity_names import SHIPPED_ENTERTAINMENT

SEED_CSV = Path(__file__).resolve().parent / "data" / "seed_rankings.csv"
FEATURE_COLUMNS = ("age", "sex", "education", "occupation", "hobbies", "lives_alone")

OCCUPATIONS = ("teacher", "farmer", "dancer", "engineer", "baker", "nurse", "clerk", "student")
EDUCATION = ("primary", "secondary", "university")
HOBBIES = ("reading", "gardening", "music", "chess", "films", "cards", "walking", "cooking")

# Effects on the log-odds of liking an activity. Activities in CONTRACT order:
# multimedia, news, weather, quiz, dance, bingo, jokes, sayings
_BASE = (0.2, 0.0, -0.2, 0.1, 0.0, 0.0, 0.3, -0.1)
_PER_DECADE_OLDER = (-0.35, 0.15, 0.3, -0.1, -0.45, 0.35, 0.0, 0.4)
_SEX = {
    "female": (0.1, -0.2, 0.0, -0.1, 0.4, 0.2, 0.0, 0.2),
    "male": (-0.1, 0.3, 0.1, 0.2, -0.3, -0.1, 0.1, -0.1),
}
_EDUCATION = {
    "primary": (0.0, -0.3, 0.2, -0.5, 0.1, 0.5, 0.2, 0.5),
    "secondary": (0.1, 0.0, 0.0, 0.0, 0.1, 0.1, 0.1, 0.0),
    "university": (0.0, 0.5, -0.1, 0.6, -0.1, -0.4, -0.1, -0.2),
}
_HOBBY = {
    "reading": (-0.2, 0.6, 0.0, 0.5, -0.3, -0.1, 0.0, 0.3),
    "gardening": (-0.2, 0.0, 0.9, -0.1, 0.0, 0.1, 0.0, 0.3),
    "music": (0.9, -0.2, -0.2, -0.1, 0.9, 0.0, 0.0, -0.1),
    "chess": (-0.2, 0.2, 0.0, 1.0, -0.4, 0.1, -0.1, 0.0),
    "films": (1.0, 0.1, -0.2, 0.1, 0.0, -0.2, 0.3, -0.2),
    "cards": (-0.2, -0.1, 0.0, 0.2, -0.1, 1.0, 0.2, 0.1),
    "walking": (-0.1, 0.0, 0.6, -0.1, 0.3, 0.0, 0.0, 0.1),
    "cooking": (0.2, 0.0, 0.1, 0.0, 0.1, 0.2, 0.3, 0.3),
}
_OCCUPATION = {
    "teacher": (0.0, 0.3, 0.0, 0.5, 0.0, -0.1, 0.0, 0.2),
    "farmer": (-0.2, 0.0, 0.8, -0.2, 0.0, 0.3, 0.1, 0.4),
    "dancer": (0.3, -0.2, 0.0, -0.2, 1.0, 0.0, 0.1, 0.0),
    "engineer": (0.0, 0.4, 0.1, 0.6, -0.2, -0.2, 0.0, -0.3),
    "baker": (0.0, -0.1, 0.1, -0.1, 0.1, 0.3, 0.4, 0.3),
    "nurse": (0.1, 0.1, 0.0, 0.1, 0.1, 0.2, 0.3, 0.1),
    "clerk": (0.1, 0.2, 0.0, 0.1, 0.0, 0.1, 0.2, 0.0),
    "student": (0.6, 0.1, -0.3, 0.2, 0.4, -0.5, 0.3, -0.4),
}
_LIVES_ALONE = (0.1, 0.3, 0.2, 0.0, -0.1, 0.0, 0.3, 0.1)
IDIOSYNCRASY_SD = 0.45
"""Spread of each persona's own taste that no feature explains (log-odds)."""


@dataclass(frozen=True, slots=True)
class SimulatedPersona:
    """Features the robot can learn by asking, and the hidden true liking (0..1)."""

    features: dict[str, str | int | bool]
    liking: dict[str, float]

    def ranking(self) -> list[str]:
        """The true ranking, best liked first."""
        return sorted(self.liking, key=lambda name: -self.liking[name])


def make_persona(rng: random.Random) -> SimulatedPersona:
    """One random persona: mostly older adults, as in the paper's studies."""
    age = int(rng.triangular(18, 98, 78))
    sex = rng.choice(("female", "male"))
    education = rng.choices(EDUCATION, weights=(4, 4, 3))[0]
    occupation = "student" if age < 25 else rng.choice(OCCUPATIONS[:-1])
    hobbies = rng.choice(HOBBIES)
    lives_alone = rng.random() < 0.45
    features: dict[str, str | int | bool] = {
        "age": age,
        "sex": sex,
        "education": education,
        "occupation": occupation,
        "hobbies": hobbies,
        "lives_alone": lives_alone,
    }
    liking = {}
    for index, name in enumerate(SHIPPED_ENTERTAINMENT):
        logit = (
            _BASE[index]
            + _PER_DECADE_OLDER[index] * (age - 75) / 10
            + _SEX[sex][index]
            + _EDUCATION[education][index]
            + _HOBBY[hobbies][index]
            + _OCCUPATION[occupation][index]
            + (_LIVES_ALONE[index] if lives_alone else 0.0)
            + rng.gauss(0.0, IDIOSYNCRASY_SD)
        )
        liking[name] = round(1 / (1 + math.exp(-logit)), 4)
    return SimulatedPersona(features, liking)


def make_personas(count: int, seed: int) -> list[SimulatedPersona]:
    """``count`` personas from ``seed`` (the same seed gives the same personas)."""
    rng = random.Random(seed)
    return [make_persona(rng) for _ in range(count)]


def write_seed_csv(path: Path = SEED_CSV, count: int = 400, seed: int = 2026) -> None:
    """Write the features and true ranking (``a>b>...``) of ``count`` personas."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow([*FEATURE_COLUMNS, "ranking"])
        for persona in make_personas(count, seed):
            writer.writerow(
                [*(persona.features[c] for c in FEATURE_COLUMNS), ">".join(persona.ranking())]
            )


if __name__ == "__main__":
    write_seed_csv()
    print(SEED_CSV)
