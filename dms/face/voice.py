"""Push-to-talk, transcribed on this machine: pocketsphinx and its bundled US English
model (``pip install 'dms[voice]'``); nothing leaves the computer.

The page records while the button is held and sends one WAV file; :meth:`Transcriber.
transcribe` turns it into text and a confidence, the mean of the recognised words'
posterior probabilities (pocketsphinx's own word confidences), which the daemon compares
with its ``min_speech_confidence``. One utterance is decoded at a time; at most
:data:`MAX_SECONDS` of audio are taken.
"""

from __future__ import annotations

import io
import threading
import wave
from dataclasses import dataclass
from typing import Any

import numpy as np

RATE = 16_000
"""The model's sample rate: other rates are resampled to it."""
MAX_SECONDS = 20.0
MAX_BYTES = int(MAX_SECONDS * 48_000 * 2 * 2) + 1024
"""The largest WAV taken: 20 s of 48 kHz 16-bit stereo and a header."""
SPEECH_RMS = 300.0
"""A 20 ms frame louder than this (about -40 dBFS) may hold speech; a quiet room's
microphone stays under it."""
SPEECH_MIN_S = 0.15
"""A recording with less sound than this holds no words: nothing is decoded (the
recogniser would make words out of silence)."""
MARGIN_S = 0.3
"""Kept before the first and after the last sound: the words' soft edges."""
FILLERS = frozenset({"<s>", "</s>", "<sil>", "[NOISE]", "[SPEECH]", "[BREATH]", "[COUGH]"})


class VoiceError(ValueError):
    """The recording cannot be transcribed: the reason is said to the page."""


@dataclass(frozen=True, slots=True)
class Heard:
    """What the microphone heard: the words and how sure the recogniser is (0..1)."""

    text: str
    confidence: float


def unavailable() -> str | None:
    """None when push-to-talk can work here, else why not (one line for the page)."""
    try:
        import pocketsphinx  # noqa: F401
    except ImportError:
        return "voice input needs the voice extra: pip install 'dms[voice]'"
    return None


def read_wav(data: bytes) -> np.ndarray[Any, np.dtype[np.int16]]:
    """16 kHz mono 16-bit samples from a WAV file of any rate, mono or stereo."""
    if len(data) > MAX_BYTES:
        raise VoiceError(f"the recording is longer than {MAX_SECONDS:g} s")
    try:
        with wave.open(io.BytesIO(data)) as wav:
            rate, channels, width = wav.getframerate(), wav.getnchannels(), wav.getsampwidth()
            frames = wav.readframes(wav.getnframes())
    except (wave.Error, EOFError) as error:
        raise VoiceError(f"not a WAV recording ({error})") from None
    if width != 2 or channels not in (1, 2) or not 8_000 <= rate <= 96_000:
        raise VoiceError("the recording is not 16-bit mono or stereo PCM at 8-96 kHz")
    samples = np.frombuffer(frames[: len(frames) - len(frames) % (2 * channels)], "<i2")
    samples = samples.reshape(-1, channels).mean(axis=1)
    if len(samples) > MAX_SECONDS * rate:
        raise VoiceError(f"the recording is longer than {MAX_SECONDS:g} s")
    if rate % RATE == 0 and rate > RATE:  # 32 or 48 kHz: the mean of each group of samples
        factor = rate // RATE  # (a low-pass filter before dropping them, against aliasing)
        samples = samples[: len(samples) - len(samples) % factor].reshape(-1, factor).mean(axis=1)
    elif rate != RATE and len(samples):
        count = int(len(samples) * RATE / rate)
        samples = np.interp(np.arange(count) * rate / RATE, np.arange(len(samples)), samples)
    return np.asarray(np.clip(samples, -32768, 32767), dtype=np.int16)


def voiced(
    samples: np.ndarray[Any, np.dtype[np.int16]],
) -> np.ndarray[Any, np.dtype[np.int16]] | None:
    """The part of the recording with sound in it, with :data:`MARGIN_S` of what is around
    it (decoding takes time in proportion to the audio: the silence before and after the
    words is left out); None when less than :data:`SPEECH_MIN_S` of it is louder than
    silence."""
    frame = RATE // 50
    count = len(samples) // frame
    if count == 0:
        return None
    frames = samples[: count * frame].astype(np.float64).reshape(count, frame)
    loud = np.flatnonzero(np.sqrt((frames**2).mean(axis=1)) > SPEECH_RMS)
    if len(loud) * frame < SPEECH_MIN_S * RATE:
        return None
    margin = int(MARGIN_S * RATE)
    first, last = loud[0] * frame - margin, (loud[-1] + 1) * frame + margin
    return samples[max(0, first) : last]


class Transcriber:
    """pocketsphinx's decoder, made on first use (a third of a second) and kept."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._decoder: Any = None

    def transcribe(self, data: bytes) -> Heard:
        """The words in one WAV recording; empty text when nothing was recognised.
        Raises VoiceError for a file it cannot read."""
        samples = voiced(read_wav(data))
        if samples is None:
            return Heard("", 0.0)
        pad = np.zeros(RATE // 4, dtype=np.int16)  # silence around: the model expects it
        raw = np.concatenate([pad, samples, pad]).tobytes()
        with self._lock:
            decoder = self._decoder_made()
            decoder.start_utt()
            decoder.process_raw(raw, full_utt=True)
            decoder.end_utt()
            hypothesis = decoder.hyp()
            words = [(s.word, float(s.prob)) for s in decoder.seg() if s.word not in FILLERS]
        if hypothesis is None or not words:
            return Heard("", 0.0)
        text = " ".join(_plain(word) for word, _ in words)
        confidence = sum(prob for _, prob in words) / len(words)
        return Heard(text, round(min(1.0, max(0.0, confidence)), 3))

    def _decoder_made(self) -> Any:
        if self._decoder is None:
            from pocketsphinx import Decoder

            self._decoder = Decoder(samprate=RATE, loglevel="FATAL")
        return self._decoder


def _plain(word: str) -> str:
    """``read(2)`` (a pronunciation variant) as ``read``."""
    return word.split("(", 1)[0]
