"""What people call the activities: names and synonyms to recognise a spoken request.

The menu block and the controller share :func:`match_activity`, so "let's play the
quiz", "tell me a joke" or "cognitive stimulation" name the same activity everywhere.
"""

from __future__ import annotations

import re

from dms.kernel.activity_names import ACTIVITIES, current

SYNONYMS: dict[str, tuple[str, ...]] = {
    "multimedia": ("multimedia", "music", "song", "songs", "video", "videos", "photos", "film"),
    "news": ("news", "newspaper", "headlines"),
    "weather": ("weather", "forecast", "temperature"),
    "quiz": ("quiz", "trivia", "questions game"),
    "dance": ("dance", "dancing"),
    "bingo": ("bingo", "lottery"),
    "jokes": ("jokes", "joke", "something funny", "make me laugh"),
    "sayings": ("sayings", "saying", "proverbs", "proverb"),
    "talk": ("talk", "chat", "conversation"),
    "presentation": ("presentation", "present yourself", "introduce yourself", "who are you"),
    "sleep": ("sleep", "go to sleep", "nap"),
    "wait": (),
    "cognitive_stimulation": (
        "cognitive stimulation",
        "cognitive_stimulation",
        "exercises",
        "brain training",
        "memory games",
    ),
    "notification": ("notification", "reminder"),
    "instructions": ("instructions", "help", "how do you work", "how to use"),
    "menu": ("menu", "options", "what can you do"),
}
"""Phrases that name each activity (lower case, whole words); ``wait`` only by its name."""

_PATTERNS: list[tuple[re.Pattern[str], str]] = sorted(
    (
        (re.compile(rf"(?<![\w']){re.escape(phrase)}(?![\w'])"), name)
        for name, phrases in SYNONYMS.items()
        for phrase in phrases
    ),
    key=lambda item: -len(item[0].pattern),
)


def match_activity(text: str) -> str | None:
    """The activity ``text`` names (its name or a synonym, as whole words), else None.

    Longer phrases win, so "cognitive stimulation" is not read as anything shorter.
    """
    spoken = " ".join(text.lower().replace("_", " ").split())
    if not spoken:
        return None
    exact = spoken.replace(" ", "_")
    if exact in ACTIVITIES:
        return exact
    for entry in current().declared:  # a declared activity is also called by its menu name
        if entry.label and re.search(
            rf"(?<![\w']){re.escape(entry.label.lower())}(?![\w'])", spoken
        ):
            return entry.name
    for pattern, name in _PATTERNS:
        if pattern.search(spoken):
            return name
    return None


def bare_activity(text: str) -> str | None:
    """The activity ``text`` is nothing but the name or a synonym of ("Bingo!",
    "lottery"), else None: said to a question whose answer is a name, such words ask for
    the activity (they are no one's name)."""
    spoken = " ".join(re.sub(r"[^\w' ]+", " ", text.lower()).replace("_", " ").split())
    wanted = match_activity(spoken) if spoken else None
    if wanted is None:
        return None
    names = {wanted.replace("_", " "), *SYNONYMS.get(wanted, ())}
    names |= {e.label.lower() for e in current().declared if e.name == wanted and e.label}
    return wanted if spoken in names else None


_REQUEST_CUES = re.compile(
    r"\b(let'?s|let us|play|start|put on|i want|i'd like|i would like|can we|could we|"
    r"shall we|how about|tell me|show me|do some|do the|time for)\b"
)


def requests_activity(text: str) -> bool:
    """True if ``text`` asks for the activity it names ("let's play bingo"), rather than
    mentioning it ("I like the news" as the answer to a question on hobbies)."""
    spoken = " ".join(text.lower().replace("’", "'").split())
    return match_activity(spoken) is not None and _REQUEST_CUES.search(spoken) is not None
