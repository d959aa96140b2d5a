"""Number words, defined once: what a speech recognizer writes for a number said.

A quiz's "six", a feedback's "four": answers are matched against choices written as
digits, so every place that compares a spoken answer turns number words into digits
with :func:`digits`.
"""

from __future__ import annotations

NUMBER_WORDS = {
    "zero": "0", "one": "1", "two": "2", "three": "3", "four": "4", "five": "5",
    "six": "6", "seven": "7", "eight": "8", "nine": "9", "ten": "10",
}  # fmt: skip


def digits(text: str) -> str:
    """``text`` lower-cased, its words split on spaces, number words as digits."""
    return " ".join(NUMBER_WORDS.get(word, word) for word in text.lower().split())
