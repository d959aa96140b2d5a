"""A behavior declared an activity: the loader's checks, the catalogue it puts in force,
the chooser's first guess and evidence, a pause of an activity that may not be paused,
and rows that name a removed activity."""

from __future__ import annotations

import random
import re
import shutil
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest

from activities import BehaviorLibrary
from activities.errors import BehaviorError
from activities.library import BEHAVIORS_DIR
from activities.synonyms import match_activity
from dms.kernel import activity_names
from dms.kernel.activity_names import (
    ACTIVITIES,
    ENTERTAINMENT_ACTIVITIES,
    MAX_DECLARED,
    SHIPPED,
    USER_SELECTABLE,
    ActivityEntry,
    Catalogue,
    ManagerName,
)
from managers.base import Manager, ManagerStatus
from memory import ActivityChooser, PreferenceModel
from memory.preferences import first_guess
from memory.profile import ActivityScore, Profile
from tests.activities.conftest import Bench

DOCS = Path(__file__).resolve().parents[2] / "docs" / "studio.md"
NOW = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)


def docs_example() -> str:
    """The example of docs/studio.md, as a designer would save it."""
    found = re.search(r"```yaml\n(name: song_or_chat\n.*?)```", DOCS.read_text(), re.S)
    assert found is not None, "docs/studio.md lost its example"
    return found.group(1)


@pytest.fixture(autouse=True)
def shipped_catalogue() -> Iterator[None]:
    """Each test leaves the shipped catalogue in force, as it found it."""
    yield
    activity_names.install(Catalogue())


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    shutil.copytree(BEHAVIORS_DIR, tmp_path, dirs_exist_ok=True)
    (tmp_path / "song_or_chat.yaml").write_text(docs_example(), encoding="utf-8")
    return tmp_path


def test_the_docs_example_loads_and_joins_every_list_of_activities(folder: Path) -> None:
    library = BehaviorLibrary.load(folder)
    assert "song_or_chat" not in ACTIVITIES  # loading alone puts nothing in force
    catalogue = library.install_catalogue()
    entry = catalogue.entry("song_or_chat")
    assert entry == ActivityEntry(
        name="song_or_chat",
        manager=ManagerName.ENTERTAINMENT,
        label="Song or chat",
        picture="song.png",
        expected_s=90.0,
        features={"hobbies": ("music",), "age": (65, 100)},
        pausable=True,
    )
    assert ACTIVITIES["song_or_chat"] is ManagerName.ENTERTAINMENT
    assert list(ENTERTAINMENT_ACTIVITIES)[-1] == "song_or_chat"
    assert "song_or_chat" in USER_SELECTABLE
    assert list(ACTIVITIES)[: len(SHIPPED)] == list(SHIPPED)  # the shipped keep their order
    assert match_activity("can we do the song or chat?") == "song_or_chat"


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (("manager: entertainment", "manager: general"), "manager 'general' is not one of"),
        (("hobbies: [music]", "hobbies: [musik]"), "feature hobbies: 'musik' is not one of"),
        (("age: [65, 100]", "age: [100, 65]"), "feature age: write [youngest, oldest]"),
        (("menu: Song or chat", "menu: ''"), "menu: write the name shown on the menu"),
        (("expected_s: 90", "expected_s: -1"), "expected_s: write seconds"),
        (("picture: song.png", "pictur: song.png"), "unknown key 'pictur': did you mean picture?"),
    ],
)
def test_each_problem_of_a_declaration_is_one_line_at_its_field(
    folder: Path, change: tuple[str, str], expected: str
) -> None:
    path = folder / "song_or_chat.yaml"
    path.write_text(docs_example().replace(*change), encoding="utf-8")
    with pytest.raises(BehaviorError) as error:
        BehaviorLibrary.load(folder)
    assert len(error.value.problems) == 1, error.value.problems
    (problem,) = error.value.problems
    line = next(n for n, text in enumerate(path.read_text().splitlines(), 1) if change[1] in text)
    assert problem.startswith(f"{path}:{line}: activity: "), problem
    assert expected in problem, problem


def test_a_folder_declares_a_bounded_number_of_activities(folder: Path) -> None:
    for index in range(MAX_DECLARED):  # with the docs' one, one more than the bound
        name = f"extra_{index:02d}"
        text = docs_example().replace("name: song_or_chat", f"name: {name}")
        (folder / f"{name}.yaml").write_text(text, encoding="utf-8")
    with pytest.raises(BehaviorError) as error:
        BehaviorLibrary.load(folder)
    assert error.value.problems == [
        f"{folder}: {MAX_DECLARED + 1} behaviors declare an activity, more than "
        f"{MAX_DECLARED}: remove the activity key of those the robot no longer offers"
    ]


def test_a_saved_declaration_is_written_back_as_it_was(folder: Path) -> None:
    library = BehaviorLibrary.load(folder)
    spec = library.spec("song_or_chat")
    again = spec.to_dict()["activity"]
    assert again == {
        "manager": "entertainment",
        "menu": "Song or chat",
        "picture": "song.png",
        "expected_s": 90,
        "features": {"hobbies": ["music"], "age": [65, 100]},
    }


def _profile(scores: dict[str, ActivityScore], **fields: object) -> Profile:
    return Profile.model_validate(
        {"user_id": "ann", "created_at": NOW, "updated_at": NOW, "scores": scores, **fields}
    )


def test_the_first_guess_follows_the_declared_features() -> None:
    entry = ActivityEntry(
        "song_or_chat",
        ManagerName.ENTERTAINMENT,
        features={"hobbies": ("music",), "age": (65, 100)},
    )
    assert first_guess(entry, {"hobbies": "Music", "age": 70}) == pytest.approx(0.7)
    assert first_guess(entry, {"hobbies": "chess", "age": 70}) == pytest.approx(0.5)
    assert first_guess(entry, {"hobbies": "chess", "age": 30}) == pytest.approx(0.3)
    assert first_guess(entry, {"sex": "female"}) == 0.5  # nothing to go on


def test_the_chooser_learns_a_declared_activity_from_the_users_evidence(folder: Path) -> None:
    BehaviorLibrary.load(folder).install_catalogue()
    chooser = ActivityChooser(PreferenceModel.from_seed(), policy="explore")  # tries others
    disliked = ActivityScore(feedback_count=3, feedback_sum=0.3, cancellations=3)
    scores = {name: disliked for name in SHIPPED if SHIPPED[name] is ManagerName.ENTERTAINMENT}
    scores["song_or_chat"] = ActivityScore(feedback_count=3, feedback_sum=2.9, completions=3)
    profile = _profile(scores, age=72)
    rng = random.Random(7)
    picks = [chooser.choose(profile, rng).activity for _ in range(50)]
    assert picks.count("song_or_chat") > 40, picks
    assert chooser.ranking(profile, rng)[0] == "song_or_chat"


def test_rows_naming_a_removed_activity_are_kept_and_left_out(folder: Path) -> None:
    chooser = ActivityChooser(PreferenceModel.from_seed())
    loved = ActivityScore(feedback_count=5, feedback_sum=5.0, completions=5)
    profile = _profile({"song_or_chat": loved}, age=72)  # stored while it was declared
    assert "song_or_chat" not in ACTIVITIES
    rng = random.Random(3)
    assert {chooser.choose(profile, rng).activity for _ in range(30)} <= set(SHIPPED)
    assert "song_or_chat" not in chooser.beliefs(profile)
    assert profile.scores["song_or_chat"] == loved  # kept, for when it comes back


def test_a_declared_activity_that_may_not_be_paused_is_stopped_instead(
    folder: Path, bench: Bench
) -> None:
    path = folder / "song_or_chat.yaml"
    path.write_text(
        docs_example().replace("expected_s: 90", "expected_s: 90\n  pausable: false"),
        encoding="utf-8",
    )
    library = BehaviorLibrary.load(folder)
    library.install_catalogue()
    manager = Manager(ManagerName.ENTERTAINMENT, library)
    started = manager.start("song_or_chat", bench.context("song_or_chat"), bench.now)
    assert started.status is ManagerStatus.RUNNING
    paused = manager.pause(bench.now)
    assert (paused.status, paused.detail) == (
        ManagerStatus.CANCELLED,
        "it cannot be paused: stopped",
    )
    assert manager.tick(bench.now).status is ManagerStatus.IDLE


def test_the_published_schema_takes_the_docs_example_and_refuses_a_wrong_declaration() -> None:
    import json

    import yaml
    from jsonschema import Draft202012Validator

    from activities.schema import SCHEMA_PATH

    validator = Draft202012Validator(json.loads(SCHEMA_PATH.read_text()))
    example = yaml.safe_load(docs_example())
    assert not list(validator.iter_errors(example))
    example["activity"]["features"] = {"hobby": ["music"]}
    assert list(validator.iter_errors(example))
