"""Does motion follow the music? Its dominant period, the metrical level it sits at, and every rhythm
figure beside its chance level (definitions: docs/rhythm.md, "Beat following and chance levels").

- :func:`dominant_period`: the period of the vertical motion, from the autocorrelation of the joints'
  up-axis trajectories (the analysis of Lee et al. 2018, "Listen to Dance"), looked at up to two bars;
- :func:`metrical_level`: which level of the music's metre that period is (half beat, beat, two
  beats, bar, two bars), within a tolerance of 10 %;
- :func:`beat_following`: over a set of recordings (motion + the music's beats), the share whose
  motion has its dominant period at the beat, the rank correlation of motion period and beat period
  across songs, both Beat Align Scores and the beat F-measure, each with a chance level computed
  from the same motion (the music's beats shifted by random phases; for the period, other songs'
  tempi) and a one-sided p-value, and plain verdicts that say "yes" only when a figure is
  significantly above its chance level;
- :func:`bar_periodicity`: how much a motion repeats after one and two bars of its song (its
  autocorrelation there), which :func:`beat_following` compares with every other pairing of the
  motions with the songs: a listening figure that does not rest on the dominant period alone.

Why chance levels: the Beat Align Score grows with the number of motion beats (speed minima), so a
motion that merely jitters scores high against any beat grid; and any motion's autocorrelation has
some peak near some metrical level. Compared with the same motion against beats it was not made for,
neither can pass for following the music.

Times are seconds; motion frames are on a uniform grid, frame i at ``i / fps`` s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.beat_scores_rows import beat_align_scores, beat_fmeasures
from kinectdata.evaluation.rhythm import (
    BEAT_ALIGN_SIGMA_S,
    DRIFT_WINDOW_S,
    FMEASURE_WINDOW_S,
    autocorrelation_peaks,
    beat_align_score,
    beat_period_s,
    motion_beat_fmeasure,
    motion_beats,
    trajectory_autocorrelation,
)

PERIOD_TOLERANCE = 0.10
"""A period is at a metrical level when within 10 % of it."""
BEATS_PER_BAR = 4
"""Beats per bar when the music's metre is not known (most dance music is in 4)."""
LEVELS = (("half beat", 0.5), ("beat", 1.0), ("two beats", 2.0), ("bar", None), ("two bars", None))
"""The metrical levels looked at, in beats (the bar's from ``beats_per_bar``)."""
DOMINANT_FRACTION = 0.8
"""The dominant period is the shortest-lag autocorrelation peak at least this fraction of the
highest peak's height: a motion that repeats every beat also repeats every two beats and every bar,
with peaks about as high, and its period is the shortest of them."""
MIN_PERIOD_S = 0.2
"""Lags below this are not looked at (300 BPM: faster than any dance beat; sensor jitter lives here)."""
CHANCE_DRAWS = 1000
"""Random phase shifts drawn per recording for the chance levels."""
SIGNIFICANCE = 0.05
"""A verdict says "yes" only when the figure's one-sided p-value against chance is below this."""
TEMPO_PRIOR_BPM = (60.0, 200.0)
"""With fewer than two songs, the period's chance level is that of a tempo drawn log-uniformly here."""
BAR_TOLERANCE = 0.05
"""The bar periodicity looks at lags within 5 % of one bar and of two bars (beat trackers give the
beat period to about 1 %; dancers' figures drift a little against it)."""
EXACT_PAIRINGS = 8
"""Up to this many songs every pairing of motions with songs is scored (8! = 40 320); above, random ones."""


@dataclass(frozen=True)
class PeriodEstimate:
    """The dominant period of one motion's vertical movement.

    Attributes:
        period_s: the dominant period in seconds, or None when the autocorrelation has no peak.
        height: the autocorrelation at that period (unitless, -1..1; 0 when none).
        peaks: every peak found, ``(lag_s, height)`` in increasing lag.
        max_lag_s: the largest lag looked at, seconds.
    """

    period_s: float | None
    height: float
    peaks: tuple[tuple[float, float], ...]
    max_lag_s: float


def vertical_autocorrelation(
    positions: np.ndarray, mask: np.ndarray | None, fps: float, max_lag_s: float, up_axis: int = 1
) -> np.ndarray:
    """Autocorrelation [L + 1] of the joints' up-axis trajectories at lags 0..L frames, averaged over
    joints, slow drift removed (:func:`~kinectdata.evaluation.rhythm.trajectory_autocorrelation`).

    Args:
        positions: [T, J, C] joint positions, any unit.
        mask: [T, J] bool validity, or None.
        fps: frames per second.
        max_lag_s: largest lag in seconds (cut to half the motion).
        up_axis: index of the vertical axis in C (1: y up, the Kinect's camera space).
    """
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 3 or not 0 <= up_axis < pos.shape[2]:
        raise KinectDataError(f"positions must be [T, J, C] with up axis {up_axis} among C, got shape {pos.shape}")
    if not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    max_lag = min(int(np.ceil(max_lag_s * fps)), pos.shape[0] // 2)
    if max_lag < 2:
        raise KinectDataError(f"{pos.shape[0]} frames are too few for an autocorrelation up to {max_lag_s:.2f} s")
    vertical = pos[:, :, up_axis : up_axis + 1]
    return trajectory_autocorrelation(vertical, mask, max_lag, max(1, round(DRIFT_WINDOW_S * fps)))[:, 0]


def dominant_period(
    positions: np.ndarray,
    mask: np.ndarray | None,
    fps: float,
    max_lag_s: float,
    up_axis: int = 1,
) -> PeriodEstimate:
    """The dominant period of the vertical motion: the shortest-lag autocorrelation peak (of
    :func:`vertical_autocorrelation`, peaks as :func:`~kinectdata.evaluation.rhythm.autocorrelation_peaks`
    finds them, lags of at least :data:`MIN_PERIOD_S`) whose height is at least
    :data:`DOMINANT_FRACTION` of the highest peak's.

    Args:
        positions: [T, J, C] joint positions, any unit.
        mask: [T, J] bool validity, or None.
        fps: frames per second.
        max_lag_s: largest lag in seconds (e.g. two bars and their tolerance).
        up_axis: index of the vertical axis in C.
    """
    curve = vertical_autocorrelation(positions, mask, fps, max_lag_s, up_axis)
    peaks = tuple((lag, h) for lag, h in autocorrelation_peaks(curve, fps) if lag >= MIN_PERIOD_S)
    looked = (len(curve) - 1) / fps
    if not peaks or max(h for _, h in peaks) <= 0:
        return PeriodEstimate(None, 0.0, peaks, looked)
    highest = max(h for _, h in peaks)
    lag, height = next((lag, h) for lag, h in peaks if h >= DOMINANT_FRACTION * highest)
    return PeriodEstimate(float(lag), float(height), peaks, looked)


def metrical_level(
    period_s: float | None, beat_period: float, beats_per_bar: int = BEATS_PER_BAR, tolerance: float = PERIOD_TOLERANCE
) -> str | None:
    """The metrical level (a name of :data:`LEVELS`) within ``tolerance`` of ``period_s``, or None.

    Args:
        period_s: a motion's period in seconds (None: None).
        beat_period: the music's beat period in seconds.
        beats_per_bar: beats per bar (4 unless the metre is known).
        tolerance: relative tolerance (0.1: within 10 %).
    """
    if period_s is None:
        return None
    best, error = None, tolerance
    for name, beats in _levels(beats_per_bar):
        e = abs(period_s / (beats * beat_period) - 1)
        if e <= error:
            best, error = name, e
    return best


def _levels(beats_per_bar: int) -> list[tuple[str, float]]:
    return [(n, b if b is not None else (beats_per_bar if n == "bar" else 2 * beats_per_bar)) for n, b in LEVELS]


def dominant_level(levels: dict[str, int]) -> str:
    """The metrical level most recordings sit at, from ``levels`` (name -> how many; ``"none"``
    for recordings at no level): ``"none"`` loses a tie, and of tied levels the finer one in
    :data:`LEVELS`'s order wins, so that the order the songs came in never decides; ``"none"``
    when ``levels`` is empty or only ``"none"``."""
    order = {name: i for i, (name, _) in enumerate(LEVELS)}
    if not levels:
        return "none"
    return max(levels, key=lambda k: (levels[k], k != "none", -order.get(k, len(order))))


def level_beats(level: str, beats_per_bar: int) -> float:
    """Beats in a metrical level of a song with ``beats_per_bar`` (``bar``: 3 in a waltz, 4 in a
    cha-cha); 1 for ``none`` and unknown names."""
    return float(dict(_levels(beats_per_bar)).get(level, 1.0))


@dataclass(frozen=True)
class ChanceFigure:
    """A rhythm figure beside its chance level.

    Attributes:
        value: the figure (mean over recordings).
        chance: its expected value by chance (mean over the chance draws).
        chance_spread: the standard deviation of the chance draws' means (0 for an exact chance level).
        p_value: one-sided probability of a value at least this high by chance.
        chance_from: how the chance level was made.
    """

    value: float
    chance: float
    chance_spread: float
    p_value: float
    chance_from: str

    @property
    def above_chance(self) -> bool:
        return self.p_value < SIGNIFICANCE

    def describe(self, fmt: str = ".3f") -> str:
        return f"{self.value:{fmt}} (chance {self.chance:{fmt}} +- {self.chance_spread:{fmt}}, p {_p(self.p_value)})"


@dataclass(frozen=True)
class RecordingBeats:
    """One recording's motion and its music's beats, on the motion's clock.

    Attributes:
        name: the recording's name.
        positions: [T, J, C] joint positions (metres or any unit), row 0 at ``first_frame / fps`` s.
        mask: [T, J] validity, or None.
        fps: frames per second.
        beats_s: [B] the music's beat times in seconds on the motion's clock (frame 0 at 0 s).
        first_frame: the frame number of row 0 (1 for generated motion that starts from frame 0's true pose).
        beats_per_bar: the metre (4 when unknown).
        up_axis: the vertical axis' index in C.
    """

    name: str
    positions: np.ndarray
    mask: np.ndarray | None
    fps: float
    beats_s: np.ndarray
    first_frame: int = 0
    beats_per_bar: int = BEATS_PER_BAR
    up_axis: int = 1

    @property
    def span_s(self) -> tuple[float, float]:
        return self.first_frame / self.fps, (self.first_frame + len(self.positions) - 1) / self.fps

    def beats_inside(self, beats: np.ndarray | None = None) -> np.ndarray:
        b = self.beats_s if beats is None else beats
        lo, hi = self.span_s
        return b[(b >= lo) & (b <= hi)]

    @property
    def beat_period_s(self) -> float:
        inside = self.beats_inside()
        return beat_period_s(inside if inside.size >= 2 else self.beats_s)


@dataclass(frozen=True)
class RecordingRhythm:
    """The rhythm figures of one recording's motion.

    Attributes:
        name: the recording. beat_period_s: the music's, seconds.
        period: the motion's dominant period. level: its metrical level (None: none).
        at_beat: the period is at the beat (within 10 %).
        beat_align_music, beat_align_motion: Beat Align Scores averaged over the music's beats and
            over the motion's beats (sigma 0.05 s).
        f_measure: motion beats against music beats within :data:`FMEASURE_WINDOW_S`.
        motion_beats: how many motion beats (speed minima) the motion has.
        beats_per_bar: the music's metre the levels were built from.
    """

    name: str
    beat_period_s: float
    period: PeriodEstimate
    level: str | None
    at_beat: bool
    in_metre: bool
    beat_align_music: float
    beat_align_motion: float
    f_measure: float
    motion_beats: int
    beat_times_s: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    beats_per_bar: int = BEATS_PER_BAR


def recording_rhythm(rec: RecordingBeats) -> RecordingRhythm:
    """The dominant period (looked at up to two bars and its tolerance), its metrical level, and the
    beat scores of one recording's motion."""
    period_s = rec.beat_period_s
    estimate = dominant_period(
        rec.positions, rec.mask, rec.fps, 2 * rec.beats_per_bar * period_s * (1 + 2 * PERIOD_TOLERANCE), rec.up_axis
    )
    level = metrical_level(estimate.period_s, period_s, rec.beats_per_bar)
    beats = motion_beats(rec.positions, rec.mask, rec.fps) + rec.span_s[0]
    music = rec.beats_inside()
    return RecordingRhythm(
        name=rec.name,
        beat_period_s=period_s,
        period=estimate,
        level=level,
        at_beat=level == "beat",
        in_metre=level is not None,
        beat_align_music=_bas(music, beats, "music_to_motion"),
        beat_align_motion=_bas(music, beats, "motion_to_music"),
        f_measure=motion_beat_fmeasure(music, beats, FMEASURE_WINDOW_S) if music.size else 0.0,
        motion_beats=int(beats.size),
        beat_times_s=beats,
        beats_per_bar=rec.beats_per_bar,
    )


def _bas(music: np.ndarray, motion: np.ndarray, direction: str) -> float:
    averaged = music if direction == "music_to_motion" else motion
    return beat_align_score(music, motion, BEAT_ALIGN_SIGMA_S, direction) if averaged.size else 0.0


@dataclass(frozen=True)
class BeatFollowing:
    """Rhythm figures over a set of recordings, each beside its chance level.

    Attributes:
        recordings: per recording, :class:`RecordingRhythm`.
        in_metre: share of recordings whose dominant period is at a metrical level of their music
            (half beat, beat, two beats, bar, two bars), with the chance that it is at one of another
            song's (other songs' tempi).
        at_beat: share of recordings whose dominant period is at the beat itself, with its chance level.
        levels: per metrical level (and "none"), how many recordings' periods sit there.
        tempo_p_value: the one-sided p-value of ``tempo_correlation`` (exact over every ordering for
            up to 8 songs): with 3 songs even a perfect correlation has p = 1/6.
        tempo_correlation: Spearman rank correlation, across recordings, of the motion's period at
            the level most recordings follow (the autocorrelation peak nearest that level's lag, within
            a third of it) with the music's period at that level in its own metre (the beat period
            times the level's beats: a bar of a waltz is 3 beats, of a cha-cha 4), None with fewer
            than 3 recordings, no such peaks or no spread in either. At the beat or two beats this is
            the rank correlation with the beat period; at the bar it does not rank a waltz's 3-beat bar
            by its beat.
        beat_align_music, beat_align_motion, f_measure: means over recordings with their chance
            levels from the same motion against the music's beats shifted by random phases.
        beat_align_other_songs: the music-direction Beat Align Score of each motion against the
            other songs' beats (None with one song): a second chance level.
        bar_periodicity: how much each motion repeats after one and after two of its song's bars
            (:func:`bar_periodicity`), with its chance level from every other pairing of the motions
            with the songs (None with one song).
        bar_periodicity_other_songs: the same motions' figure against the other songs' bars (None
            with one song).
    """

    recordings: list[RecordingRhythm]
    in_metre: ChanceFigure
    at_beat: ChanceFigure
    levels: dict[str, int]
    tempo_correlation: float | None
    tempo_p_value: float | None
    beat_align_music: ChanceFigure
    beat_align_motion: ChanceFigure
    f_measure: ChanceFigure
    beat_align_other_songs: float | None
    bar_periodicity: ChanceFigure | None = None
    bar_periodicity_other_songs: float | None = None

    @property
    def follows_bars(self) -> bool:
        """The motions repeat after their own songs' bars more than after other songs' bars,
        significantly (one-sided p < 0.05 over every pairing of motions with songs)."""
        return self.bar_periodicity is not None and self.bar_periodicity.above_chance

    @property
    def follows_beat(self) -> bool:
        """Most recordings' periods are at a metrical level of their music (the beat or a multiple),
        significantly more often than at another song's."""
        return self.in_metre.value >= 0.5 and self.in_metre.above_chance

    @property
    def follows_tempo(self) -> bool:
        """The motion's period rises and falls with the music's period at its level: rank correlation
        >= 0.9, p < 0.05."""
        return (
            self.tempo_correlation is not None
            and self.tempo_correlation >= 0.9
            and self.tempo_p_value is not None
            and self.tempo_p_value < SIGNIFICANCE
        )

    @property
    def on_beat(self) -> bool:
        """The motion's beats fall on the music's beats significantly more than by chance."""
        return self.beat_align_music.above_chance and self.beat_align_motion.above_chance

    @property
    def dominant_level(self) -> str:
        """The metrical level most recordings' periods sit at (:func:`dominant_level`)."""
        return dominant_level(self.levels)

    def verdicts(self, what: str = "motion") -> list[str]:
        """Plain lines with a yes or no and the figures next to it."""
        n = len(self.recordings)
        level = self.dominant_level
        at_level = [r for r in self.recordings if r.level == level]
        if level != "none" and at_level:
            period = float(np.median([r.period.period_s for r in at_level]))
            music = float(np.median([r.beat_period_s for r in at_level]))
            where = f"at {level}: period {period:.2f} s = {period / music:.1f} x the beat of {music:.2f} s"
        else:
            where = "at no metrical level"
        spread = ", ".join(f"{k} {v}" for k, v in sorted(self.levels.items(), key=lambda kv: -kv[1]))
        lines = [
            f"{what} follows the beat: {_yes(self.follows_beat)} ({where}; {round(self.in_metre.value * n)} of {n} "
            f"songs at a metrical level ({spread}), chance {self.in_metre.chance:.0%}, p {_p(self.in_metre.p_value)};"
            f" at the beat itself {round(self.at_beat.value * n)} of {n})",
            f"{what} moves on the beats: {_yes(self.on_beat)} (Beat Align Score {self.beat_align_music.describe()} "
            f"over music beats, {self.beat_align_motion.describe()} over motion beats; "
            f"F-measure {self.f_measure.describe('.2f')})",
        ]
        if self.tempo_correlation is not None:
            lines.append(
                f"{what} follows the tempo: {_yes(self.follows_tempo)} (rank correlation of the motion's "
                f"period at {level} with the music's {self.tempo_correlation:.2f} over {n} songs, "
                f"p {_p(self.tempo_p_value)})"
            )
        if self.bar_periodicity is not None:
            lines.append(
                f"{what} repeats with its song's bars: {_yes(self.follows_bars)} (autocorrelation after one or two "
                f"bars {self.bar_periodicity.value:.3f}; against the other songs' bars "
                f"{self.bar_periodicity_other_songs:.3f}; {self.bar_periodicity.chance_from} "
                f"{self.bar_periodicity.chance:.3f} +- {self.bar_periodicity.chance_spread:.3f}, "
                f"p {_p(self.bar_periodicity.p_value)})"
            )
        return lines

    def to_dict(self) -> dict:
        """JSON-ready figures."""

        def figure(f: ChanceFigure) -> dict:
            return {
                "value": f.value,
                "chance": f.chance,
                "chance_spread": f.chance_spread,
                "p_value": f.p_value,
                "chance_from": f.chance_from,
                "above_chance": f.above_chance,
            }

        return {
            "follows_beat": self.follows_beat,
            "on_beat": self.on_beat,
            "in_metre": figure(self.in_metre),
            "at_beat": figure(self.at_beat),
            "dominant_level": self.dominant_level,
            "levels": self.levels,
            "tempo_correlation": self.tempo_correlation,
            "tempo_p_value": self.tempo_p_value,
            "follows_tempo": self.follows_tempo,
            "beat_align_music": figure(self.beat_align_music),
            "beat_align_motion": figure(self.beat_align_motion),
            "f_measure": figure(self.f_measure),
            "beat_align_other_songs": self.beat_align_other_songs,
            "bar_periodicity": None if self.bar_periodicity is None else figure(self.bar_periodicity),
            "bar_periodicity_other_songs": self.bar_periodicity_other_songs,
            "follows_bars": self.follows_bars,
            "recordings": {
                r.name: {
                    "beat_period_s": r.beat_period_s,
                    "period_s": r.period.period_s,
                    "period_height": r.period.height,
                    "level": r.level,
                    "at_beat": r.at_beat,
                    "in_metre": r.in_metre,
                    "beat_align_music": r.beat_align_music,
                    "beat_align_motion": r.beat_align_motion,
                    "f_measure": r.f_measure,
                    "motion_beats": r.motion_beats,
                    "beats_per_bar": r.beats_per_bar,
                    "peaks": [{"lag_s": lag, "height": h} for lag, h in r.period.peaks],
                }
                for r in self.recordings
            },
        }


def beat_following(recordings: Sequence[RecordingBeats], *, draws: int = CHANCE_DRAWS, seed: int = 0) -> BeatFollowing:
    """Rhythm figures over ``recordings``, each with its chance level and p-value.

    - **At the beat** (:func:`recording_rhythm`): the share of recordings whose dominant period is
      within 10 % of their music's beat period. Its chance level per recording is the share of the
      other songs' beat periods the motion's period matches (one song: a tempo drawn log-uniformly
      from :data:`TEMPO_PRIOR_BPM`); the p-value is the binomial tail of that many matches at the
      mean chance rate.
    - **Beat Align Scores and F-measure**: chance levels from the same motion against its music's
      beats shifted by ``draws`` random phases (uniform over one beat period, the beats wrapped
      around the motion's span so their number stays); the p-value is the share of draws whose
      mean over recordings is at least the observed mean (plus one, over draws plus one).

    Args:
        recordings: the motions and their music's beats.
        draws: random phase shifts per recording.
        seed: the draws' random generator.
    """
    from scipy.stats import binomtest

    if not recordings:
        raise KinectDataError("beat following needs at least one recording")
    rhythms = [recording_rhythm(r) for r in recordings]
    n = len(rhythms)
    periods = np.array([r.beat_period_s for r in rhythms])
    bars = [r.beats_per_bar for r in recordings]
    figures = []
    for hit, matches in (
        (lambda r: r.in_metre, lambda p, beat, bar: metrical_level(p, beat, bar) is not None),
        (lambda r: r.at_beat, lambda p, beat, bar: metrical_level(p, beat, bar) == "beat"),
    ):
        rates = []
        for i, r in enumerate(rhythms):
            if n > 1:
                others = [matches(r.period.period_s, p, bars[j]) for j, p in enumerate(periods) if j != i]
                rates.append(float(np.mean(others)))
            else:
                rates.append(_prior_match_rate(r.period.period_s, lambda p, b, m=matches: m(p, b, bars[0])))
        hits = sum(hit(r) for r in rhythms)
        rate = float(np.mean(rates))
        p = float(binomtest(hits, n, rate, alternative="greater").pvalue) if 0 < rate < 1 else float(rate >= 1)
        chance_from = "other songs' beat periods" if n > 1 else f"a tempo drawn log-uniformly in {TEMPO_PRIOR_BPM} BPM"
        figures.append(ChanceFigure(hits / n, rate, 0.0, p if hits else 1.0, chance_from))
    in_metre, at_beat = figures
    levels: dict[str, int] = {}
    for r in rhythms:
        levels[r.level or "none"] = levels.get(r.level or "none", 0) + 1
    tempo, tempo_p = _tempo_correlation(rhythms, levels, bars)

    rng = np.random.default_rng(seed)
    shifted = np.zeros((3, draws, n))
    for i, (rec, rhythm) in enumerate(zip(recordings, rhythms)):
        music = _wrapped(rec, rng.uniform(0, rhythm.beat_period_s, draws))
        shifted[0, :, i] = beat_align_scores(music, rhythm.beat_times_s, BEAT_ALIGN_SIGMA_S, "music_to_motion")
        shifted[1, :, i] = beat_align_scores(music, rhythm.beat_times_s, BEAT_ALIGN_SIGMA_S, "motion_to_music")
        shifted[2, :, i] = beat_fmeasures(music, rhythm.beat_times_s, FMEASURE_WINDOW_S)
    observed = np.array(
        [[r.beat_align_music for r in rhythms], [r.beat_align_motion for r in rhythms], [r.f_measure for r in rhythms]]
    )
    phase = [_shifted_figure(observed[m].mean(), shifted[m].mean(axis=1)) for m in range(3)]
    other_songs = None
    if n > 1:
        other_songs = float(
            np.mean(
                [
                    _bas(rec.beats_inside(recordings[j].beats_s), rhythm.beat_times_s, "music_to_motion")
                    for i, (rec, rhythm) in enumerate(zip(recordings, rhythms))
                    for j in range(n)
                    if j != i
                ]
            )
        )
    bars, bars_other = _bar_periodicity(recordings, draws, rng)
    return BeatFollowing(rhythms, in_metre, at_beat, levels, tempo, tempo_p, *phase, other_songs, bars, bars_other)


def bar_lags_s(rec: RecordingBeats) -> tuple[float, float]:
    """One bar and two bars of a recording's music, seconds."""
    bar = rec.beats_per_bar * rec.beat_period_s
    return bar, 2 * bar


def bar_periodicity(curve: np.ndarray, fps: float, lags_s: Sequence[float], tolerance: float = BAR_TOLERANCE) -> float:
    """How much a motion repeats after the given lags: the highest value of its vertical
    autocorrelation ``curve`` [L + 1] (lags 0..L frames, :func:`vertical_autocorrelation`) within
    ``tolerance`` of any of ``lags_s`` (seconds), unitless -1..1; NaN where no such lag is on the
    curve. A dance that repeats its figures every bar or two bars of its song scores high against
    that song's bars; against another song's bars it scores what its curve happens to hold there."""
    values = []
    for lag in lags_s:
        lo = max(1, int(np.floor(lag * (1 - tolerance) * fps)))
        hi = min(len(curve) - 1, int(np.ceil(lag * (1 + tolerance) * fps)))
        window = curve[lo : hi + 1]
        if window.size and np.isfinite(window).any():
            values.append(float(np.nanmax(window)))
    return max(values) if values else float("nan")


def _bar_periodicity(
    recordings: Sequence[RecordingBeats], draws: int, rng: np.random.Generator
) -> tuple[ChanceFigure | None, float | None]:
    """(the motions' bar periodicity against their own songs with its chance level over every
    pairing of motions with songs, the mean against the other songs); (None, None) for one song."""
    from itertools import permutations

    n = len(recordings)
    if n < 2:
        return None, None
    lags = [bar_lags_s(r) for r in recordings]
    longest = max(max(pair) for pair in lags) * (1 + BAR_TOLERANCE)
    scores = np.full((n, n), np.nan)  # [motion, song]
    for i, rec in enumerate(recordings):
        try:
            curve = vertical_autocorrelation(rec.positions, rec.mask, rec.fps, longest, rec.up_axis)
        except KinectDataError:
            continue
        for j in range(n):
            scores[i, j] = bar_periodicity(curve, rec.fps, lags[j])
    scores = np.nan_to_num(scores, nan=0.0)  # a lag beyond half the motion: no evidence of repeating there
    observed = float(np.mean(np.diag(scores)))
    if n <= EXACT_PAIRINGS:
        pairings = np.array(list(permutations(range(n))))
    else:
        pairings = np.array([rng.permutation(n) for _ in range(draws)])
    chance = scores[np.arange(n), pairings].mean(axis=1)  # [pairings]
    hits = int(np.count_nonzero(chance >= observed - 1e-12))
    # exact: the share of every pairing; drawn: plus one over draws plus one (the observed pairing is one)
    p = hits / len(chance) if n <= EXACT_PAIRINGS else (1 + hits) / (1 + len(chance))
    from_ = "every pairing of the motions with the songs" if n <= EXACT_PAIRINGS else f"{draws} random pairings"
    others = float(scores[~np.eye(n, dtype=bool)].mean())
    return ChanceFigure(observed, float(chance.mean()), float(chance.std()), p, from_), others


def _tempo_correlation(
    rhythms: list[RecordingRhythm], levels: dict[str, int], bars: list[int]
) -> tuple[float | None, float | None]:
    """(Spearman correlation, one-sided p-value) of each motion's period at the most common level
    (its autocorrelation peak nearest that level's lag, within a third of it) with its music's period
    at that level, in the song's metre (``bars``: beats per bar); (None, None) when fewer than 3 songs
    have such a peak or either side does not vary."""
    from itertools import permutations

    from scipy.stats import rankdata, spearmanr

    level = dominant_level(levels)
    if len(rhythms) < 3 or level == "none":
        return None, None
    motion, music = [], []
    for r, bar in zip(rhythms, bars):
        lag = level_beats(level, bar) * r.beat_period_s
        near = [p for p, _ in r.period.peaks if abs(p / lag - 1) <= 1 / 3]
        if near:
            motion.append(min(near, key=lambda p: abs(p / lag - 1)))
            music.append(lag)
    if len(motion) < 3 or np.ptp(motion) == 0 or np.ptp(music) == 0:
        return None, None
    result = spearmanr(motion, music)
    rho = float(result.statistic)
    if not np.isfinite(rho):
        return None, None
    if len(motion) <= 8:  # exact: the share of orderings of the motion periods that correlate as well
        a, b = rankdata(motion), rankdata(music)
        orders = np.array(list(permutations(a - a.mean())))  # [n!, n]
        draws = orders @ (b - b.mean()) / (np.linalg.norm(a - a.mean()) * np.linalg.norm(b - b.mean()))
        p = float(np.mean(draws >= rho - 1e-12))
    else:
        p = float(result.pvalue) / 2 if rho > 0 else 1.0
    return rho, p


def _shifted_figure(value: float, draws: np.ndarray) -> ChanceFigure:
    p = (1 + np.count_nonzero(draws >= value - 1e-12)) / (1 + draws.size)
    return ChanceFigure(
        float(value), float(draws.mean()), float(draws.std()), float(p), "beats shifted by random phases"
    )


def _wrapped(rec: RecordingBeats, phases: np.ndarray) -> np.ndarray:
    """The recording's music beats inside its span [B], shifted by each of ``phases`` [D] s and
    wrapped around the span: [D, B], each row increasing."""
    lo, hi = rec.span_s
    inside = rec.beats_inside()
    return np.sort(lo + np.mod(inside[None, :] + phases[:, None] - lo, hi - lo + 1 / rec.fps), axis=1)


def _matches(period_s: float | None, beat_period: float) -> bool:
    return period_s is not None and abs(period_s / beat_period - 1) <= PERIOD_TOLERANCE


def _prior_match_rate(period_s: float | None, matches=None, samples: int = 2001) -> float:
    """Probability that a beat period drawn log-uniformly from :data:`TEMPO_PRIOR_BPM` is matched
    by ``period_s`` (``matches(period_s, beat_period)``; default: within 10 % of it), integrated on
    a log-spaced grid of ``samples`` tempi."""
    if period_s is None:
        return 0.0
    matches = matches or (lambda p, b: _matches(p, b))
    tempi = np.geomspace(*TEMPO_PRIOR_BPM, samples)
    return float(np.mean([matches(period_s, 60.0 / t) for t in tempi]))


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def _p(p: float) -> str:
    return f"= {p:.2g}" if p >= 0.001 else "< 0.001"
