"""What a behavior means: placeholders, the robot's repertoire, frames, outcomes.

A behavior that is well formed but would break in silence (an empty sentence, a gesture
the robot does not have, a frame that ends the state ``lost`` at once) is refused by
the loader, so by ``dms behavior check`` and by a reload alike.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from activities import BehaviorError, BehaviorLibrary
from activities.library import BEHAVIORS_DIR
from activities.names import frame_problem
from dms.kernel.repertoire import GESTURES
from sim.robot import MOTION_SECONDS

ROOT = Path(__file__).resolve().parents[2]


def dms(*args: str) -> subprocess.CompletedProcess[str]:
    """``dms ARGS`` as a person types it."""
    return subprocess.run(
        [sys.executable, "-m", "dms.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )


def _shipped(tmp_path: Path, name: str, old: str, new: str) -> tuple[Path, int]:
    """A copy of a shipped behavior with ``old`` replaced by ``new``, and its line."""
    text = (BEHAVIORS_DIR / f"{name}.yaml").read_text()
    assert text.count(old) == 1
    path = tmp_path / f"{name}.yaml"
    path.write_text(text.replace(old, new))
    line = text[: text.index(old)].count("\n") + 1
    return path, line


def _problems(tmp_path: Path, text: str, name: str = "b") -> list[str]:
    """The loader's problems with a behavior written in a folder of its own."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(textwrap.dedent(text).lstrip())
    try:
        BehaviorLibrary.load(tmp_path)
    except BehaviorError as error:
        return error.problems
    return []


# ---------------------------------------------------------------- as a user types it


def test_check_refuses_a_misspelled_content_field_with_its_line_and_the_right_one(
    tmp_path: Path,
) -> None:
    path, line = _shipped(tmp_path, "jokes", "{joke.punchline}", "{joke.punchlin}")
    done = dms("behavior", "check", str(path))
    assert done.returncode == 1
    assert done.stdout.splitlines() == [
        f"{path}:{line}: state TELL/JOKE/PUNCHLINE: speak: parameter 'text': "
        "{joke.punchlin} binds to nothing: joke has no field 'punchlin'; "
        "did you mean {joke.punchline}?"
    ]


def test_check_refuses_a_gesture_the_robot_does_not_have(tmp_path: Path) -> None:
    path, line = _shipped(tmp_path, "jokes", "name: celebrate", "name: celebrat")
    done = dms("behavior", "check", str(path))
    assert done.returncode == 1
    assert done.stdout.splitlines() == [
        f"{path}:{line}: state TELL/JOKE/LAUGH: gesture: parameter 'name': "
        "the robot has no gesture 'celebrat'; did you mean 'celebrate'?"
    ]


def test_check_refuses_a_frame_that_cannot_exist_and_suggests_the_object(
    tmp_path: Path,
) -> None:
    path = tmp_path / "show_tag.yaml"
    path.write_text(
        "name: show_tag\noutcomes: [done]\nstates:\n"
        "  POINT:\n    point_at: {frame: tag_7}\n    transitions: {done: done, lost: done}\n"
    )
    done = dms("behavior", "check", str(path))
    assert done.returncode == 1
    (line,) = done.stdout.splitlines()
    assert line.startswith(f"{path}:5: state POINT: point_at: parameter 'frame': ")
    assert "frame 'tag_7' cannot exist; did you mean 'object:tag_7'?" in line


def test_every_shipped_behavior_checks_clean() -> None:
    done = dms("behavior", "check", str(BEHAVIORS_DIR))
    assert done.returncode == 0, done.stdout
    assert done.stdout.count(": ok\n") == len(list(BEHAVIORS_DIR.glob("*.yaml")))
    alone = dms("behavior", "check")  # the shipped folder by default
    assert alone.returncode == 0 and alone.stdout == done.stdout


def test_show_takes_a_behaviors_name() -> None:
    done = dms("behavior", "show", "quiz")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith('digraph "quiz"')
    wrong = dms("behavior", "show", "quzi")
    assert wrong.returncode == 1
    assert wrong.stderr.startswith("dms: quzi: no such file, and no behavior of that name")
    assert "did you mean 'quiz'?" in wrong.stderr and "weather" in wrong.stderr


def test_check_of_a_folder_names_each_bad_file_and_passes_the_others(tmp_path: Path) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    quiz = folder / "quiz.yaml"
    quiz.write_text(quiz.read_text().replace("{score} right", "{scroe} right", 1))
    done = dms("behavior", "check", str(folder))
    assert done.returncode == 1
    bad = [line for line in done.stdout.splitlines() if not line.endswith(": ok")]
    assert len(bad) == 1 and bad[0].startswith(f"{quiz}:")
    assert "{scroe} binds to nothing" in bad[0] and "did you mean {score}?" in bad[0]
    assert done.stdout.count(": ok\n") == len(list(folder.glob("*.yaml"))) - 1


# ---------------------------------------------------------------- placeholders


def test_keys_written_by_states_and_content_fields_bind(tmp_path: Path) -> None:
    assert (
        _problems(
            tmp_path,
            """
            name: b
            outcomes: [done]
            userdata: {score: 0}
            states:
              ASK:
                ask: {question: "Your name?"}
                transitions: {answered: PICK, no_answer: PICK}
              PICK:
                sample: {items: "{content.quiz.questions}", count: 2, key: picked}
                transitions: {done: LOOP}
              LOOP:
                iterator:
                  items: "{picked}"
                  item_key: q
                  index_key: n
                  continue_on: [done]
                  state:
                    SAY:
                      speak: {text: "{n}. {q.text} {q.choices.0} {answer} {score} {picked.1.text}"}
                transitions: {done: CHOOSE}
              CHOOSE:
                decide: {component: C, outcomes: [a]}
                transitions: {a: KEEP}
              KEEP:
                set_data: {values: {last: "{q}"}, append: {seen: "{decision}"}}
                transitions: {done: END}
              END:
                speak: {text: "{last.answer} {seen.0} {user.name} {user.hobbies} {args.anything}"}
                transitions: {done: done}
            """,
        )
        == []
    )


def test_a_misspelled_key_or_content_file_is_refused_with_the_close_name(
    tmp_path: Path,
) -> None:
    problems = _problems(
        tmp_path,
        """
        name: b
        outcomes: [done]
        userdata: {score: 0}
        states:
          A:
            speak:
              text: "You have {scroe} points."
            transitions: {done: B}
          B:
            sample: {items: "{content.jokse.jokes}", key: jokes}
            transitions: {done: C}
          C:
            speak: {text: "{jokes.setup} {score.value}"}
            transitions: {done: done}
        """,
    )
    where = f"{tmp_path / 'b.yaml'}"
    assert problems == [
        f"{where}:7: state A: speak: parameter 'text': {{scroe}} binds to nothing: "
        "scroe is no userdata key, profile, args or content; did you mean {score}?",
        f"{where}:10: state B: sample: parameter 'items': {{content.jokse.jokes}} binds to "
        "nothing: content names no content file jokse.yaml; did you mean "
        "{content.jokes.jokes}?",
        f"{where}:13: state C: speak: parameter 'text': {{jokes.setup}} binds to nothing: "
        "jokes is a list: an item is read by its index (.0)",
        f"{where}:13: state C: speak: parameter 'text': {{score.value}} binds to nothing: "
        "score is a single value, with nothing below it",
    ]


def test_a_default_stands_in_for_a_value_not_set_yet(tmp_path: Path) -> None:
    text = """
        name: b
        outcomes: [done]
        states:
          A:
            speak: {text: "Hello{nobody|}, {user.name|friend}, {user.pet|dear}."}
            transitions: {done: done}
        """
    assert _problems(tmp_path, text) == []


def test_a_misspelled_profile_field_is_refused_even_with_a_default(tmp_path: Path) -> None:
    text = """
        name: b
        outcomes: [done]
        states:
          A:
            speak: {text: "Hello {user.nmae|there}, {user.pet}."}
            transitions: {done: done}
        """
    where = tmp_path / "b.yaml"
    assert _problems(tmp_path, text) == [
        f"{where}:5: state A: speak: parameter 'text': {{user.nmae}} binds to nothing: "
        "user has no field 'nmae'; did you mean {user.name}?",
        f"{where}:5: state A: speak: parameter 'text': {{user.pet}} binds to nothing: "
        "user has no field 'pet' (a free attribute: give a default, "
        "{user.pet|...}, for users without it)",
    ]


def test_a_profile_parameter_a_state_sets_binds(tmp_path: Path) -> None:
    text = """
        name: b
        outcomes: [done]
        states:
          KEEP:
            set_param: {name: nickname, value: Bob}
            transitions: {done: SAY}
          SAY:
            speak: {text: "Hello {user.nickname}, {user.occupation}, {user.favorite_room}."}
            transitions: {done: done}
        """
    assert _problems(tmp_path, text) == []


@pytest.mark.parametrize(
    ("block", "param"), [("speak", "text"), ("ask", "question"), ("gesture", "name")]
)
def test_a_required_text_left_empty_is_refused(tmp_path: Path, block: str, param: str) -> None:
    text = f"""
        name: b
        outcomes: [done]
        states:
          A:
            {block}: {{{param}: "  "}}
            transitions: {{done: done}}
        """
    (problem,) = [p for p in _problems(tmp_path, text) if f"parameter {param!r}" in p]
    assert problem.endswith(f"{block}: parameter {param!r} is empty: write it (it is required)")


def test_a_behavior_used_as_a_state_sees_its_users_keys(tmp_path: Path) -> None:
    (tmp_path / "inner.yaml").write_text(
        "name: inner\noutcomes: [done]\nstates:\n"
        "  SAY:\n    speak: {text: 'Hello {guest}'}\n    transitions: {done: done}\n"
    )
    text = """
        name: outer
        outcomes: [done]
        userdata: {guest: Ana}
        states:
          GREET:
            behavior: {name: inner}
            transitions: {done: done}
        """
    assert _problems(tmp_path, text, "outer") == []
    (tmp_path / "outer.yaml").unlink()
    (only,) = _problems(tmp_path, "name: x\noutcomes: [done]\nstates: {W: {wait: {}}}\n", "x")
    assert "{guest} binds to nothing" in only


def test_names_given_by_a_remapping_bind(tmp_path: Path) -> None:
    text = """
        name: b
        outcomes: [done]
        states:
          A:
            speak: {text: "{line}"}
            remapping: {line: headline}
            transitions: {done: done}
        """
    assert _problems(tmp_path, text) == []


# ---------------------------------------------------------------- repertoire and frames


def test_led_patterns_and_faces_are_the_robots(tmp_path: Path) -> None:
    problems = _problems(
        tmp_path,
        """
        name: b
        outcomes: [done]
        states:
          A:
            leds: {color: white, pattern: breathe}
            transitions: {done: B}
          B:
            show: {face: hapy}
            transitions: {done: C}
          C:
            gesture: {name: "{args.gesture}"}
            transitions: {done: done}
        """,
    )
    assert [p.split(": ", 1)[1] for p in problems] == [
        "state A: leds: parameter 'pattern': the robot has no LED pattern 'breathe'; "
        "did you mean 'breathing'?",
        "state B: show: parameter 'face': the robot has no face 'hapy'; did you mean 'happy'?",
    ]


def test_the_simulated_mini_times_every_gesture_of_the_repertoire() -> None:
    assert set(MOTION_SECONDS) == set(GESTURES)


@pytest.mark.parametrize(
    ("frame", "expected"),
    [
        ("user", None),
        ("face:ann", None),
        ("object:tag_7", None),
        ("shoulder:left", None),
        ("tag_7", "did you mean 'object:tag_7'?"),
        ("usre", "did you mean 'user'?"),
        ("face:", "frame 'face:' cannot exist: "),
        ("object:a b", "an object's name is 1 to 64 of"),
        ("#3", "cannot exist (frames: user, face:<user id>"),
    ],
)
def test_frames_that_cannot_exist(frame: str, expected: str | None) -> None:
    problem = frame_problem(frame)
    if expected is None:
        assert problem is None
    else:
        assert problem is not None and expected in problem


def test_the_top_attend_and_a_gestures_toward_are_frames_too(tmp_path: Path) -> None:
    problems = _problems(
        tmp_path,
        """
        name: b
        attend: {frame: usr}
        outcomes: [done]
        states:
          A:
            gesture: {name: wave, toward: "face:{args.user}"}
            transitions: {done: B}
          B:
            gesture: {name: wave, toward: ball}
            transitions: {done: done}
        """,
    )
    assert len(problems) == 2
    assert problems[0].endswith(
        "b.yaml:2: attend: frame 'usr' cannot exist; did you mean "
        "'user'? (frames: user, face:<user id>, object:<name>, base, "
        "torso, neck, head, shoulder:left|right)"
    )
    assert ":9: state B: gesture: parameter 'toward': frame 'ball' cannot exist; " in problems[1]


# ---------------------------------------------------------------- outcomes


def test_an_outcome_with_no_transition_is_refused_but_one_the_container_has_passes(
    tmp_path: Path,
) -> None:
    problems = _problems(
        tmp_path,
        """
        name: b
        outcomes: [done, lost]
        states:
          LOOK:
            look_at: {frame: user}
            transitions: {done: POINTING}
          POINTING:
            state_machine:
              outcomes: [done]
              states:
                POINT:
                  point_at: {frame: "object:cup"}
                  transitions: {done: done}
            transitions: {done: done}
        """,
    )
    # LOOK's lost is the behavior's own outcome: it passes through; POINT's leads nowhere
    (problem,) = problems
    assert problem.endswith(
        "b.yaml:11: state POINTING/POINT: outcome 'lost' leads nowhere (add a transition)"
    )


def test_an_outcome_of_a_used_behavior_that_leads_nowhere_is_refused(tmp_path: Path) -> None:
    (tmp_path / "inner.yaml").write_text(
        "name: inner\noutcomes: [done, lost]\nstates:\n"
        "  LOOK:\n    look_at: {frame: user}\n    transitions: {done: done}\n"
    )
    text = """
        name: outer
        outcomes: [done]
        states:
          LOOP:
            iterator:
              items: 2
              continue_on: [done]
              state:
                INNER: {behavior: {name: inner}}
            transitions: {done: done}
        """
    (problem,) = _problems(tmp_path, text, "outer")
    assert problem.endswith(
        "state LOOP/INNER: outcome 'lost' is neither in continue_on nor in break_on"
    )


# ---------------------------------------------------------------- reload


def test_a_reload_refuses_a_misspelled_placeholder_and_keeps_the_old_version(
    tmp_path: Path,
) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    library = BehaviorLibrary.load(folder)
    before = library.spec("jokes")
    jokes = folder / "jokes.yaml"
    jokes.write_text(jokes.read_text().replace("{joke.punchline}", "{joke.punchlin}"))
    (problem,) = library.reload()
    assert problem.startswith(f"{jokes}:") and "did you mean {joke.punchline}?" in problem
    assert library.spec("jokes") is before


def test_behavior_check_refuses_a_misspelled_profile_field_and_an_empty_text(
    tmp_path: Path,
) -> None:
    path = tmp_path / "hello.yaml"
    path.write_text(
        "name: hello\noutcomes: [done]\nstates:\n"
        "  HI:\n    speak: {text: 'Hello {user.nmae|there}!'}\n    transitions: {done: BYE}\n"
        "  BYE:\n    speak: {text: ''}\n"
    )
    checked = dms("behavior", "check", str(path))
    assert checked.returncode == 1, checked.stdout + checked.stderr
    assert f"{path}:8: state BYE: speak: parameter 'text' is empty" in checked.stdout
    path.write_text(path.read_text().replace("{text: ''}", "{text: 'Bye!'}"))
    checked = dms("behavior", "check", str(path))
    assert checked.returncode == 1, checked.stdout + checked.stderr
    assert "{user.nmae} binds to nothing: user has no field 'nmae'; did you mean {user.name}?" in (
        checked.stdout
    )
