"""Audio played faster or slower with its pitch kept: a song at another tempo.

:func:`stretch_audio` runs SoX's ``tempo`` effect (WSOLA: overlapping segments of the waveform
re-spaced where they line up best, so that onsets stay sharp) when the ``sox`` program is on the
PATH (Debian's and Homebrew's ``sox`` package), and librosa's phase vocoder
(``librosa.effects.time_stretch``, ``pip install 'kinectdata[music]'``) otherwise, which is about a
hundred times slower and smears onsets a little. Either way a song of S samples played at ``rate``
comes back with ``round(S / rate)`` samples, the beat ``rate`` times as fast.
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np

from kinectdata.core.errors import AudioError, ConfigError, KinectDataError
from kinectdata.core.librosa_import import import_librosa

STRETCHERS = ("sox", "librosa")
"""The programs :func:`stretch_audio` can use, in the order it tries them."""


def available_stretcher() -> str | None:
    """The first of :data:`STRETCHERS` installed here, or None."""
    if shutil.which("sox"):
        return "sox"
    try:
        import librosa  # noqa: F401
    except ImportError:
        return None
    return "librosa"


def stretch_audio(samples: np.ndarray, rate: float, sample_rate: int, stretcher: str | None = None) -> np.ndarray:
    """Mono audio [S] played ``rate`` times as fast with its pitch kept (``rate`` 1.18: the beat 18 %
    faster and the song 1 / 1.18 as long), as float32 [round(S / rate)].

    Args:
        samples: [S] mono samples, full scale 1.
        rate: the tempo factor, 0.25 to 4.
        sample_rate: Hz.
        stretcher: ``sox`` or ``librosa`` (:data:`STRETCHERS`); None: the first installed.

    Raises:
        ConfigError: a rate outside 0.25-4 or an unknown stretcher.
        AudioError: neither SoX nor librosa is installed, or SoX failed (its message named).
    """
    if not 0.25 <= rate <= 4.0:
        raise ConfigError(f"a tempo factor must be 0.25-4, not {rate!r}")
    if stretcher is not None and stretcher not in STRETCHERS:
        raise ConfigError(f"stretcher must be one of {', '.join(STRETCHERS)}, not {stretcher!r}")
    stretcher = stretcher or available_stretcher()
    if stretcher is None:
        raise AudioError(
            None, "changing a song's tempo needs SoX (apt-get install sox) or librosa (pip install 'kinectdata[music]')"
        )
    x = np.ascontiguousarray(samples, dtype=np.float32)
    wanted = int(round(x.size / rate))
    if rate == 1.0 or x.size == 0:
        return x.copy()
    made = _sox(x, rate, sample_rate) if stretcher == "sox" else _librosa(x, rate)
    if made.size >= wanted:  # the two programs end a sample or two apart; the length is the tempo's
        return np.ascontiguousarray(made[:wanted])
    return np.concatenate([made, np.zeros(wanted - made.size, np.float32)])


def _sox(x: np.ndarray, rate: float, sample_rate: int) -> np.ndarray:
    raw = ["-t", "raw", "-e", "floating-point", "-b", "32", "-r", str(int(sample_rate)), "-c", "1"]
    # -m: SoX's settings for music (its default segment is for speech)
    command = ["sox", "-V1", *raw, "-", *raw, "-", "tempo", "-m", f"{rate:.6f}"]
    try:
        done = subprocess.run(command, input=x.tobytes(), capture_output=True, check=False)
    except OSError as exc:
        raise AudioError(None, f"sox could not be started: {exc}") from exc
    if done.returncode != 0:
        said = done.stderr.decode("utf-8", "replace").strip().splitlines()
        raise AudioError(None, f"sox tempo {rate:g} failed: {said[-1] if said else f'exit status {done.returncode}'}")
    return np.frombuffer(done.stdout, np.float32)


def _librosa(x: np.ndarray, rate: float) -> np.ndarray:
    try:
        librosa = import_librosa("changing a song's tempo without SoX")
    except KinectDataError as exc:
        raise AudioError(None, str(exc)) from None
    return np.asarray(librosa.effects.time_stretch(x, rate=rate), np.float32)
