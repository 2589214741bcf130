"""Envelopes of an audio signal for alignment, computed block by block in one pass.

Offset estimation (:mod:`kinectdata.align.offset`) needs only these small summaries of the audio, not
the audio itself, so long recordings are analysed with bounded memory:

- ``clap_energy`` [F]: mean square of the audio high-passed at 1 kHz (4th-order Butterworth),
  in consecutive 5 ms frames (frame i covers samples [i * 5 ms, (i + 1) * 5 ms));
- ``onset`` [K]: spectral-flux onset strength at exactly 100 Hz (index k at k / 100 s): the summed
  positive change of log(1 + 100 |X|) between consecutive frames of a 40 ms Hann STFT with a
  10 ms hop, interpolated onto the 100 Hz grid;
- ``mean_square``: of the whole signal (full scale = 1).

:func:`audio_envelopes` gives the same numbers whether the audio comes in one block or many.
Audio below 8 kHz is resampled to 16 kHz first (the 1 kHz high-pass needs the bandwidth).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import soxr

from kinectdata.align.audio import Audio

CLAP_FRAME_S = 0.005
ONSET_RATE = 100.0  # Hz
ANALYSIS_RATE = 16000  # Hz, for audio below MIN_RATE
MIN_RATE = 8000  # Hz
_CHUNK = 4096  # frames processed at a time


@dataclass(frozen=True)
class AudioEnvelopes:
    """See the module docstring. ``sample_rate`` is the analysed rate, ``duration`` in seconds."""

    sample_rate: int
    duration: float
    clap_energy: np.ndarray
    onset: np.ndarray
    mean_square: float

    @classmethod
    def of(cls, audio: Audio) -> AudioEnvelopes:
        """Envelopes of in-memory audio (the same numbers as streaming it)."""
        return audio_envelopes([audio.samples], audio.sample_rate)


class _Framer:
    """Collects a stream into frames of ``size`` samples starting every ``hop`` samples."""

    def __init__(self, size: int, hop: int):
        self.size, self.hop = size, hop
        self.buffer = np.zeros(0, np.float64)

    def push(self, x: np.ndarray) -> np.ndarray:
        """[M, size] frames completed by ``x`` (in order)."""
        buf = np.concatenate([self.buffer, x]) if self.buffer.size else x
        if buf.size < self.size:  # no frame complete yet (audio shorter than one frame so far)
            self.buffer = buf
            return np.zeros((0, self.size), buf.dtype)
        m = (buf.size - self.size) // self.hop + 1
        frames = np.lib.stride_tricks.sliding_window_view(buf, self.size)[:: self.hop][:m]
        self.buffer = buf[m * self.hop :]
        return frames


def audio_envelopes(blocks: Iterable[np.ndarray], sample_rate: int) -> AudioEnvelopes:
    """Compute :class:`AudioEnvelopes` from consecutive mono blocks at ``sample_rate`` Hz."""
    from scipy import signal  # imported here: it takes longer to import than most commands run

    stream = None
    if sample_rate < MIN_RATE:
        stream = soxr.ResampleStream(sample_rate, ANALYSIS_RATE, 1, dtype="float32", quality="HQ")
        sample_rate = ANALYSIS_RATE
    sr = sample_rate
    sos = signal.butter(4, 1000.0, btype="highpass", fs=sr, output="sos")
    zi = np.zeros((sos.shape[0], 2))
    clap_hop = int(round(CLAP_FRAME_S * sr))
    onset_hop = max(1, int(round(sr / ONSET_RATE)))
    clap_frames = _Framer(clap_hop, clap_hop)
    stft_frames = _Framer(4 * onset_hop, onset_hop)
    window = signal.get_window("hann", 4 * onset_hop)
    window_sum = window.sum()
    energy, flux = [], []
    previous: list[np.ndarray] = []  # the last STFT frame's log magnitude, for the next difference
    total, square_sum = 0, 0.0

    def consume(x: np.ndarray) -> None:
        nonlocal zi, total, square_sum
        x = np.asarray(x, dtype=np.float64)
        if not x.size:  # an empty block (a resampler's flush may be one) adds nothing
            return
        total += x.size
        square_sum += float(np.dot(x, x))
        high, zi = signal.sosfilt(sos, x, zi=zi)
        frames = clap_frames.push(high)
        for s in range(0, frames.shape[0], _CHUNK):  # chunks bound the temporaries of one big block
            energy.append(np.square(frames[s : s + _CHUNK]).mean(axis=1))
        frames = stft_frames.push(x)
        for s in range(0, frames.shape[0], _CHUNK):
            spectrum = np.abs(np.fft.rfft(frames[s : s + _CHUNK] * window, axis=1))
            logmag = np.concatenate([*previous, np.log1p(100.0 * spectrum / window_sum)])
            flux.append(np.maximum(np.diff(logmag, axis=0), 0.0).sum(axis=1))
            previous[:] = [logmag[-1:]]

    for block in blocks:
        consume(block if stream is None else stream.resample_chunk(np.asarray(block, np.float32), last=False))
    if stream is not None:
        consume(stream.resample_chunk(np.zeros(0, np.float32), last=True))

    flux = np.concatenate(flux) if flux else np.zeros(0)
    # STFT frame i is centred on sample (i + 2) * hop; difference i belongs to frame i + 1
    times = (np.arange(flux.size) + 3) * onset_hop / sr
    duration = total / sr
    grid = np.arange(0.0, duration, 1.0 / ONSET_RATE)
    onset = np.interp(grid, times, flux, left=0.0, right=0.0) if flux.size else np.zeros(grid.size)
    return AudioEnvelopes(
        sample_rate=sr,
        duration=duration,
        clap_energy=np.concatenate(energy) if energy else np.zeros(0),
        onset=onset,
        mean_square=square_sum / max(total, 1),
    )
