"""Audio input: any file libsndfile reads (WAV, FLAC, OGG/Vorbis, MP3...), as mono at a target rate.

Channels are averaged (a plain mean, so a mono file duplicated to two channels comes out
unchanged) and the result is resampled with soxr's high-quality band-limited resampler, whose
anti-aliasing filter removes content above the new Nyquist frequency instead of folding it back.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import soundfile
import soxr

from .errors import AudioError

DEFAULT_SAMPLE_RATE = 16000
"""Hz; the rate the Yalta et al. (2016) pipeline works at."""


@dataclass(eq=False)
class Audio:
    """Mono audio.

    Attributes:
        samples: [S] float32 in -1..1 (full scale).
        sample_rate: Hz.
        source: what was read: ``path``, ``sample_rate`` (Hz), ``channels``, ``frames``, ``format``.
    """

    samples: np.ndarray
    sample_rate: int
    source: dict[str, Any] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Seconds."""
        return self.samples.shape[0] / self.sample_rate


def resample(samples: np.ndarray, from_rate: float, to_rate: float) -> np.ndarray:
    """Band-limited resampling of [S] or [S, C] audio from ``from_rate`` to ``to_rate`` Hz (soxr HQ)."""
    if from_rate == to_rate:
        return np.asarray(samples, dtype=np.float32)
    return soxr.resample(np.asarray(samples, dtype=np.float32), from_rate, to_rate, quality="HQ")


def to_mono(samples: np.ndarray) -> np.ndarray:
    """[S, C] -> [S]: the mean of the channels."""
    samples = np.asarray(samples)
    return samples if samples.ndim == 1 else samples.mean(axis=1, dtype=np.float64).astype(np.float32)


def load_audio(path: str | Path, sample_rate: int = DEFAULT_SAMPLE_RATE) -> Audio:
    """Read an audio file as mono float32 at ``sample_rate`` Hz.

    Raises:
        AudioError: the file is missing, unreadable, empty or holds non-finite samples.
    """
    path = Path(path)
    if not path.is_file():
        raise AudioError(path, "no such audio file")
    try:
        data, rate = soundfile.read(str(path), dtype="float32", always_2d=True)
        info = soundfile.info(str(path))
    except (soundfile.LibsndfileError, RuntimeError, TypeError, ValueError) as exc:
        raise AudioError(
            path, f"cannot read audio ({exc}); kinectdata reads what libsndfile reads: WAV, FLAC, OGG, MP3..."
        ) from exc
    if data.shape[0] == 0:
        raise AudioError(path, "the audio file holds no samples")
    if not np.isfinite(data).all():
        frame = int(np.argmax(~np.isfinite(data).all(axis=1)))
        raise AudioError(path, f"non-finite sample (NaN or infinity) at sample {frame} ({frame / rate:.3f} s)")
    mono = resample(to_mono(data), rate, sample_rate)
    return Audio(
        samples=mono,
        sample_rate=int(sample_rate),
        source={
            "path": str(path),
            "sample_rate": int(rate),
            "channels": int(data.shape[1]),
            "frames": int(data.shape[0]),
            "format": f"{info.format}/{info.subtype}",
        },
    )
