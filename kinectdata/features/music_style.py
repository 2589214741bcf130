"""A song's dance style from its music: song-level descriptors and a nearest-centroid classifier
fitted on songs whose style is known (a dataset's training songs), for the style input
(:mod:`.style_input`).

Why: a network trained on a corpus where most songs are waltzes, given only the spectra and the
pulse, dances one average dance for every song (docs/notebook/2026-12-real-dance-variety.md); told
the style, it can learn one dance per style. The style of a training song is its manifest's; of
any other song, it is what this classifier hears.

The descriptors (:data:`DESCRIPTORS`, :func:`song_descriptors`) are those that tell ballroom styles
apart and that a stretch of the tempo (pitch kept) moves little:

- ``metre``: the bar-to-bar similarity of beat spectra at 3 beats minus that at 4
  (:func:`~kinectdata.features.metre.bar_similarity`): a waltz is in 3;
- ``tempo``: log2 of the median beat rate (beats per minute) of librosa's tracker: a cha-cha
  (~120-128 BPM) is faster than a rumba (~100-108). The classifier compares it with octaves set
  aside (modulo one octave): the tracker reports some songs at twice their beat, and a waltz heard
  at 174 is as much a waltz as one heard at 87;
- ``onset_cv``: the onset strength's coefficient of variation (how percussive the music is);
- ``centroid``, ``flatness``: the logarithm of the mean spectral centroid (Hz) and flatness (timbre).

The classifier (:class:`MusicStyleClassifier`) scales each descriptor by its spread within the
styles (pooled), takes each style's mean (the tempo's: its circular mean modulo an octave, as
:func:`usual_tempo`), and names the style whose mean is nearest: every style
counts alike however many songs it has (a corpus with 27 waltzes and 2 cha-chas does not make every
song a waltz). Labelled songs without a dance (a corpus's songs whose motion is lost, a collection of
dance music) teach it too: with 3 cha-chas and 5 rumbas, every labelled song counts.

It also keeps each style's usual tempo (:attr:`MusicStyleClassifier.tempi`): the beat rate its danced
songs share once octaves are set aside (librosa's tracker reports some waltzes at twice their beat), so that
a song far from its style's tempo can be played to a network at its style's (:meth:`~MusicStyleClassifier.tempo_factor`,
:mod:`kinectdata.inference.style_tempo`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.core.librosa_import import import_librosa
from kinectdata.features.beats import music_beats
from kinectdata.features.metre import bar_similarity, beat_descriptors

__all__ = [
    "DESCRIPTORS",
    "HEARING_VERSION",
    "MusicStyleClassifier",
    "TooLittleMusic",
    "song_descriptors",
    "usual_tempo",
]

DESCRIPTORS = ("metre", "tempo", "onset_cv", "centroid", "flatness")
"""The song-level descriptors, in the order :func:`song_descriptors` returns them (module docstring)."""
_TEMPO = DESCRIPTORS.index("tempo")

HEARING_VERSION = 2
"""How the classifier hears (1: the tempo compared as is; 2: modulo one octave). A dataset build's key
holds it, so that a dataset whose features hear the style is built again when the hearing changes."""


class TooLittleMusic(KinectDataError):
    """A song too short or too quiet to tell its style from (fewer than :data:`MIN_BEATS` beats)."""


MIN_BEATS = 10
"""Beats a song needs to be described: the metre compares beats two bars of 4 apart."""

_HOP_S = 0.01
_N_FFT = 1024
_FLOOR = 1e-10


def song_descriptors(samples: np.ndarray, sample_rate: float) -> np.ndarray:
    """[len(DESCRIPTORS)] float64: the song-level descriptors of mono music ``samples`` [S]
    (full scale -1..1) at ``sample_rate`` Hz (module docstring).

    Raises:
        TooLittleMusic: fewer than :data:`MIN_BEATS` beats (too short or silent to tell).
        KinectDataError: librosa missing.
    """
    librosa = import_librosa("telling a song's style")
    y = np.asarray(samples, np.float32)
    beats, _ = music_beats(y, sample_rate)
    if beats.size < MIN_BEATS:
        raise TooLittleMusic(f"telling a song's style needs at least {MIN_BEATS} beats of music, got {beats.size}")
    described = beat_descriptors(y, sample_rate, beats)
    metre = bar_similarity(described, 3) - bar_similarity(described, 4)
    tempo = np.log2(60.0 / np.median(np.diff(beats)))
    hop = max(1, round(sample_rate * _HOP_S))
    onsets = librosa.onset.onset_strength(y=y, sr=sample_rate, hop_length=hop)
    onset_cv = onsets.std() / max(onsets.mean(), _FLOOR)
    spectrum = np.abs(librosa.stft(y, n_fft=_N_FFT, hop_length=_N_FFT // 2))
    centroid = librosa.feature.spectral_centroid(S=spectrum, sr=sample_rate)[0]
    flatness = librosa.feature.spectral_flatness(S=spectrum)[0]
    return np.array(
        [metre, tempo, onset_cv, np.log(centroid.mean() + _FLOOR), np.log(flatness.mean() + _FLOOR)], np.float64
    )


@dataclass(frozen=True)
class MusicStyleClassifier:
    """The style whose songs' mean descriptors are nearest (module docstring).

    Attributes:
        styles: the styles it names, sorted, [K].
        centres: [K][D] each style's mean descriptors, in scaled units.
        mean: [D] the descriptors' mean over the fitted songs.
        scale: [D] their pooled spread within the styles.
        songs: how many songs it was fitted on.
        leave_one_out: how many of them it names right when each is left out of the fit in turn.
        tempi: [K] each style's usual tempo, beats per minute (:func:`usual_tempo` of its danced
            songs' tempo descriptors); empty for a classifier saved before it was kept.
        undanced: how many of the ``songs`` had no dance (labelled music only): they teach the
            hearing, not the tempi.
        octave_free: the tempo descriptor is compared modulo one octave (every fit since
            :data:`HEARING_VERSION` 2; False for a classifier saved before, which compared it as is).
    """

    styles: tuple[str, ...]
    centres: tuple[tuple[float, ...], ...]
    mean: tuple[float, ...]
    scale: tuple[float, ...]
    songs: int = 0
    leave_one_out: int = 0
    tempi: tuple[float, ...] = ()
    undanced: int = 0
    octave_free: bool = False

    def __post_init__(self) -> None:
        d = len(DESCRIPTORS)
        if self.tempi and (len(self.tempi) != len(self.styles) or not all(t > 0 for t in self.tempi)):
            raise ConfigError("a music style classifier's tempi hold one positive tempo per style")
        if len(self.styles) < 1 or len(self.centres) != len(self.styles):
            raise ConfigError("a music style classifier needs one centre per style")
        if any(len(c) != d for c in self.centres) or len(self.mean) != d or len(self.scale) != d:
            raise ConfigError(f"a music style classifier's centres, mean and scale hold {d} descriptors each")
        if not all(s > 0 for s in self.scale):
            raise ConfigError("a music style classifier's scale must be positive")
        if not 0 <= self.undanced <= self.songs:
            raise ConfigError("a music style classifier's undanced songs are some of its songs")

    @classmethod
    def fit(
        cls, descriptors: np.ndarray, styles: Sequence[str], danced: Sequence[bool] | None = None
    ) -> MusicStyleClassifier:
        """Fit on songs' ``descriptors`` [N, D] (:func:`song_descriptors`) and their ``styles`` [N].

        ``danced`` [N]: whether each song has a dance a network learns from (default all). Every song
        teaches the hearing; a style's usual tempo is its danced songs' (the tempo a network learned
        it at), all of its songs' when none is danced.
        """
        x = np.asarray(descriptors, np.float64)
        labels = np.asarray(list(styles))
        if x.ndim != 2 or x.shape[1] != len(DESCRIPTORS) or x.shape[0] != labels.size or labels.size < 2:
            raise KinectDataError(
                f"fitting a music style classifier needs at least 2 songs with {len(DESCRIPTORS)} descriptors "
                f"and a style each; got descriptors {x.shape} and {labels.size} styles"
            )
        shown = np.ones(labels.size, bool) if danced is None else np.asarray(list(danced), bool)
        if shown.shape != labels.shape:
            raise KinectDataError(f"danced: one flag per song ({labels.size}), got {shown.size}")
        if not np.isfinite(x).all():
            raise KinectDataError("a music style classifier's songs' descriptors must be finite")
        fitted = _fit(x, labels)
        right = sum(_fit(np.delete(x, i, 0), np.delete(labels, i)).predict(x[i]) == labels[i] for i in range(len(x)))
        tempi = []
        for style in fitted.styles:
            mine = labels == style
            taught = mine & shown if (mine & shown).any() else mine
            tempi.append(usual_tempo(2.0 ** x[taught, _TEMPO]))
        return cls(
            fitted.styles,
            fitted.centres,
            fitted.mean,
            fitted.scale,
            songs=len(x),
            leave_one_out=int(right),
            tempi=tuple(tempi),
            undanced=int((~shown).sum()),
            octave_free=True,
        )

    def predict(self, descriptors: np.ndarray) -> str:
        """The style of a song with ``descriptors`` [D]."""
        scale = np.array(self.scale)
        centres = np.array(self.centres) * scale + np.array(self.mean)
        song = np.asarray(descriptors, np.float64)
        off = _off(centres, song) if self.octave_free else centres - song
        distance = ((off / scale) ** 2).sum(axis=1)
        return self.styles[int(distance.argmin())]

    def style_of(self, samples: np.ndarray, sample_rate: float) -> str:
        """The style of mono music ``samples`` [S] at ``sample_rate`` Hz."""
        return self.predict(song_descriptors(samples, sample_rate))

    def tempo_factor(self, descriptors: np.ndarray, band: float, style: str | None = None) -> tuple[float, str]:
        """How much faster to play a song with ``descriptors`` [D] so that its tempo lies within a
        factor ``1 + band`` (0.08: 8 %) of its style's usual tempo, octaves set aside (a song heard at
        twice its beat is not slowed by half), and that style: ``(factor, style)``, factor 1.0 for a
        song already within the band, else the stretch to the band's nearer edge. The style is
        ``style`` when given (one the classifier names), else the one heard in the descriptors.

        Raises:
            KinectDataError: the classifier keeps no tempi (saved before they were kept: build the
                dataset again).
        """
        if not self.tempi:
            raise KinectDataError(
                "this music style classifier keeps no tempo per style (fitted by an older build): build the dataset "
                "again to play songs at their style's tempo"
            )
        if style is not None and style not in self.styles:
            raise ConfigError(f"style {style!r}: the classifier knows {', '.join(self.styles)}")
        style = style if style is not None else self.predict(descriptors)
        usual = self.tempi[self.styles.index(style)]
        off = np.log2(usual) - float(np.asarray(descriptors, np.float64)[DESCRIPTORS.index("tempo")])
        off -= np.round(off)  # to the nearest octave of the usual tempo: within half an octave
        edge = np.log2(1.0 + band)
        if abs(off) <= edge:
            return 1.0, style
        return float(2.0 ** (off - np.sign(off) * edge)), style

    def to_dict(self) -> dict[str, Any]:
        return {
            "styles": list(self.styles),
            "centres": [list(c) for c in self.centres],
            "mean": list(self.mean),
            "scale": list(self.scale),
            "songs": self.songs,
            "leave_one_out": self.leave_one_out,
            "tempi": list(self.tempi),
            "undanced": self.undanced,
            "octave_free": self.octave_free,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MusicStyleClassifier:
        try:
            return cls(
                tuple(str(s) for s in d["styles"]),
                tuple(tuple(float(v) for v in c) for c in d["centres"]),
                tuple(float(v) for v in d["mean"]),
                tuple(float(v) for v in d["scale"]),
                int(d.get("songs", 0)),
                int(d.get("leave_one_out", 0)),
                tuple(float(t) for t in d.get("tempi", ())),
                int(d.get("undanced", 0)),
                bool(d.get("octave_free", False)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"not a music style classifier ({exc})") from exc


def usual_tempo(tempi_bpm: np.ndarray) -> float:
    """The tempo [N] songs share once octaves are set aside, beats per minute: the circular mean of
    their log2 tempi modulo one octave (a song reported at twice its beat counts as at its beat),
    placed in the octave most of them are in (the lower of two as common). One song: its own tempo."""
    t = np.log2(np.asarray(tempi_bpm, np.float64))
    if t.size == 0 or not np.isfinite(t).all():
        raise KinectDataError("a style's usual tempo needs at least one finite, positive tempo")
    phase = np.angle(np.exp(2j * np.pi * t).mean()) / (2 * np.pi)
    octaves, counts = np.unique(np.round(t - phase), return_counts=True)
    return float(2.0 ** (phase + octaves[np.argmax(counts)]))


def _fit(x: np.ndarray, labels: np.ndarray) -> MusicStyleClassifier:
    styles = tuple(sorted(set(labels.tolist())))
    mean = x.mean(axis=0)
    means = []
    for s in styles:
        mine = x[labels == s].mean(axis=0)
        mine[_TEMPO] = np.log2(usual_tempo(2.0 ** x[labels == s, _TEMPO]))
        means.append(mine)
    within = np.concatenate([_off(x[labels == s], m) for s, m in zip(styles, means)])
    dof = max(len(x) - len(styles), 1)
    scale = np.sqrt((within**2).sum(axis=0) / dof)
    overall = _off(x, mean).std(axis=0)
    # a descriptor no style varies in (one song per style) falls back to its spread over all songs, then to 1
    scale = np.where(scale > 0, scale, np.where(overall > 0, overall, 1.0))
    centres = tuple(tuple(((m - mean) / scale).tolist()) for m in means)
    return MusicStyleClassifier(styles, centres, tuple(mean.tolist()), tuple(scale.tolist()), octave_free=True)


def _off(x: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """[N, D] songs' descriptors ``x`` [N, D] less ``centre`` [D], the tempo's within half an octave."""
    off = x - centre
    off[:, _TEMPO] -= np.round(off[:, _TEMPO])
    return off
