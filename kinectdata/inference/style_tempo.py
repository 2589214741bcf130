"""A song played to the network at its style's tempo, and the dance played back at the song's
(``train --style-tempo BAND``).

Why: a network learns a style's dance at the tempi its training songs have (on Dance with Melody
the waltzes within 4 % of 86 beats a minute). Played the same waltz 15 % slower or 18 % faster, the
cdhc model danced it at another metrical level or at none in a fifth of the tempo control's pairs
(docs/notebook/2026-12-real-dance-variety.md), and a song in none of the data may be at any tempo.
A dancer dances the same steps faster or slower; so does a run with ``style_tempo``:

1. the style of the whole song is heard and its tempo read (the classifier the dataset build fitted
   on the training songs, :meth:`~kinectdata.features.music_style.MusicStyleClassifier.tempo_factor`:
   librosa's beat tracker, octaves set aside); a dataset's recording keeps the style the build gave
   its song (told, or heard in the whole file), and ``evaluate`` does not hear again the stretch of
   it the dance covers;
2. a song within a factor ``1 + band`` (0.08: 8 %) of its style's usual tempo is danced as it is;
   any other is played faster or slower with its pitch kept (:func:`~kinectdata.align.stretch.stretch_audio`:
   SoX, or librosa without it) to the band's nearer edge, with the style input of the song as heard
   before, and the network dances to that;
3. the dance is warped back onto the song's clock (:func:`warp_back`): its steps keep the song's time.

The run keeps ``band`` in its ``config.json`` (``train.style_tempo``; absent or None: every song as it
is, as runs written before it). ``generate`` plays songs so, and ``evaluate`` plays every whole song it
dances (the split's recordings, each version of the tempo control; its kind is told which,
:meth:`~kinectdata.inference.turning.TurnedKind.know_played`, and warps the network's frames back
before the drawn turning, travel and low-pass, as ``generate`` does). A control that dances the opening
of a song it played (a swapped song cut to its partner's length, the noise cut to its song's) dances
it from the played frames that cover it, as the whole song is danced. The tempo control then scores
the run as a user gets it: its versions played faster and slower are each brought back near the
style's tempo, so the pairs it keeps are this module's doing as much as the network's (``evaluate
--style-tempo 0`` scores the network alone). ``live`` cannot (its music arrives as it plays, and a
network cannot hear it faster than it arrives) and dances every song at its own tempo, as do the kept
epoch's validation songs in training. A song too short or too quiet to tell its style or tempo is
danced as it is.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.features import FeatureConfig, style_input_of
from kinectdata.features.music_style import TooLittleMusic, song_descriptors

__all__ = [
    "AS_IT_IS",
    "check_band",
    "on_song_clock",
    "run_style_tempo",
    "style_tempo_factor",
    "style_tempo_line",
    "warp_back",
]

AS_IT_IS = "every song at its own tempo"
""":func:`style_tempo_line` of a run that plays every song as it is."""


def check_band(band: float, features: FeatureConfig) -> None:
    """Raise :class:`ConfigError` unless ``band`` is a share of at least 0 and ``features`` hear the
    song's style (a ``*_style`` preset), whose classifier tells each style's tempo."""
    if not (isinstance(band, (int, float)) and 0 <= band < 1):
        raise ConfigError(f"style_tempo must be a share of the tempo from 0 to below 1 (0.08: 8 %), not {band!r}")
    if style_input_of(features) is None:
        raise ConfigError(
            "style_tempo: the features must hear the song's style (a *_style preset, e.g. "
            "listen_to_dance_rhythm_bars_style) to know the style's tempo"
        )


def run_style_tempo(config: dict[str, Any]) -> float | None:
    """The band a run's ``config.json`` plays songs at their style's tempo within, or None."""
    band = config.get("train", {}).get("style_tempo")
    return float(band) if band else None  # None or 0: off, as train takes 0


def style_tempo_line(band: float | None) -> str:
    """What a run does to a song's tempo, for a printout (:data:`AS_IT_IS` when nothing)."""
    if band is None:
        return AS_IT_IS
    return f"a song more than {100 * band:g} % off its style's usual tempo is danced at it, then played back at its own"


def style_tempo_factor(
    samples: np.ndarray, features: FeatureConfig, band: float, style: str | None = None
) -> tuple[float, str | None]:
    """``(factor, style)``: how much faster to play mono ``samples`` [S] (a whole song at the
    features' sample rate) so that its tempo lies within a factor ``1 + band`` of its style's usual
    tempo (1.0: as it is), and that style (``style`` when given, else the one heard); ``(1.0, None)``
    for a song whose style or tempo cannot be told (too few beats).

    Raises:
        ConfigError: features that do not hear the style, or whose classifier is not fitted.
        KinectDataError: a classifier that keeps no tempi (a dataset built before them).
    """
    part = style_input_of(features)
    if part is None or part.classifier is None:
        raise ConfigError("style_tempo: the features hear no style (no fitted music style classifier)")
    try:
        described = song_descriptors(samples, part.sample_rate)
    except TooLittleMusic:
        return 1.0, None
    return part.classifier.tempo_factor(described, band, style)


def warp_back(values: np.ndarray, rate: float, frames: int | None = None) -> np.ndarray:
    """Frames [T', ...] made for a song played at ``rate``, on the original song's clock: frame k of
    the result is frame k / ``rate`` (linear interpolation between frames), for ``frames`` frames
    (default: as many as the frames cover, ``floor((T' - 1) * rate) + 1``; past the last frame it is
    held). A dance that keeps time with the music comes back as it would be at x1.00.

    Raises:
        KinectDataError: fewer than two frames.
    """
    p = np.asarray(values, np.float64)
    if p.ndim < 2 or p.shape[0] < 2:
        raise KinectDataError(f"frames to warp must be [T, ...] with T >= 2, got shape {p.shape}")
    n = int(np.floor((p.shape[0] - 1) * rate + 1e-9)) + 1 if frames is None else int(frames)
    at = np.minimum(np.arange(n) / rate, p.shape[0] - 1)  # fractional source frames, the last one held
    low = np.minimum(np.floor(at).astype(np.int64), p.shape[0] - 2)
    share = (at - low).reshape((n,) + (1,) * (p.ndim - 1))
    return (1 - share) * p[low] + share * p[low + 1]


def on_song_clock(run: np.ndarray, first_pose: np.ndarray, factor: float, frames: int) -> np.ndarray:
    """A free run [T'-1, D] (frames 1.. after ``first_pose`` [D]) of a song's music played ``factor``
    times as fast, on the song's own ``frames`` (T) frames: [T-1, D], frame 0 still the first pose."""
    whole = np.concatenate([np.asarray(first_pose, run.dtype)[None], run])
    return warp_back(whole, factor, frames)[1:].astype(run.dtype)
