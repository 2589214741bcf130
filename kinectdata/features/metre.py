"""The music's metre: how many beats make a bar (a waltz 3, most dance music 4), given or estimated.

:func:`estimate_beats_per_bar` looks for what repeats from bar to bar: each beat is described by
the mean log-mel spectrum of its span (what sounds on it: the bass on the downbeat, the chords on
the off-beats of a waltz), and the beats k and k + m are compared (cosine similarity of their
standardised descriptions) for a bar of m = 3 and m = 4 beats and for two such bars. Music in 3
repeats best every 3 and 6 beats, music in 4 every 4 and 8 (the method of Gouyon and Herrera 2003,
"Determination of the meter of musical audio signals: seeking recurrences in beat segment
descriptors", with log-mel bands as the descriptors). On the Dance with Melody corpus's 43 songs it
tells the waltzes from the other dances as docs/rhythm.md reports.

:func:`recording_metre` gives a recording its metre: the recordings manifest's ``beats_per_bar``
when it has one, else the one the caller gives (``evaluate --beats-per-bar``), else the estimate
(from the beats given, or tracked with :func:`~kinectdata.features.beats.music_beats`). A dataset
build asks for it when its features count the song's bars (the pulse's ``bar_levels``),
``evaluate`` for its metrical levels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.librosa_import import import_librosa
from kinectdata.features.beats import music_beats

CANDIDATES = (3, 4)
"""The bar lengths told apart (in beats)."""
MEL_BANDS = 40
HOP_S = 0.01
MIN_BEATS = 17
"""Fewer beats than this (two bars of 8 and one more) leave too few pairs to compare."""


@dataclass(frozen=True)
class Metre:
    """A song's metre and where it came from.

    Attributes:
        beats_per_bar: beats in a bar.
        source: ``manifest`` (the recordings manifest says), ``given`` (the caller says),
            ``estimated`` (from the music), ``dataset`` (the metre a dataset build found for
            features that count bars, from the whole song) or ``default`` (4: nothing else was
            possible).
        scores: for an estimate, per candidate bar length, the mean similarity of beats one and two
            bars apart (the larger wins); empty otherwise.
    """

    beats_per_bar: int
    source: str
    scores: dict[int, float]

    def describe(self) -> str:
        if not self.scores:
            return f"{self.beats_per_bar} beats per bar ({self.source})"
        detail = ", ".join(f"{m}: {s:.3f}" for m, s in sorted(self.scores.items()))
        return f"{self.beats_per_bar} beats per bar ({self.source}; bar-to-bar similarity {detail})"


def beat_descriptors(samples: np.ndarray, sample_rate: float, beats_s: np.ndarray) -> np.ndarray:
    """[K, MEL_BANDS] the mean log-mel spectrum (dB) between consecutive beats (K = beats - 1),
    each band standardised over the beats."""
    librosa = import_librosa("estimating the metre")
    y = np.asarray(samples, dtype=np.float32)
    hop = max(1, round(sample_rate * HOP_S))
    mel = librosa.feature.melspectrogram(y=y, sr=sample_rate, hop_length=hop, n_mels=MEL_BANDS, n_fft=2048)
    db = librosa.power_to_db(mel + 1e-10)  # [bands, frames]
    frames = np.clip(np.round(np.asarray(beats_s) * sample_rate / hop).astype(int), 0, db.shape[1])
    described = np.stack(
        [db[:, a:b].mean(axis=1) if b > a else db[:, min(a, db.shape[1] - 1)] for a, b in zip(frames[:-1], frames[1:])]
    )
    spread = described.std(axis=0)
    return (described - described.mean(axis=0)) / np.where(spread > 0, spread, 1.0)


def bar_similarity(descriptors: np.ndarray, beats_per_bar: int) -> float:
    """Mean cosine similarity of beat descriptions one bar and two bars apart ([K, F] descriptors)."""
    unit = descriptors / np.maximum(np.linalg.norm(descriptors, axis=1, keepdims=True), 1e-12)
    lags = [beats_per_bar, 2 * beats_per_bar]
    return float(np.mean([np.mean(np.sum(unit[:-lag] * unit[lag:], axis=1)) for lag in lags]))


def estimate_beats_per_bar(samples: np.ndarray, sample_rate: float, beats_s: np.ndarray) -> Metre:
    """The metre of mono music (3 or 4 beats per bar) from its beats (module docstring).

    Args:
        samples: [S] mono audio, full scale -1..1.
        sample_rate: Hz.
        beats_s: [B] beat times in seconds from the first sample.

    Returns:
        The :class:`Metre` (source ``estimated``).

    Raises:
        KinectDataError: fewer than :data:`MIN_BEATS` beats, or librosa missing.
    """
    beats = np.asarray(beats_s, dtype=np.float64)
    if beats.size < MIN_BEATS:
        raise KinectDataError(f"estimating the metre needs at least {MIN_BEATS} beats, got {beats.size}")
    descriptors = beat_descriptors(samples, sample_rate, beats)
    scores = {m: bar_similarity(descriptors, m) for m in CANDIDATES}
    return Metre(max(scores, key=scores.get), "estimated", scores)


def recording_metre(
    listed: int | None,
    samples: np.ndarray | None,
    sample_rate: float,
    beats_s: np.ndarray | None = None,
    given: int | None = None,
    found: int | None = None,
) -> Metre:
    """A recording's metre: ``listed`` (its recordings-manifest entry's ``beats_per_bar``), else
    ``given`` (the caller's, e.g. ``evaluate --beats-per-bar``), else ``found`` (the metre a dataset
    build found for features that count bars: the bars the model heard), else estimated from its
    music ``samples`` [S] (mono, ``sample_rate`` Hz) at its beats ``beats_s`` [B] (seconds from
    sample 0; None: tracked here), else 4 (source ``default``: too few beats, no audio or no librosa)."""
    if listed is not None:
        return Metre(int(listed), "manifest", {})
    if given is not None:
        return Metre(int(given), "given", {})
    if found is not None:
        return Metre(int(found), "dataset", {})
    if samples is not None:
        try:
            if beats_s is None:
                beats_s, _ = music_beats(samples, sample_rate)
            return estimate_beats_per_bar(samples, sample_rate, beats_s)
        except KinectDataError:
            pass
    return Metre(4, "default", {})
