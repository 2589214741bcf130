"""Does the dance keep time with the song when the song is played faster or slower?

The tempo control (docs/rhythm.md): each test song is played at other tempi with its pitch kept
(:data:`TEMPO_RATES`, :func:`~kinectdata.align.stretch.stretch_audio`), the model dances to each
version from the same first pose, and the dance made for a stretched song is warped back in time by
the stretch (:func:`warp_back`: at x1.18 its time is multiplied by 1.18). A model that keeps time
with the music makes a dance that, warped back, repeats like its dance of the song at x1.00; a model
that ignores the tempo makes a dance that repeats like it without the warp.

How a dance repeats is read from the autocorrelation of its joints' heights over
:data:`LAG_RANGE_S` of lag (:func:`~kinectdata.evaluation.beat_following.vertical_autocorrelation`,
slow drift removed): a whole curve, so that no period estimate can be wrong by an octave. A pair
(song, tempo) **follows** when the warped dance's curve correlates better with the x1.00 dance's
curve than the unwarped one does. A dance that repeats alike at every tempo, or not at all,
follows in half the pairs by chance: the p-value is the binomial tail of the pairs followed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from math import comb
from typing import Any

import numpy as np

from kinectdata.align.stretch import stretch_audio
from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.beat_following import vertical_autocorrelation
from kinectdata.inference.style_tempo import warp_back

TEMPO_RATES = (0.85, 1.18)
"""The tempo factors each song is played at besides x1.00."""
LAG_RANGE_S = (0.3, 4.5)
"""Seconds of lag over which the autocorrelation curves are compared: from below the fastest
dance's beat to past two bars of the slowest waltz."""
FOLLOWS_AT_LEAST = 12 / 14
"""The share of pairs the benchmark's goal c asks to follow (12 of 14 for 7 songs at two tempi)."""


@dataclass(frozen=True)
class TempoPair:
    """One song at one tempo.

    Attributes:
        song: the song's name.
        rate: the tempo factor it was played at.
        warped: correlation of the warped-back dance's autocorrelation curve with the x1.00 dance's.
        unwarped: the same for the dance as it was made.
    """

    song: str
    rate: float
    warped: float
    unwarped: float

    @property
    def follows(self) -> bool:
        return bool(self.warped > self.unwarped)


@dataclass(frozen=True)
class TempoControl:
    """The tempo control over a set of songs (:func:`tempo_control`).

    Attributes:
        pairs: every (song, tempo) pair.
        rates: the tempo factors played.
        stretcher: the program that changed the tempo (:data:`~kinectdata.align.stretch.STRETCHERS`).
    """

    pairs: tuple[TempoPair, ...]
    rates: tuple[float, ...]
    stretcher: str

    @property
    def followed(self) -> int:
        return sum(p.follows for p in self.pairs)

    @property
    def p_value(self) -> float:
        """One-sided binomial probability of following in this many pairs or more at chance (half)."""
        n, k = len(self.pairs), self.followed
        return sum(comb(n, i) for i in range(k, n + 1)) / 2**n

    @property
    def keeps_time(self) -> bool:
        """At least :data:`FOLLOWS_AT_LEAST` of the pairs follow."""
        return bool(self.pairs) and self.followed >= FOLLOWS_AT_LEAST * len(self.pairs) - 1e-9

    def verdict(self) -> str:
        rates = ", ".join(f"x{r:g}" for r in self.rates)
        p = "< 0.001" if self.p_value < 0.001 else f"= {self.p_value:.2g}"
        return (
            f"keeps time with the song at other tempi: {'yes' if self.keeps_time else 'no'} ({self.followed} of "
            f"{len(self.pairs)} pairs follow: the dance for the song at {rates}, warped back by the tempo, repeats "
            f"more like the dance at x1.00 than unwarped; chance half, p {p}; wanted at least "
            f"{FOLLOWS_AT_LEAST:.0%}; the songs stretched by {self.stretcher})"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "pairs": [
                {"song": p.song, "rate": p.rate, "warped": p.warped, "unwarped": p.unwarped, "follows": p.follows}
                for p in self.pairs
            ],
            "rates": list(self.rates),
            "stretcher": self.stretcher,
            "followed": self.followed,
            "p_value": self.p_value,
            "keeps_time": self.keeps_time,
            "verdict": self.verdict(),
        }


def repetition_curve(positions: np.ndarray, fps: float, lags_s: tuple[float, float] = LAG_RANGE_S) -> np.ndarray:
    """The autocorrelation of the joints' heights (y up) at lags ``lags_s[0]``..``lags_s[1]`` s, one
    value per frame of lag (:func:`~kinectdata.evaluation.beat_following.vertical_autocorrelation`);
    NaN where no joint counts."""
    curve = vertical_autocorrelation(positions, None, fps, lags_s[1])
    first = int(round(lags_s[0] * fps))
    if len(curve) - first < 3:
        raise KinectDataError(
            f"{len(positions)} frames are too few for the tempo control's lags of {lags_s[0]:g}-{lags_s[1]:g} s"
        )
    return curve[first:]


def _similarity(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two curves over the lags both have (-1 when either is flat or missing)."""
    n = min(len(a), len(b))
    a, b = a[:n], b[:n]
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return -1.0
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def tempo_pair(song: str, rate: float, at_one: np.ndarray, stretched: np.ndarray, fps: float) -> TempoPair:
    """The pair of one song at ``rate``: ``at_one`` [T, J, C] its dance at x1.00, ``stretched``
    [T', J, C] its dance at ``rate``, both at ``fps``."""
    reference = repetition_curve(at_one, fps)
    warped = repetition_curve(warp_back(stretched, rate), fps)
    unwarped = repetition_curve(stretched, fps)
    return TempoPair(song, float(rate), _similarity(warped, reference), _similarity(unwarped, reference))


@dataclass(frozen=True)
class TempoSong:
    """A song for the tempo control.

    Attributes:
        name: the song.
        samples: [S] its music, mono, on the motion's clock (sample 0 at frame 0).
        first_pose: [D] the pose the model starts from.
        beats_per_bar: the song's metre, for features that count bars.
    """

    name: str
    samples: np.ndarray
    first_pose: np.ndarray
    beats_per_bar: int | None = None


def tempo_control(
    songs: Sequence[TempoSong],
    generate_many: Callable[[list[tuple[np.ndarray, np.ndarray]]], list[np.ndarray]],
    features_of: Callable[..., np.ndarray],
    fps: float,
    *,
    rates: Sequence[float] = TEMPO_RATES,
    stretcher: str | None = None,
) -> TempoControl:
    """Play every song at x1.00 and at each of ``rates``, dance to each, and read every pair
    (module docstring).

    Args:
        songs: the songs.
        generate_many: ``[(features [T, ...], first_pose [D]), ...] -> [positions [T-1, J, C], ...]``:
            the model run free, its output as positions (y up).
        features_of: ``features_of(samples [S], beats_per_bar=...) -> features [T, ...]`` on the motion
            clock at ``fps``; its ``sample_rate`` attribute gives the rate (default 16 kHz).
        fps: motion frames per second.
        rates: the tempo factors.
        stretcher: the program that changes the tempo (None: the first installed).

    Raises:
        AudioError: no program to change the tempo with.
        KinectDataError: a song too short for the lags.
    """
    from kinectdata.align.stretch import available_stretcher

    if not songs:
        raise KinectDataError("the tempo control needs at least one song")
    sample_rate = getattr(features_of, "sample_rate", 16000)
    used = stretcher or available_stretcher() or "sox"
    jobs, keys = [], []
    for song in songs:
        for rate in (1.0, *rates):
            audio = song.samples if rate == 1.0 else stretch_audio(song.samples, rate, sample_rate, used)
            jobs.append((features_of(audio, beats_per_bar=song.beats_per_bar), song.first_pose))
            keys.append((song.name, rate))
    made = dict(zip(keys, generate_many(jobs)))
    pairs = tuple(
        tempo_pair(song.name, rate, made[(song.name, 1.0)], made[(song.name, rate)], fps)
        for song in songs
        for rate in rates
    )
    return TempoControl(pairs, tuple(float(r) for r in rates), used)
