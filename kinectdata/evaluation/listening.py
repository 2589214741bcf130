"""Does a trained model listen to the music? Its generated motion against the real one, and the
controls that tell a model that listens from one that ignores the audio (docs/rhythm.md).

For a set of test songs (each: its features, the true first pose, the real motion and the music's
beats), with one trained network:

- **generated** motion for each song, and the real motion, through
  :func:`~kinectdata.evaluation.beat_following.beat_following` (period, metrical level, Beat
  Align Scores, F-measure, each beside its chance level);
- **swapped songs**: each song's start pose with another test song of a different tempo (the
  one whose tempo differs most): the motion's period must follow the new song;
- **noise**: the audio replaced by white noise of the song's loudness (RMS): beat following falls
  to its chance level;
- **shifted**: the audio shifted against the motion by whole beats (2 s or more) and a random
  quarter to three quarters of a beat more (:func:`shift_frames`), so that its beats fall between the
  original ones: the Beat Align Score against the original beats falls to its chance level;
- **silence**: all-silent audio: the motion's energy against the energy with music (the paper's
  Figure 7: the motion stops);
- **baselines** for the phase: the mean real pose with Gaussian noise of the real motion's
  per-coordinate spread, and the real motion of another song, each scored against the song's beats;
- **alive**: the generated motion's energy (mean squared joint speed) against the real motion's;
- **turning**: how fast each motion turns about the vertical and the share of its energy the turning
  is (:mod:`~kinectdata.evaluation.metrics.turning`), and the energy without it.

Every function takes plain arrays; the network is run through its model kind's ``free_run``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.beat_following import (
    BEATS_PER_BAR,
    PERIOD_TOLERANCE,
    SIGNIFICANCE,
    BeatFollowing,
    RecordingBeats,
    beat_following,
    level_beats,
    metrical_level,
)
from kinectdata.evaluation.metrics.pose_error import motion_energy_per_s
from kinectdata.evaluation.metrics.turning import Turning, turning
from kinectdata.evaluation.tempo_control import TempoControl, TempoSong, tempo_control

ALIVE_RANGE = (0.5, 2.0)
"""Generated motion is alive, not frozen or wild, when its energy is within these times the real motion's."""
SILENCE_STOPS = 0.1
"""Silence stops the motion when the energy under silence is below this fraction of the energy with music."""
MIN_SHIFT_S = 2.0
"""The shifted-audio control moves each song's music by at least this (seconds), then a fraction of a beat."""
OFF_GRID = (0.25, 0.75)
"""... that fraction of a beat: the shifted music's beats fall this far between the original ones."""
TURNS_AT_ALL = 0.05
"""The real motion turns when turning is at least this share of its energy; below it the turning verdict is
not asked."""


@dataclass(frozen=True)
class TurningFigures:
    """The generated and the real motion's turning about the vertical, over the test songs.

    Attributes:
        real_rate, generated_rate: mean absolute turning speed, rad/s (means over the songs).
        real_share, generated_share: the turning's share of the motion's energy (means over the songs).
        turning_ratio: the generated motion's turning energy over the real motion's (mean over the
            songs; NaN when the real motion never turns).
        energy_ratio_without_turning: the energy left when the turning's is taken out, generated over
            real (mean over the songs).
        spread_ratio: how wide the generated body is about the vertical over the real one
            (:attr:`~kinectdata.evaluation.metrics.turning.Turning.spread`; mean over the songs): a
            turning's energy short of the real one's at the same speed is a narrow body.
    """

    real_rate: float
    generated_rate: float
    real_share: float
    generated_share: float
    turning_ratio: float
    energy_ratio_without_turning: float
    spread_ratio: float = float("nan")

    @classmethod
    def of(cls, real: list[Turning], generated: list[Turning]) -> TurningFigures:
        def ratio(a: float, b: float) -> float:
            return a / b if b > 0 else float("nan")

        return cls(
            real_rate=float(np.nanmean([t.rate for t in real])),
            generated_rate=float(np.nanmean([t.rate for t in generated])),
            real_share=float(np.nanmean([t.share for t in real])),
            generated_share=float(np.nanmean([t.share for t in generated])),
            turning_ratio=float(np.mean([ratio(g.turning_energy, r.turning_energy) for r, g in zip(real, generated)])),
            energy_ratio_without_turning=float(
                np.mean(
                    [ratio(g.energy - g.turning_energy, r.energy - r.turning_energy) for r, g in zip(real, generated)]
                )
            ),
            spread_ratio=float(np.mean([ratio(g.spread, r.spread) for r, g in zip(real, generated)])),
        )

    @property
    def asked(self) -> bool:
        """Whether the real motion turns enough for the verdict (:data:`TURNS_AT_ALL`)."""
        return self.real_share >= TURNS_AT_ALL

    @property
    def turns(self) -> bool:
        """The generated motion's turning energy within :data:`ALIVE_RANGE` times the real motion's."""
        return self.asked and ALIVE_RANGE[0] <= self.turning_ratio <= ALIVE_RANGE[1]

    def verdict(self) -> str:
        figures = (
            f"about the vertical at {self.generated_rate:.2f} rad/s, {self.generated_share:.0%} of its energy; the "
            f"real motion {self.real_rate:.2f} rad/s, {self.real_share:.0%}"
        )
        if not self.asked:
            return (
                f"generated motion turns as the real motion does: not asked (the real motion hardly turns: {figures})"
            )
        return (
            f"generated motion turns as the real motion does: {'yes' if self.turns else 'no'} ({figures}; the "
            f"turning's energy {self.turning_ratio:.2g} x the real's, wanted {ALIVE_RANGE[0]:g}-{ALIVE_RANGE[1]:g}; "
            f"the energy without the turning {self.energy_ratio_without_turning:.2f} x the real's; the body "
            f"{self.spread_ratio:.2f} x as wide about the vertical)"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "real_rate_rad_s": self.real_rate,
            "generated_rate_rad_s": self.generated_rate,
            "real_share": self.real_share,
            "generated_share": self.generated_share,
            "turning_ratio": self.turning_ratio,
            "energy_ratio_without_turning": self.energy_ratio_without_turning,
            "spread_ratio": self.spread_ratio,
            "asked": self.asked,
            "turns": self.turns,
        }


@dataclass(frozen=True)
class HeldOutSong:
    """One test recording for the listening controls.

    Attributes:
        name: the recording.
        features: [T, *feature shape] the model's inputs, one per motion frame.
        first_pose: [D] the model's previous pose for frame 1 (the true pose of frame 0).
        real_positions: [T, J, C] the real motion (metres, or the target's units).
        real_mask: [T, J] its validity.
        beats_s: [B] the music's beat times on the motion's clock, seconds.
        fps: motion frames per second.
        rms: the audio's root mean square (full scale 1), for the noise control (None: no noise control).
        beats_per_bar: the music's metre (:mod:`~kinectdata.features.metre`), which the metrical
            levels (bar, two bars) are built from.
        travel_joint: the joint of ``real_positions`` (and of the generated positions) whose value is
            the dancer's travel, not a place on the body (the root of root-centred targets): left out
            of the turning. None: every joint is on the body.
        samples: [S] the song's music, mono at ``features_of``'s rate, sample 0 at frame 0, for the
            tempo control (:mod:`~kinectdata.evaluation.tempo_control`; None: no tempo control).
    """

    name: str
    features: np.ndarray
    first_pose: np.ndarray
    real_positions: np.ndarray
    real_mask: np.ndarray | None
    beats_s: np.ndarray
    fps: float
    rms: float | None = None
    beats_per_bar: int = BEATS_PER_BAR
    travel_joint: int | None = None
    samples: np.ndarray | None = field(default=None, repr=False)

    def body_turning(self, positions: np.ndarray, mask: np.ndarray | None = None) -> Turning:
        """:func:`~kinectdata.evaluation.metrics.turning.turning` of this song's motion [T, J, 3], the
        travel joint left out."""
        if self.travel_joint is not None:
            positions = np.delete(positions, self.travel_joint, axis=1)
            mask = None if mask is None else np.delete(mask, self.travel_joint, axis=1)
        return turning(positions, self.fps, mask)


@dataclass(frozen=True)
class Listening:
    """The figures and controls of :func:`listening_report`.

    Attributes:
        real, generated: beat following of the real and the generated motion.
        swapped: the swapped-song control's beat following against the new songs' beats (None: one song).
        swapped_follows_new: share of swapped runs whose period is at a metrical level of the new song.
        swapped_follows_old: share at a metrical level of the original song instead.
        noise: beat following of the motion generated from noise (None: no audio loudness known).
        shifted: beat following of the motion generated from shifted audio, against the original beats.
        silence_energy_ratio: energy under silence over energy with music.
        energy_ratio: generated motion energy over real motion energy.
        turning: both motions' turning about the vertical (:class:`TurningFigures`; None for motion in
            two dimensions, e.g. OpenPose's image positions).
        baselines: Beat Align Score (music direction) of the mean pose with noise and of another
            song's real motion, against each song's beats.
        generated_positions: per song, the generated motion [T-1, J, C] (frames 1..T-1).
        swapped_period_changes: share of swapped runs whose dominant period is more than 10 % away
            from the period the same start pose made with its own song (None: no swapped runs).
        tempo: the tempo control (:class:`~kinectdata.evaluation.tempo_control.TempoControl`: each song
            played faster and slower, the dances warped back); None when it could not run.
        tempo_unavailable: why the tempo control did not run ("" when it did).
    """

    real: BeatFollowing
    generated: BeatFollowing
    swapped: BeatFollowing | None
    swapped_follows_new: float | None
    swapped_follows_old: float | None
    noise: BeatFollowing | None
    shifted: BeatFollowing
    silence_energy_ratio: float
    energy_ratio: float
    turning: TurningFigures | None
    baselines: dict[str, float | None]
    generated_positions: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    swapped_period_changes: float | None = None
    tempo: TempoControl | None = None
    tempo_unavailable: str = ""

    @property
    def alive(self) -> bool:
        return ALIVE_RANGE[0] <= self.energy_ratio <= ALIVE_RANGE[1]

    @property
    def listens(self) -> bool:
        """The motion follows the music it is given (its period at the new song's metre in most swapped
        runs, more often than at the old song's), and noise does not make it follow the beat (False when
        the swapped-song control could not run)."""
        return self.generated.follows_beat and self.follows_swapped and self.ignores_noise

    @property
    def follows_swapped(self) -> bool:
        """The swapped-song control passes: the period is at the new song's metre in most runs, more
        often than at the old song's (False when it could not run)."""
        # the swapped runs share partner songs, so their own chance level (other songs' tempi) says nothing:
        # the control compares the new song's metre with the old one's
        return (
            self.swapped is not None
            and self.swapped_follows_new > 0.5
            and self.swapped_follows_new > self.swapped_follows_old
        )

    @property
    def ignores_noise(self) -> bool:
        """The noise control passes: noise does not make the motion follow the song's beat (True when
        it did not run)."""
        return self.noise is None or not self.noise.follows_beat

    @property
    def period_spread(self) -> float | None:
        """The longest of the generated motion's dominant periods over its shortest (None: fewer than
        two songs with a period): 1 for a motion that keeps one period whatever it hears."""
        periods = [r.period.period_s for r in self.generated.recordings if r.period.period_s]
        return max(periods) / min(periods) if len(periods) > 1 else None

    @property
    def no_fixed_oscillator(self) -> bool:
        """The generated motion's dominant period differs between songs (spread above 1 + twice the
        period tolerance) and follows their tempo at least as well as the real motion's (rank
        correlation at least the real one's, p < 0.05), and changes in most swapped-song runs."""
        spread, rho, real = self.period_spread, self.generated.tempo_correlation, self.real.tempo_correlation
        return (
            spread is not None
            and spread > 1 + 2 * PERIOD_TOLERANCE
            and rho is not None
            and (real is None or rho >= real)
            and self.generated.tempo_p_value is not None
            and self.generated.tempo_p_value < SIGNIFICANCE
            and self.swapped_period_changes is not None
            and self.swapped_period_changes > 0.5
        )

    @property
    def shifted_at_chance(self) -> bool:
        """Audio shifted against the motion by two seconds and a fraction of a beat takes the motion's
        beats off the original music's: their Beat Align Score is not significantly above chance."""
        return not self.shifted.beat_align_music.above_chance

    @property
    def in_phase(self) -> bool:
        """The generated motion's beats fall on the music's beats significantly more than by chance,
        with a Beat Align Score at least 0.8 times the real motion's and above both baselines."""
        baselines = [b for b in self.baselines.values() if b is not None]
        score = self.generated.beat_align_music.value
        return self.generated.on_beat and self.phase_ratio >= 0.8 and all(score > b for b in baselines)

    @property
    def phase_ratio(self) -> float:
        """The generated motion's Beat Align Score (music direction) over the real motion's."""
        real = self.real.beat_align_music.value
        return self.generated.beat_align_music.value / real if real > 0 else float("nan")

    def verdicts(self) -> list[str]:
        """Plain lines: a yes or no, and the figures beside it."""
        lines = []
        if self.energy_ratio < ALIVE_RANGE[0] / 5:
            lines.append(
                f"note: the generated motion is nearly still (energy {self.energy_ratio:.2g} x the real motion's): the "
                "rhythm verdicts below describe movements too small to see"
            )
        lines += self.generated.verdicts("generated motion")
        lines += [f"  (real motion: {line.split(': ', 1)[1]})" for line in self.real.verdicts("real")[:2]]
        noise = (
            f"at a metrical level in {self.noise.in_metre.value:.0%}, chance {self.noise.in_metre.chance:.0%}"
            if self.noise is not None
            else "not run (audio loudness unknown)"
        )
        if self.swapped is not None:
            lines.append(
                f"listens to the music: {'yes' if self.listens else 'no'} (swapped-song control: the period "
                f"is at the new song's metre in {self.swapped_follows_new:.0%} of runs, the old one's in "
                f"{self.swapped_follows_old:.0%}; noise control: {noise})"
            )
        else:
            lines.append(
                "listens to the music: not shown (the swapped-song control needs two test songs whose periods at "
                f"the motion's level differ by more than {2 * PERIOD_TOLERANCE:.0%}; noise control: {noise})"
            )
        lines.append(
            f"moves with the music's phase: {'yes' if self.in_phase else 'no'} (Beat Align Score "
            f"{self.generated.beat_align_music.value:.3f} = {self.phase_ratio:.2f} x the real motion's "
            f"{self.real.beat_align_music.value:.3f}; shifted audio {self.shifted.beat_align_music.describe()}; "
            f"baselines: mean pose + noise {_fmt(self.baselines['mean_pose_noise'])}, "
            f"another song's real motion {_fmt(self.baselines['other_song'])})"
        )
        lines.append(self._oscillator_verdict())
        lines.append(
            self.tempo.verdict()
            if self.tempo is not None
            else f"keeps time with the song at other tempi: not measured ({self.tempo_unavailable})"
        )
        lines.append(
            f"generated motion is alive: {'yes' if self.alive else 'no'} (energy {self.energy_ratio:.2f} x the real "
            f"motion's; wanted {ALIVE_RANGE[0]:g}-{ALIVE_RANGE[1]:g})"
        )
        if self.turning is not None:
            lines.append(self.turning.verdict())
        lines.append(
            f"stops in silence: {'yes' if self.silence_energy_ratio < SILENCE_STOPS else 'no'} (energy "
            f"{self.silence_energy_ratio:.2g} x the energy with music)"
        )
        return lines

    def _oscillator_verdict(self) -> str:
        periods = [r.period.period_s for r in self.generated.recordings]
        shown = [f"{p:.2f}" for p in periods if p] or ["none"]
        rho, real = self.generated.tempo_correlation, self.real.tempo_correlation
        tempo = "n/a" if rho is None else f"{rho:.2f} (p {_p_text(self.generated.tempo_p_value)})"
        changes = "n/a" if self.swapped_period_changes is None else f"{self.swapped_period_changes:.0%}"
        return (
            f"generated motion is no fixed oscillator: {'yes' if self.no_fixed_oscillator else 'no'} (dominant "
            f"periods {', '.join(shown)} s; rank correlation with the tempo {tempo}, the real motion's "
            f"{'n/a' if real is None else f'{real:.2f}'}; the period changes with a swapped song in {changes} of runs)"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "real": self.real.to_dict(),
            "generated": self.generated.to_dict(),
            "swapped": None if self.swapped is None else self.swapped.to_dict(),
            "swapped_follows_new": self.swapped_follows_new,
            "swapped_follows_old": self.swapped_follows_old,
            "noise": None if self.noise is None else self.noise.to_dict(),
            "shifted": self.shifted.to_dict(),
            "silence_energy_ratio": self.silence_energy_ratio,
            "energy_ratio": self.energy_ratio,
            "turning": None if self.turning is None else self.turning.to_dict(),
            "alive": self.alive,
            "listens": self.listens,
            "follows_swapped": self.follows_swapped,
            "ignores_noise": self.ignores_noise,
            "phase_ratio": self.phase_ratio,
            "in_phase": self.in_phase,
            "period_spread": self.period_spread,
            "swapped_period_changes": self.swapped_period_changes,
            "no_fixed_oscillator": self.no_fixed_oscillator,
            "tempo": None if self.tempo is None else self.tempo.to_dict(),
            "tempo_unavailable": self.tempo_unavailable,
            "shifted_at_chance": self.shifted_at_chance,
            "baselines": self.baselines,
            "verdicts": self.verdicts(),
        }


def listening_report(
    songs: list[HeldOutSong],
    generate: Callable[[np.ndarray, np.ndarray], np.ndarray],
    features_of: Callable[[np.ndarray], np.ndarray],
    *,
    seed: int = 0,
    draws: int = 500,
    generated: dict[str, np.ndarray] | None = None,
    generate_many: Callable[[list[tuple[np.ndarray, np.ndarray]]], list[np.ndarray]] | None = None,
    tempo_rates: tuple[float, ...] | None = None,
) -> Listening:
    """Run the generated-motion figures and the listening controls (module docstring).

    Args:
        songs: the test songs.
        generate: ``generate(features [T, ...], first_pose [D]) -> positions [T-1, J, C]``: the
            model run free from the first pose, its output as positions in the real motion's units.
        features_of: ``features_of(samples [S]) -> features [T, ...]``: the model's features of mono
            audio on the songs' motion clock (frame k at k / fps); its ``sample_rate`` attribute
            gives the rate (default 16 kHz). Makes the noise and silence controls' inputs.
        seed: the random choices (noise, shifts, chance draws).
        draws: chance draws per recording.
        generated: per song name, ``generate(features, first_pose)`` when the caller has run it
            already (the rest are generated here).
        generate_many: ``generate`` over a list of (features, first_pose) at once, when the model
            runs several songs faster together than one by one (default: ``generate`` in turn).
        tempo_rates: the tempo factors of the tempo control, run on the songs whose ``samples`` are
            given (None: :data:`~kinectdata.evaluation.tempo_control.TEMPO_RATES`; empty: none).
            ``features_of`` then takes ``beats_per_bar=`` too.
    """
    if not songs:
        raise KinectDataError("the listening controls need at least one test song")
    rng = np.random.default_rng(seed)

    def run_all(jobs: list[tuple[np.ndarray, np.ndarray]]) -> list[np.ndarray]:
        return generate_many(jobs) if generate_many is not None else [generate(f, p) for f, p in jobs]

    def following(motions: list[tuple[str, np.ndarray, np.ndarray | None, HeldOutSong]], first: int) -> BeatFollowing:
        recs = [
            RecordingBeats(n, p, m, s.fps, s.beats_s, first_frame=first, beats_per_bar=s.beats_per_bar)
            for n, p, m, s in motions
        ]
        return beat_following(recs, draws=draws, seed=seed)

    real = following([(s.name, s.real_positions, s.real_mask, s) for s in songs], 0)
    given = generated or {}
    missing = [s for s in songs if s.name not in given]
    made = dict(zip([s.name for s in missing], run_all([(s.features, s.first_pose) for s in missing])))
    generated_positions = {s.name: given[s.name] if s.name in given else made[s.name] for s in songs}
    generated = following([(s.name, generated_positions[s.name], None, s) for s in songs], 1)

    # every control's runs in one call: a model whose runs share work across songs (the yalta
    # model convolves each distinct frame once) finds the swapped and shifted songs' frames together
    partners = _swap_partners(songs, real, generated.dominant_level)
    lengths = [min(len(songs[i].features), len(songs[j].features)) for i, j in partners]
    swap_jobs = [(songs[j].features[:n], songs[i].first_pose) for (i, j), n in zip(partners, lengths)]
    noisy = []
    if all(s.rms is not None for s in songs):
        for s in songs:
            audio = rng.normal(0.0, s.rms, _samples_for(s, features_of)).astype(np.float32)
            noisy.append((features_of(audio)[: len(s.features)], s.first_pose))
    rolled = []
    for s, rhythm in zip(songs, real.recordings):
        shift = shift_frames(len(s.features), rhythm.beat_period_s, s.fps, rng.uniform(*OFF_GRID))
        rolled.append((np.roll(s.features, shift, axis=0), s.first_pose))
    silent = [features_of(np.zeros(_samples_for(s, features_of), np.float32))[: len(s.features)] for s in songs]
    quiet = [(f, s.first_pose) for f, s in zip(silent, songs)]
    made_runs = iter(run_all(swap_jobs + noisy + rolled + quiet))
    swap_motions, noise_motions, rolled_motions, quiet_motions = (
        [next(made_runs) for _ in jobs] for jobs in (swap_jobs, noisy, rolled, quiet)
    )

    swapped = follows_new = follows_old = changes = None
    if partners:
        runs = [
            (f"{songs[i].name} with {songs[j].name}'s music", motion, None, songs[j], songs[i])
            for (i, j), motion in zip(partners, swap_motions)
        ]
        swapped = following([(n, p, m, s) for n, p, m, s, _ in runs], 1)
        follows_new = float(np.mean([r.in_metre for r in swapped.recordings]))
        follows_old = float(
            np.mean(
                [
                    metrical_level(r.period.period_s, _period(orig), orig.beats_per_bar) is not None
                    for r, (*_, orig) in zip(swapped.recordings, runs)
                ]
            )
        )
        own = {r.name: r.period.period_s for r in generated.recordings}
        changes = float(
            np.mean(
                [_changed(r.period.period_s, own[songs[i].name]) for r, (i, _) in zip(swapped.recordings, partners)]
            )
        )
    noise = following([(s.name, m, None, s) for s, m in zip(songs, noise_motions)], 1) if noisy else None
    shifted = following([(s.name, m, None, s) for s, m in zip(songs, rolled_motions)], 1)
    silence = []
    for s, still in zip(songs, quiet_motions):
        moving = generated_positions[s.name]
        silence.append(motion_energy_per_s(still[_settle(s) :], None, s.fps) / motion_energy_per_s(moving, None, s.fps))
    energy = float(
        np.mean(
            [
                motion_energy_per_s(generated_positions[s.name], None, s.fps)
                / motion_energy_per_s(s.real_positions, s.real_mask, s.fps)
                for s in songs
            ]
        )
    )
    turns = (
        TurningFigures.of(
            [s.body_turning(s.real_positions, s.real_mask) for s in songs],
            [s.body_turning(generated_positions[s.name]) for s in songs],
        )
        if all(np.shape(s.real_positions)[-1] == 3 for s in songs)
        else None
    )
    tempo, tempo_why = _tempo(songs, run_all, features_of, tempo_rates)
    return Listening(
        real=real,
        generated=generated,
        swapped=swapped,
        swapped_follows_new=follows_new,
        swapped_follows_old=follows_old,
        noise=noise,
        shifted=shifted,
        silence_energy_ratio=float(np.mean(silence)),
        energy_ratio=energy,
        turning=turns,
        baselines=_baselines(songs, real, rng, draws, seed),
        generated_positions=generated_positions,
        swapped_period_changes=changes,
        tempo=tempo,
        tempo_unavailable=tempo_why,
    )


def _tempo(
    songs: list[HeldOutSong],
    run_all: Callable[[list[tuple[np.ndarray, np.ndarray]]], list[np.ndarray]],
    features_of: Callable[..., np.ndarray],
    rates: tuple[float, ...] | None,
) -> tuple[TempoControl | None, str]:
    """The tempo control over the songs whose music is known, or (None, why not)."""
    if rates is not None and not rates:
        return None, "not asked"
    if any(s.samples is None for s in songs):
        return None, "the music of some songs could not be read"
    try:
        control = tempo_control(
            [TempoSong(s.name, s.samples, s.first_pose, s.beats_per_bar) for s in songs],
            run_all,
            features_of,
            songs[0].fps,
            **({} if rates is None else {"rates": rates}),
        )
    except KinectDataError as exc:  # no SoX nor librosa, songs too short
        return None, str(exc)
    return control, ""


def _changed(period: float | None, before: float | None) -> bool:
    """Whether a dominant period differs from an earlier one by more than the period tolerance
    (appearing or vanishing counts)."""
    if period is None or before is None:
        return (period is None) != (before is None)
    return abs(period / before - 1) > PERIOD_TOLERANCE


def _settle(song: HeldOutSong) -> int:
    """Frames given to the motion to stop when the music goes silent (one second)."""
    return int(round(song.fps))


def _samples_for(song: HeldOutSong, features_of: Callable[[np.ndarray], np.ndarray]) -> int:
    """Audio samples for the song's frames, as ``features_of`` declares its rate (``sample_rate``
    attribute, default 16 kHz)."""
    rate = getattr(features_of, "sample_rate", 16000)
    return int(np.ceil((len(song.features) + 1) / song.fps * rate)) + rate // 10


def _period(song: HeldOutSong) -> float:
    from kinectdata.evaluation.rhythm import beat_period_s

    return beat_period_s(song.beats_s)


def shift_frames(frames: int, beat_period_s: float, fps: float, fraction: float) -> int:
    """How many frames the shifted-audio control rolls a song of ``frames`` frames by: whole beats
    (``beat_period_s`` seconds each) to reach :data:`MIN_SHIFT_S`, at most a third of a song too short
    for that, then ``fraction`` of a beat more (drawn from :data:`OFF_GRID`), so that the shifted
    music's beats fall between the original ones. Two seconds alone are no whole number of beats: at
    a beat of 0.72 s, 2 s and a quarter beat land 0.03 beat from the original grid, where a motion
    that follows the shifted music also follows the original beats."""
    whole = max(1, int(np.ceil(MIN_SHIFT_S / beat_period_s - 1e-9)))
    if (whole + OFF_GRID[1]) * beat_period_s * fps * 2 >= frames:  # a short song: a third of it at most
        whole = max(0, int((frames / 3 / fps) // beat_period_s) - 1)
    return max(1, int(round((whole + fraction) * beat_period_s * fps)))


def _swap_partners(songs: list[HeldOutSong], real: BeatFollowing, level: str) -> list[tuple[int, int]]:
    """(i, j) pairs: each song with the song whose period at ``level`` (the generated motion's
    dominant level, in each song's metre; the beat for ``none``) differs most from its own, when that
    differs by more than twice the period tolerance (so that following either can be told apart: a
    waltz at 86 BPM and a cha-cha at 120 differ in beat by 40 % and in bar by 3 %), counting twice and
    half a period as the same: a beat tracker that reads a song at twice its beat (librosa reads five
    of Dance with Melody's waltzes at 167 BPM, their beat 83) would otherwise pair two songs of one
    tempo, and a motion that moves to both alike would be taken for one that does not listen."""
    periods = np.array([r.beat_period_s * level_beats(level, s.beats_per_bar) for r, s in zip(real.recordings, songs)])
    pairs = []
    for i, p in enumerate(periods):
        octaves = np.log2(periods / p)
        apart = np.abs(octaves - np.round(octaves)) * np.log(2)  # log-distance to p, 2 p or p / 2 (or 4 p...)
        j = int(np.argmax(apart))
        if apart[j] > np.log(1 + 2 * PERIOD_TOLERANCE):
            pairs.append((i, j))
    return pairs


def _baselines(
    songs: list[HeldOutSong], real: BeatFollowing, rng: np.random.Generator, draws: int, seed: int
) -> dict[str, float | None]:
    """Beat Align Scores (music direction) of the mean pose with noise and of another song's real motion."""
    noisy = []
    for s in songs:
        pos = np.asarray(s.real_positions, np.float64)
        valid = np.isfinite(pos).all(axis=2) if s.real_mask is None else np.asarray(s.real_mask, bool)
        masked = np.where(valid[..., None], pos, np.nan)
        mean, spread = np.nanmean(masked, axis=0), np.nanstd(masked, axis=0)
        fake = mean + rng.normal(size=pos.shape) * np.nan_to_num(spread)
        noisy.append(RecordingBeats(s.name, np.nan_to_num(fake), None, s.fps, s.beats_s, beats_per_bar=s.beats_per_bar))
    noise_score = beat_following(noisy, draws=min(draws, 50), seed=seed).beat_align_music.value
    return {"mean_pose_noise": noise_score, "other_song": real.beat_align_other_songs}


def _p_text(p: float | None) -> str:
    return "n/a" if p is None else (f"= {p:.2g}" if p >= 0.001 else "< 0.001")


def _fmt(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.3f}"
