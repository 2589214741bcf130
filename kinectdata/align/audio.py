"""Audio input: any file libsndfile reads (WAV, FLAC, OGG/Vorbis, MP3...), as mono at a target rate.

Channels are averaged (a plain mean, so a mono file duplicated to two channels comes out
unchanged) and the result is resampled with soxr's high-quality band-limited resampler, whose
anti-aliasing filter removes content above the new Nyquist frequency instead of folding it back.

:class:`AudioReader` streams a file in blocks, so that long recordings are processed with
bounded memory; :func:`load_audio` reads a whole file through the same path, so both give
identical samples (soxr's streaming resampler does not depend on how its input is cut).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import soundfile
import soxr

from kinectdata.core.errors import AudioError

DEFAULT_SAMPLE_RATE = 16000
"""Hz; the rate the Yalta et al. (2016) pipeline works at."""
BLOCK_SECONDS = 10.0
"""Seconds of source audio decoded at a time when streaming."""


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


def resampled_length(n: int, from_rate: int, to_rate: int) -> int:
    """Samples soxr produces from ``n`` input samples: n * to / from, rounded half up."""
    return n if from_rate == to_rate else (2 * n * to_rate + from_rate) // (2 * from_rate)


def to_mono(samples: np.ndarray) -> np.ndarray:
    """[S, C] -> [S] float32: the mean of the channels (accumulated in float64)."""
    samples = np.asarray(samples)
    if samples.ndim == 1:
        return samples.astype(np.float32, copy=False)
    # column by column: numpy reductions over a short last axis are several times slower
    total = samples[:, 0].astype(np.float64)
    for c in range(1, samples.shape[1]):
        total += samples[:, c]
    return (total / samples.shape[1]).astype(np.float32)


MIN_SOURCE_RATE = 4000
"""Audio recorded below this rate (Hz) is refused: it holds no music the features can use."""


class AudioReader:
    """An audio file streamed as mono float32 blocks at ``sample_rate`` Hz.

    Opening checks that the file is readable and not empty (AudioError otherwise); :meth:`blocks`
    decodes it from the start each time it is called.
    """

    def __init__(self, path: str | Path, sample_rate: int = DEFAULT_SAMPLE_RATE, block_seconds: float = BLOCK_SECONDS):
        self.path = Path(path)
        self.sample_rate = int(sample_rate)
        if not self.path.is_file():
            raise AudioError(self.path, "no such audio file")
        try:
            info = soundfile.info(str(self.path))
        except (soundfile.LibsndfileError, RuntimeError, TypeError, ValueError) as exc:
            raise AudioError(
                self.path, f"cannot read audio ({exc}); kinectdata reads what libsndfile reads: WAV, FLAC, OGG, MP3..."
            ) from exc
        if info.frames <= 0:
            raise AudioError(self.path, "the audio file holds no samples")
        self.source_rate = int(info.samplerate)
        if self.source_rate < MIN_SOURCE_RATE:
            raise AudioError(
                self.path,
                f"sample rate {self.source_rate} Hz: too low for music (at least {MIN_SOURCE_RATE} Hz; the features "
                "need frequencies up to 8 kHz): is the rate in the file's header right?",
            )
        self.channels = int(info.channels)
        self.source_frames = int(info.frames)
        self.format = f"{info.format}/{info.subtype}"
        self._block = max(1, int(block_seconds * self.source_rate))

    @property
    def n_samples(self) -> int:
        """Samples :meth:`blocks` yields in all (from the header's frame count, which is exact for
        WAV and FLAC; compressed formats may differ by a few samples)."""
        return resampled_length(self.source_frames, self.source_rate, self.sample_rate)

    @property
    def duration(self) -> float:
        """Seconds, at the output rate."""
        return self.n_samples / self.sample_rate

    @property
    def source(self) -> dict[str, Any]:
        return {
            "path": str(self.path),
            "sample_rate": self.source_rate,
            "channels": self.channels,
            "frames": self.source_frames,
            "format": self.format,
        }

    def blocks(self) -> Iterator[np.ndarray]:
        """Consecutive [B] float32 mono blocks at ``sample_rate``; together, :attr:`n_samples` samples."""
        stream = None
        if self.source_rate != self.sample_rate:
            stream = soxr.ResampleStream(self.source_rate, self.sample_rate, 1, dtype="float32", quality="HQ")
        done = 0
        try:
            with soundfile.SoundFile(str(self.path)) as f:
                for block in f.blocks(blocksize=self._block, dtype="float32", always_2d=True):
                    mono = to_mono(block)
                    if not np.isfinite(mono).all():  # NaN and infinities survive the mean
                        i = done + int(np.argmax(~np.isfinite(block).all(axis=1)))
                        raise AudioError(self.path, f"non-finite sample (NaN or infinity) at {self._where(i)}")
                    done += block.shape[0]
                    yield mono if stream is None else stream.resample_chunk(mono, last=False)
        except (soundfile.LibsndfileError, RuntimeError) as exc:
            failed = self._decodable_from(done)
            raise AudioError(
                self.path,
                f"cannot decode audio from {self._where(failed)} on, of {self.source_frames} samples in its "
                f"header ({exc})",
            ) from exc
        if stream is not None:  # flush the resampler's tail
            yield stream.resample_chunk(np.zeros(0, np.float32), last=True)

    def _where(self, sample: int) -> str:
        """``sample N (S s)``: a place in the file, at the file's own rate."""
        return f"sample {sample} ({sample / self.source_rate:.3f} s)"

    def _decodable_from(self, start: int) -> int:
        """The first sample at or after ``start`` (where a block that failed to decode began) that
        cannot be decoded, found by decoding again from ``start`` in steps of
        :data:`LOCATE_STEP` samples; ``start`` when the file cannot even be reopened there."""
        done = start
        try:
            with soundfile.SoundFile(str(self.path)) as f:
                if start:
                    f.seek(start)
                while got := f.read(LOCATE_STEP, dtype="float32", always_2d=True).shape[0]:
                    done += got
        except (soundfile.LibsndfileError, RuntimeError):
            return done
        return start  # decoded this time: the failure is not at a place in the file


LOCATE_STEP = 256
"""Samples decoded at a time when finding where a damaged file stops decoding (the reported place
is at most this many samples before the damage: 6 ms at 44.1 kHz)."""


def load_audio(path: str | Path, sample_rate: int = DEFAULT_SAMPLE_RATE) -> Audio:
    """Read an audio file as mono float32 at ``sample_rate`` Hz.

    Raises:
        AudioError: the file is missing, unreadable, empty or holds non-finite samples.
    """
    reader = AudioReader(path, sample_rate)
    samples = np.concatenate(list(reader.blocks())) if reader.n_samples else np.zeros(0, np.float32)
    return Audio(samples=samples, sample_rate=reader.sample_rate, source=reader.source)
