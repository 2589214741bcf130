"""The music's beats, tracked with librosa: what the metre (:mod:`.metre`), the rhythm figures and
the listening controls count from. Times are seconds from the first sample."""

from __future__ import annotations

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.librosa_import import import_librosa

__all__ = ["BEAT_TRACKER_HOP_S", "music_beats"]

BEAT_TRACKER_HOP_S = 0.01
"""Seconds between librosa onset frames (its default 512 samples is 32 ms at 16 kHz: too coarse)."""


def music_beats(samples: np.ndarray, sample_rate: float) -> tuple[np.ndarray, float]:
    """Beats of mono music with librosa's dynamic-programming beat tracker (Ellis 2007).

    The onset envelope uses a hop of :data:`BEAT_TRACKER_HOP_S` (10 ms) instead of librosa's 512
    samples, which at 16 kHz would quantise every beat to 32 ms (a 0.5 s period to 0.48 or 0.512 s).
    librosa's other defaults apply (start tempo 120 BPM, weak leading and trailing beats trimmed).

    Args:
        samples: [S] mono audio, full scale -1..1.
        sample_rate: Hz.

    Returns:
        ``(beat_times_s [B], tempo_bpm)``: beat times in seconds from the first sample (B may be 0
        for silence) and librosa's global tempo estimate in beats per minute.
    """
    librosa = import_librosa("music beat tracking")
    y = np.asarray(samples, dtype=np.float32)
    if y.ndim != 1:
        raise KinectDataError(f"music beat tracking needs mono samples [S], got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise KinectDataError(f"music samples contain NaN or infinity at sample {int(np.argmin(np.isfinite(y)))}")
    if not sample_rate > 0:
        raise KinectDataError(f"sample rate must be positive, got {sample_rate}")
    hop = max(1, round(sample_rate * BEAT_TRACKER_HOP_S))
    tempo, beats = librosa.beat.beat_track(y=y, sr=sample_rate, hop_length=hop, units="time")
    return np.asarray(beats, dtype=np.float64), float(np.atleast_1d(tempo)[0])
