"""Speech for Reachy Mini: espeak-ng's voice through the robot's speaker, or shown.

espeak-ng (Debian's ``espeak-ng``) speaks offline, with no model to download. With the
robot's media on, the text is written to a WAV file in a private temporary folder and
played by the SDK (``media.play_sound``); the command is done when the file has played.
With media off (``--no-media``, the simulator's ``--no-media``), or without espeak-ng,
the sentence is printed on the bridge's standard output and timed at the speaking rate,
as the daemon's simulated Mini times it.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import wave
from pathlib import Path

DEFAULT_WPM = 150.0
"""The speaking rate when the command gives none (the simulated Mini's)."""
MAX_CHARS = 4096
"""The contract's longest text: a longer one is cut, never sent whole to espeak-ng."""
SYNTH_TIMEOUT_S = 20.0


def words_seconds(text: str, rate_wpm: object) -> float:
    """How long ``text`` takes at ``rate_wpm`` (40 to 400; otherwise the default)."""
    rate = rate_wpm if isinstance(rate_wpm, int | float) and 40 <= rate_wpm <= 400 else None
    return 0.3 + 60.0 * len(text.split()) / float(rate or DEFAULT_WPM)


class Voice:
    """espeak-ng writing WAV files into a folder of its own, one file at a time."""

    def __init__(self, executable: str | None = None) -> None:
        self.executable = executable or shutil.which("espeak-ng")
        self._folder = tempfile.TemporaryDirectory(prefix="dms-reachy-voice-")
        self._count = 0

    @property
    def available(self) -> bool:
        return self.executable is not None

    def synthesize(self, text: str, rate_wpm: object, language: object) -> tuple[Path, float]:
        """A WAV file of ``text`` and its length in seconds. Raises OSError (with
        espeak-ng's reason) when it cannot be made."""
        if self.executable is None:
            raise OSError("espeak-ng is not installed (apt-get install espeak-ng)")
        self._count += 1
        path = Path(self._folder.name) / f"say-{self._count % 4}.wav"
        argv = [self.executable, "-w", str(path)]
        if isinstance(rate_wpm, int | float) and 80 <= rate_wpm <= 400:
            argv += ["-s", str(int(rate_wpm))]
        if isinstance(language, str) and language.replace("-", "").isalnum():
            argv += ["-v", language[:16]]
        argv += ["--", text[:MAX_CHARS]]
        try:
            done = subprocess.run(
                argv, capture_output=True, text=True, timeout=SYNTH_TIMEOUT_S, check=False
            )
        except subprocess.TimeoutExpired:
            raise OSError(f"espeak-ng took more than {SYNTH_TIMEOUT_S:.0f} s") from None
        if done.returncode != 0:
            raise OSError(f"espeak-ng: {done.stderr.strip()[:200] or done.returncode}")
        try:
            with wave.open(str(path), "rb") as sound:
                seconds = sound.getnframes() / float(sound.getframerate() or 1)
        except (wave.Error, EOFError) as error:
            raise OSError(f"espeak-ng wrote no readable WAV ({error})") from None
        return path, seconds

    def close(self) -> None:
        self._folder.cleanup()
