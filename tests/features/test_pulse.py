"""Pulse (rhythm) features and stacked features: the onset envelope and each frame's values against
a computation done independently (tests/rhythm_reference.py), tempo and phase on click tracks with
known answers (and librosa's tempo), causality, silence, chunking and streaming, configurations."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from rhythm_reference import (
    accented_eighths,
    click_track,
    ideal_pulse,
    reference_frames,
    reference_onsets,
    reference_tempi,
)

from kinectdata.core.errors import ConfigError
from kinectdata.features import (
    PRESETS,
    YALTA_CLOCK_PLANES,
    MelConfig,
    RhythmConfig,
    StackConfig,
    StftConfig,
    compute_features,
    feature_config,
    needs_metre,
)
from kinectdata.features.rhythm import onset_envelope, predominant_beat, rhythm_features
from kinectdata.features.streaming import StreamingFeatures

librosa = pytest.importorskip("librosa")

SR = 16000
VECTOR = RhythmConfig()
PLANE = RhythmConfig(columns=5)
OTHER = RhythmConfig(  # every parameter changed: a hop of 4 ms, shorter windows, fewer bands and tempi
    hop_samples=64,
    frame_samples=400,
    n_mels=24,
    fmax=6000.0,
    detrend_s=0.3,
    window_s=4.0,
    decay_s=1.5,
    n_tempi=20,
    tempo_range_bpm=(60.0, 200.0),
    columns=3,
    column_hop=128,
    column_end=448,
)


def frame_starts(n_samples: int, fps: float = 30.0) -> np.ndarray:
    return np.round(np.arange(int(n_samples / SR * fps)) * SR / fps).astype(np.int64)


def random_clicks(seconds: float, seed: int) -> np.ndarray:
    """float32: white noise at -50 dBFS, clicks (5 ms decaying 1.5 kHz bursts) at random times about
    3 a second, and a kick every 0.5 s with jitter: onsets with some pulse, not a strict one."""
    rng = np.random.default_rng(seed)
    n = int(seconds * SR)
    x = rng.normal(0, 10 ** (-50 / 20), n)
    burst = np.sin(2 * np.pi * 1500 * np.arange(80) / SR) * np.exp(-np.arange(80) / 20)
    kick = np.sin(2 * np.pi * 60 * np.arange(1600) / SR) * np.exp(-np.arange(1600) / 400)
    for t in np.sort(rng.uniform(0, seconds, int(3 * seconds))):
        i = int(t * SR)
        x[i : i + 80] += rng.uniform(0.1, 0.6) * burst[: n - i]
    for t in np.arange(0.25, seconds, 0.5) + rng.normal(0, 0.01, len(np.arange(0.25, seconds, 0.5))):
        i = int(t * SR)
        x[i : i + 1600] += 0.5 * kick[: max(0, min(1600, n - i))]
    return x.astype(np.float32)


@pytest.fixture(scope="module")
def clicks() -> np.ndarray:
    return random_clicks(10.0, seed=4)


# ---------------------------------------------------------------- against the direct computation


@pytest.mark.parametrize("config", [VECTOR, OTHER], ids=["default", "other"])
def test_onset_envelope_matches_an_independent_computation(clicks, config):
    got = onset_envelope(clicks, config)
    expected = reference_onsets(clicks, config)
    assert got.shape == (clicks.size // config.hop_samples + 1,)
    assert (got >= 0).all() and (got > 0).mean() > 0.05  # something to compare: not all zeros
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-7 * expected.max())


@pytest.mark.parametrize("config", [VECTOR, PLANE, OTHER], ids=["vector", "plane", "other"])
def test_frames_match_the_windowed_sum_evaluated_term_by_term(clicks, config):
    starts = frame_starts(clicks.size)
    feats, padded = rhythm_features(clicks, starts, config)
    assert feats.dtype == np.float32 and feats.shape == (starts.size, *config.output_shape)
    settled = config.window_s + config.detrend_s + 0.2  # the reference needs a whole window of onsets
    chosen = np.flatnonzero(starts / SR > settled)
    chosen = np.unique(np.concatenate([chosen[:: max(1, chosen.size // 8)], chosen[-3:]]))  # ... and the last ones
    expected = reference_frames(clicks, starts[chosen], config)
    assert np.abs(expected).max() > 0.3  # a pulse to compare
    np.testing.assert_allclose(feats[chosen], expected, atol=2e-6)
    assert padded[-1] and not padded[chosen[:-3]].any()
    # a frame at a time, as live: each window summed directly instead of the recursion over the audio
    for k, start in enumerate(starts[chosen[:3]]):
        one, _ = rhythm_features(clicks, np.array([start]), config)
        np.testing.assert_allclose(one[0], expected[k], atol=2e-6)


def test_values_are_salience_then_its_cosine_and_sine_tempo_by_tempo(clicks):
    feats, _ = rhythm_features(clicks, frame_starts(clicks.size), VECTOR)
    v = feats[-60:].astype(np.float64).reshape(60, 43, 3)
    salience, cosine, sine = v[..., 0], v[..., 1], v[..., 2]
    assert (salience >= 0).all() and (salience <= 1 + 1e-6).all()
    np.testing.assert_allclose(cosine**2 + sine**2, salience**2, atol=1e-6)
    np.testing.assert_array_equal(PRESETS["yalta2016_rhythm"].parts[1].tempi_bpm, VECTOR.tempi_bpm)
    np.testing.assert_allclose(VECTOR.tempi_bpm, reference_tempi(VECTOR), rtol=1e-12)
    assert VECTOR.tempi_bpm[0] == pytest.approx(40) and VECTOR.tempi_bpm[-1] == pytest.approx(240)


# ---------------------------------------------------------------- click tracks: known tempo and phase


def _best_tempo(feats: np.ndarray, starts: np.ndarray, after_s: float = 7.0) -> float:
    salience = feats[starts / SR > after_s].reshape(-1, 43, 3)[..., 0].mean(axis=0)
    return float(VECTOR.tempi_bpm[np.argmax(salience)])


def _octave_of(tempo: float, truth: float, tolerance: float = 0.04) -> bool:
    return any(abs(tempo / (truth * f) - 1) <= tolerance for f in (0.5, 1.0, 2.0))


@pytest.mark.parametrize("bpm", [75.0, 100.0, 128.0, 150.0])
def test_click_tracks_tempo_and_salience_curve_follow_the_ideal_pulse(bpm):
    """The salience at every tempo is that of an ideal impulse train at the click times (computed in
    continuous time, tempi off the grid included: 100 BPM lies between two grid tempi), within 0.03; the most
    salient tempo is the clicks' or an octave of it, as librosa's tempo estimate is."""
    audio, times = click_track(bpm)
    starts = frame_starts(audio.size)
    feats, _ = rhythm_features(audio, starts, VECTOR)
    tempi = VECTOR.tempi_bpm
    late = np.flatnonzero(starts / SR > 7.0)
    for k in late[::10]:
        t = (starts[k] + VECTOR.slice_samples) / SR
        ideal = np.abs(ideal_pulse(t, times, tempi, VECTOR))
        np.testing.assert_allclose(feats[k].reshape(43, 3)[:, 0], ideal, atol=0.03, err_msg=f"frame {k}")
    best = _best_tempo(feats, starts)
    assert _octave_of(best, bpm), (best, bpm)
    assert feats[late].reshape(-1, 43, 3)[..., 0].max(axis=1).min() > 0.9  # a strict pulse: near 1 throughout
    theirs = float(np.atleast_1d(librosa.feature.tempo(y=audio, sr=SR))[0])
    assert _octave_of(theirs, bpm), (theirs, bpm)
    octaves = math.log2(best / theirs)
    assert abs(octaves - round(octaves)) < math.log2(1.05), (best, theirs)


def test_on_a_grid_tempo_salience_is_one_and_the_phase_is_the_time_since_the_click():
    """Clicks at exactly a grid tempo (116.2 BPM): salience 1 to within the spread of a click's
    onsets over a few hops; the phase is 2 pi f (time since the last click) to within 10 ms (two
    hops: a click's onset is seen at the first hop after it), so it rises linearly over each beat
    and wraps at each click; cosine near 1 just after a click, near -1 half a beat later."""
    k = 25
    bpm = float(VECTOR.tempi_bpm[k])
    audio, times = click_track(bpm)
    starts = frame_starts(audio.size)
    feats, _ = rhythm_features(audio, starts, VECTOR)
    late = np.flatnonzero(starts / SR > 7.0)
    v = feats[late].astype(np.float64).reshape(-1, 43, 3)[:, k]
    assert v[:, 0].min() > 0.98
    phase = np.arctan2(v[:, 2], v[:, 1])
    instant = (starts[late] + VECTOR.slice_samples) / SR
    since = instant - times[np.searchsorted(times, instant, side="right") - 1]  # s since the last click
    allowed = 2 * np.pi * bpm / 60 * 0.010
    error = np.angle(np.exp(1j * (phase - 2 * np.pi * bpm / 60 * since)))
    assert np.abs(error).max() < allowed, np.abs(error).max()
    # the wrap: just after each click the phase is near 0 (cosine near the salience), mid-beat near pi
    just_after = since < 0.03
    assert just_after.sum() >= 5 and (v[just_after, 1] > 0.9).all()
    middle = np.abs(since - 30 / bpm) < 0.03
    assert middle.sum() >= 5 and (v[middle, 1] < -0.9).all()


LEVELS = RhythmConfig(tempo_range_bpm=(15.0, 240.0), n_tempi=65, window_s=12.0, decay_s=4.0, levels=(1, 2, 4))


def accented_bars(
    bpm: float, seconds: float = 30.0, first: float = 0.3, beats_per_bar: int = 4
) -> tuple[np.ndarray, np.ndarray]:
    """(float32 audio, downbeat times in s): bars of ``beats_per_bar`` at ``bpm``, its beats 30 ms
    1.5 kHz tone bursts (a few mel bands rise), each downbeat a 30 ms noise burst (all of them
    rise), over noise at -60 dBFS."""
    n = int(seconds * SR)
    x = np.random.default_rng(0).normal(0, 1e-3, n)
    tone = 0.3 * np.sin(2 * np.pi * 1500 * np.arange(480) / SR) * np.hanning(480)
    noise = 0.3 * np.random.default_rng(1).normal(0, 1, 480) * np.hanning(480)
    beats = np.arange(first, seconds - 0.1, 60.0 / bpm)
    for k, t in enumerate(beats):
        i = int(round(t * SR))
        x[i : i + 480] += noise if k % beats_per_bar == 0 else tone
    return x.astype(np.float32), beats[::beats_per_bar]


@pytest.mark.parametrize("hold", [0.0, 0.3])
@pytest.mark.parametrize("bpm", [100.0, 150.0])
def test_the_predominant_pulse_turns_at_the_beat_and_at_its_bar(bpm, hold):
    """Bars of 4 at 100 and 150 BPM, downbeats louder across the spectrum: the levels' phasors
    (after the 65 tempi) turn at the beat rate, half and a quarter of it (the slope of the unwrapped
    phase against time, fitted by numpy, within half the tempo grid's spacing, 2.2 %), with the
    beat's salience as their length; the bar's phase is 2 pi (bar rate) (time since the downbeat)
    to within 0.4 rad (the onset is seen a few hops after the burst begins, and the grid's tempo
    nearest the bar's, up to 2.2 % off, turns up to 0.14 rad away from it over a bar). The same with
    the beat held (``beat_hold``) where the tempo is steady."""
    audio, downbeats = accented_bars(bpm)
    starts = frame_starts(audio.size)
    feats, _ = rhythm_features(audio, starts, dataclasses.replace(LEVELS, beat_hold=hold))
    assert feats.shape == (starts.size, 3 * 65 + 2 * 3)
    late = np.flatnonzero(starts / SR > 14.0)
    t = (starts[late] + LEVELS.slice_samples) / SR
    spacing = (240.0 / 15.0) ** (1 / 64) - 1
    for i, m in enumerate(LEVELS.levels):
        c, s = feats[late, 195 + 2 * i], feats[late, 196 + 2 * i]
        assert np.hypot(c, s).min() > 0.5
        phase = np.arctan2(s, c)
        turns_per_s = np.polyfit(t, np.unwrap(phase), 1)[0] / (2 * np.pi)
        assert abs(turns_per_s / (bpm / 60 / m) - 1) < spacing / 2 + 1e-3, (m, turns_per_s, bpm / 60 / m)
    since = t - downbeats[np.searchsorted(downbeats, t, side="right") - 1]
    error = np.angle(np.exp(1j * (phase - 2 * np.pi * bpm / 240 * since)))
    assert np.abs(error).max() < 0.4, np.abs(error).max()


BAR_LEVELS = dataclasses.replace(LEVELS, levels=(1,), bar_levels=(1, 2))


@pytest.mark.parametrize("beats_per_bar", [3, 4])
def test_bar_levels_turn_at_the_bar_of_the_songs_metre(beats_per_bar):
    """A waltz (bars of 3) and a song in 4, both at 120 BPM, downbeats louder: given its metre, the
    bar level turns once a bar (1.5 s in 3, 2 s in 4: the slope of the unwrapped phase, within half
    the tempo grid's spacing) and its phase is 2 pi (time since the downbeat) / bar to within 0.4 rad
    (as for the fixed levels above). The values equal fixed levels at (1, m, 2 m) beats (two bars,
    which this music does not repeat, included), and a song whose metre is not given counts bars of 4."""
    bpm = 120.0
    audio, downbeats = accented_bars(bpm, beats_per_bar=beats_per_bar)
    starts = frame_starts(audio.size)
    feats, _ = rhythm_features(audio, starts, BAR_LEVELS, beats_per_bar=beats_per_bar)
    assert feats.shape == (starts.size, 3 * 65 + 2 * 3)
    late = np.flatnonzero(starts / SR > 14.0)
    t = (starts[late] + LEVELS.slice_samples) / SR
    spacing = (240.0 / 15.0) ** (1 / 64) - 1
    for i, beats in enumerate((1, beats_per_bar)):
        phase = np.arctan2(feats[late, 196 + 2 * i], feats[late, 195 + 2 * i])
        turns_per_s = np.polyfit(t, np.unwrap(phase), 1)[0] / (2 * np.pi)
        assert abs(turns_per_s / (bpm / 60 / beats) - 1) < spacing / 2 + 1e-3, (beats, turns_per_s)
    bar_phase = np.arctan2(feats[late, 198], feats[late, 197])
    since = t - downbeats[np.searchsorted(downbeats, t, side="right") - 1]
    error = np.angle(np.exp(1j * (bar_phase - 2 * np.pi * since / (beats_per_bar * 60 / bpm))))
    assert np.abs(error).max() < 0.4, np.abs(error).max()
    fixed = dataclasses.replace(LEVELS, levels=(1, beats_per_bar, 2 * beats_per_bar))
    np.testing.assert_array_equal(feats, rhythm_features(audio, starts, fixed)[0])
    unsaid, _ = rhythm_features(audio, starts, BAR_LEVELS)
    np.testing.assert_array_equal(unsaid, rhythm_features(audio, starts, BAR_LEVELS, beats_per_bar=4)[0])
    assert BAR_LEVELS.needs_metre and not LEVELS.needs_metre


def test_the_metre_reaches_the_pulse_through_stacks_and_streams():
    """compute_features passes the song's beats per bar to a stacked pulse with bar levels (not to
    extractors whose features do not count bars), and streaming gives what the whole audio gives."""
    config = StackConfig((MelConfig(), BAR_LEVELS))
    assert needs_metre(config) and not needs_metre(PRESETS["yalta2016_rhythm"])
    audio, _ = accented_bars(120.0, seconds=14.0, beats_per_bar=3)
    starts = frame_starts(audio.size)
    waltz, _ = compute_features(audio, starts, config, beats_per_bar=3)
    np.testing.assert_array_equal(waltz[:, 80:], rhythm_features(audio, starts, BAR_LEVELS, beats_per_bar=3)[0])
    assert not np.array_equal(waltz, compute_features(audio, starts, config, beats_per_bar=4)[0])
    np.testing.assert_allclose(streamed(audio, starts, config, 16001, beats_per_bar=3), waltz, rtol=0, atol=1e-6)


def streamed(audio: np.ndarray, starts: np.ndarray, config, block: int, beats_per_bar: int | None = None) -> np.ndarray:
    """The features of ``starts`` from a StreamingFeatures pushed ``audio`` ``block`` samples at a time."""
    got = np.full((starts.size, *config.output_shape), np.nan, np.float32)

    def sink(k0, feats, pad):
        got[k0 : k0 + len(feats)] = feats

    stream = StreamingFeatures(starts, config, sink, beats_per_bar=beats_per_bar)
    for i in range(0, audio.size, block):
        stream.push(audio[i : i + block])
    stream.finish()
    return got


COUNTED = dataclasses.replace(BAR_LEVELS, levels=(1, 2), counted_levels=True)


@pytest.mark.parametrize("beats_per_bar", [3, 4])
def test_counted_levels_turn_once_a_bar_where_every_beat_sounds_alike(beats_per_bar):
    """Clicks at 120 BPM, every beat alike: the tempogram's phase at the bar's tempo restarts at
    every click and turns less than once in 4 bars; counted from the beat, the two beats, the bar and
    two bars turn at their rates (the slope of the unwrapped phase within 0.5 %), each frame's turn
    at a level is the beat's turn that frame (numpy's unwrap) divided by the level's beats, every
    level's length is the beat's salience, and the beat and the tempi are as without counting. The
    count runs on across chunks, and across calls that carry a PulseCount, as one call over every
    frame."""
    bpm = 120.0
    audio, _ = click_track(bpm, seconds=30.0)
    starts = frame_starts(audio.size)
    plain, _ = rhythm_features(
        audio, starts, dataclasses.replace(COUNTED, counted_levels=False), beats_per_bar=beats_per_bar
    )
    counted, _ = rhythm_features(audio, starts, COUNTED, beats_per_bar=beats_per_bar)
    levels = 195 + 2 * np.arange(4)  # beat, two beats, bar, two bars: cosine at i, sine at i + 1
    np.testing.assert_array_equal(counted[:, : levels[1]], plain[:, : levels[1]])
    late = np.flatnonzero(starts / SR > 14.0)
    t = (starts[late] + COUNTED.slice_samples) / SR

    def turns_per_s(feats, i):
        return np.polyfit(t, np.unwrap(np.arctan2(feats[late, i + 1], feats[late, i])), 1)[0] / (2 * np.pi)

    bar_rate = bpm / 60 / beats_per_bar
    assert abs(turns_per_s(plain, levels[2])) < bar_rate / 4
    beat = np.arctan2(counted[late, levels[0] + 1], counted[late, levels[0]])
    for i, beats in zip(levels[1:], (2, beats_per_bar, 2 * beats_per_bar)):
        assert abs(turns_per_s(counted, i) / (bpm / 60 / beats) - 1) < 0.005, beats
        level = np.arctan2(counted[late, i + 1], counted[late, i])
        np.testing.assert_allclose(np.diff(np.unwrap(level)), np.diff(np.unwrap(beat)) / beats, atol=1e-4)
        np.testing.assert_allclose(
            np.hypot(counted[:, i], counted[:, i + 1]), np.hypot(counted[:, 195], counted[:, 196]), atol=1e-6
        )
    chunked, _ = rhythm_features(audio, starts, COUNTED, beats_per_bar=beats_per_bar, chunk_frames=97)
    np.testing.assert_allclose(chunked, counted, rtol=0, atol=1e-5)
    state, half = COUNTED.new_state(), starts.size // 2
    first, _ = rhythm_features(audio, starts[:half], COUNTED, beats_per_bar=beats_per_bar, state=state)
    rest, _ = rhythm_features(audio, starts[half:], COUNTED, beats_per_bar=beats_per_bar, state=state)
    np.testing.assert_allclose(np.concatenate([first, rest]), counted, rtol=0, atol=1e-5)
    silent, _ = rhythm_features(np.zeros(SR * 3, np.float32), frame_starts(SR * 3), COUNTED)
    assert not silent.any()


def test_the_harmonic_weight_picks_the_beat_where_its_eighth_notes_are_more_salient():
    """Accented eighth notes at 90 BPM: the onsets are most periodic at 180 BPM, which the plain
    pick takes (level 1 turning at 3 Hz); with the salience at twice each tempo added
    (``harmonic_weight`` 1) the beat is 90 BPM (1.5 Hz), the fit within the tempo grid's spacing."""
    audio = accented_eighths(90.0)
    starts = frame_starts(audio.size)
    late = np.flatnonzero(starts / SR > 14.0)
    t = (starts[late] + LEVELS.slice_samples) / SR
    spacing = (240.0 / 15.0) ** (1 / 64) - 1
    for weight, beat_bpm in ((0.0, 180.0), (1.0, 90.0)):
        config = dataclasses.replace(LEVELS, harmonic_weight=weight)
        feats, _ = rhythm_features(audio, starts, config)
        phase = np.arctan2(feats[late, 196], feats[late, 195])
        turns_per_s = np.polyfit(t, np.unwrap(phase), 1)[0] / (2 * np.pi)
        assert abs(turns_per_s / (beat_bpm / 60) - 1) < spacing / 2 + 1e-3, (weight, turns_per_s)


def test_a_held_beat_changes_only_when_another_tempo_is_clearly_ahead():
    """Saliences made by hand at two neighbouring tempi, their scores (salience x the prior
    exp(-log2(bpm / 120)^2 / 2), computed here) in the ratios ``ratio``: picked afresh, the beat
    follows every frame's greater score; held with a margin of 0.3, it moves to the other tempo only
    where that one's score is more than 1.3 x its own (frame 5: 1.31; back at frame 8: 1 / 0.76)."""
    config = dataclasses.replace(LEVELS, harmonic_weight=0.0)
    tempi = config.tempi_bpm
    a, b = int(np.argmin(np.abs(tempi - 120.0))), int(np.argmin(np.abs(tempi - 120.0))) + 1
    prior = np.exp(-0.5 * np.log2(tempi / 120.0) ** 2)
    ratio = np.array([0.9, 1.1, 0.95, 1.2, 1.29, 1.31, 0.99, 0.8, 0.76, 0.7])
    salience = np.zeros((ratio.size, tempi.size))
    salience[:, a] = 0.4 / prior[a]
    salience[:, b] = 0.4 * ratio / prior[b]
    fresh = predominant_beat(salience, config)
    np.testing.assert_array_equal(fresh, np.where(ratio > 1, b, a))
    held = predominant_beat(salience, dataclasses.replace(config, beat_hold=0.3))
    np.testing.assert_array_equal(held, [a, a, a, a, a, b, b, b, a, a])
    with pytest.raises(ConfigError, match=r"consecutive frames \[F, n_tempi\]"):
        predominant_beat(salience[None], dataclasses.replace(config, beat_hold=0.3))


def test_a_held_beat_moves_only_the_levels_and_streams_as_one_call():
    """Onsets with a loose pulse: holding the beat leaves every tempo's values as they were, changes
    the levels' clocks where the pick would have flickered between tempi, and its hold runs on
    across chunks and across the calls of a stream as in one call over every frame."""
    config = dataclasses.replace(BAR_LEVELS, beat_hold=0.3, harmonic_weight=1.0)
    audio = random_clicks(20.0, seed=5)
    starts = frame_starts(audio.size)
    fresh, _ = rhythm_features(audio, starts, dataclasses.replace(config, beat_hold=0.0), beats_per_bar=3)
    held, _ = rhythm_features(audio, starts, config, beats_per_bar=3)
    np.testing.assert_array_equal(held[:, :195], fresh[:, :195])
    assert np.any(np.abs(held[:, 195:] - fresh[:, 195:]) > 0.1)
    chunked, _ = rhythm_features(audio, starts, config, beats_per_bar=3, chunk_frames=97)
    np.testing.assert_allclose(chunked, held, rtol=0, atol=1e-5)
    np.testing.assert_allclose(streamed(audio, starts, config, 7001, beats_per_bar=3), held, rtol=0, atol=1e-6)


def test_without_the_tempo_phases_a_frame_is_the_saliences_then_the_levels():
    """``tempo_phases=False``: per tempo the salience alone (the first of the three values the
    phases come with, which tests above check against the direct computation), the levels unchanged."""
    audio = accented_bars(100.0, seconds=16.0)[0]
    starts = frame_starts(audio.size)
    full, _ = rhythm_features(audio, starts, LEVELS)
    bare_config = dataclasses.replace(LEVELS, tempo_phases=False)
    bare, _ = rhythm_features(audio, starts, bare_config)
    assert bare_config.output_shape == (65 + 2 * 3,) == bare.shape[1:]
    np.testing.assert_array_equal(bare[:, :65], full[:, 0:195:3])
    np.testing.assert_array_equal(bare[:, 65:], full[:, 195:])


def test_without_the_saliences_a_frame_is_the_levels_alone():
    """``saliences=False``: only the levels' clocks, the same values as after the tempi of the full
    output (whose levels the tests above check against the ideal pulse); the tempi still pick the beat."""
    audio = accented_bars(100.0, seconds=16.0)[0]
    starts = frame_starts(audio.size)
    full, full_padded = rhythm_features(audio, starts, LEVELS)
    clocks_config = dataclasses.replace(LEVELS, tempo_phases=False, saliences=False)
    clocks, padded = rhythm_features(audio, starts, clocks_config)
    assert clocks_config.output_shape == (2 * 3,) == clocks.shape[1:]
    np.testing.assert_array_equal(clocks, full[:, 195:])
    np.testing.assert_array_equal(padded, full_padded)
    assert np.abs(clocks).max() > 0.9  # not all zeros: the clocks turn
    d = json.loads(json.dumps(clocks_config.to_dict()))
    assert d["saliences"] is False and RhythmConfig.from_dict(d) == clocks_config
    assert "saliences" not in LEVELS.to_dict()  # a dataset built before the setting keeps its build key
    assert PRESETS["listen_to_dance_clocks"].output_shape == (6,)
    assert PRESETS["listen_to_dance_clocks_style"].output_shape == (10,)


def test_the_held_preset_is_the_bar_pulse_with_its_beat_held_and_its_clocks_at_unit_amplitude():
    """``listen_to_dance_rhythm_held_style``: the 80 log-mel bands, the bar pulse's 65 saliences with
    the beat's, the bar's and two bars' clocks (no two beats' clock) at unit amplitude and the beat
    held at 1, then the style's 4 values; its configuration round-trips through JSON."""
    from kinectdata.features import LISTEN_TO_DANCE_HELD_PULSE, StackConfig, feature_config

    stack = PRESETS["listen_to_dance_rhythm_held_style"]
    mel, pulse, style = stack.parts
    assert pulse is LISTEN_TO_DANCE_HELD_PULSE
    assert (pulse.levels, pulse.bar_levels, pulse.n_tempi, pulse.beat_hold) == ((1,), (1, 2), 65, 1.0)
    assert pulse.unit_levels and pulse.saliences and not pulse.counted_levels and not pulse.tempo_phases
    assert (mel.output_shape, pulse.output_shape, style.output_shape) == ((80,), (65 + 2 * 3,), (4,))
    assert stack.output_shape == (155,)
    back = feature_config(json.loads(json.dumps(stack.to_dict())))
    assert isinstance(back, StackConfig) and back == stack


def test_clock_planes_hold_each_value_of_the_vector_as_a_constant_plane():
    """``planes``: every value of the vector layout (the clocks, which the tests above check against
    the ideal pulse) fills its own [rows, columns] plane, in the same order; the yalta preset's clocks
    and style stack after its spectra and pulse as 6 + 4 planes."""
    audio = accented_bars(100.0, seconds=16.0)[0]
    starts = frame_starts(audio.size)
    clocks_config = dataclasses.replace(LEVELS, tempo_phases=False, saliences=False, unit_levels=True)
    vector, vector_padded = rhythm_features(audio, starts, clocks_config, beats_per_bar=3)
    plane_config = dataclasses.replace(clocks_config, planes=(129, 5))
    planes, padded = rhythm_features(audio, starts, plane_config, beats_per_bar=3)
    assert plane_config.output_shape == (6, 129, 5) == planes.shape[1:]
    for k in range(6):
        assert (planes[:, k] == vector[:, k, None, None]).all()
    np.testing.assert_array_equal(padded, vector_padded)
    assert np.abs(vector).max() > 0.9
    d = json.loads(json.dumps(plane_config.to_dict()))
    assert d["planes"] == [129, 5] and RhythmConfig.from_dict(d) == plane_config
    assert "planes" not in clocks_config.to_dict()  # a dataset built before the setting keeps its build key
    preset = PRESETS["yalta2016_rhythm_clocks_style"]
    assert preset.output_shape == (12, 129, 5)
    assert [p.output_shape[0] for p in preset.parts] == [1, 1, 6, 4]


@pytest.mark.parametrize("counted", [False, True], ids=["tempogram", "counted"])
def test_unit_levels_keep_the_phase_at_length_one_and_are_zero_in_silence(counted):
    """``unit_levels``: every level's phasor, plain or counted, has the phase it has when scaled by
    the beat's salience (the angle of the same cosine and sine) and length 1 wherever the scaled one
    is not 0, 0 where it is (silence); the tempi's values are untouched. Music whose onsets are
    noisy (random clicks: the beat's salience well below 1) shows the difference."""
    audio = np.concatenate([random_clicks(16.0, seed=7), np.zeros(int(16 * SR), np.float32)])
    starts = frame_starts(audio.size)
    scaled_config = dataclasses.replace(COUNTED, counted_levels=counted)
    unit_config = dataclasses.replace(scaled_config, unit_levels=True)
    scaled, _ = rhythm_features(audio, starts, scaled_config, beats_per_bar=3)
    unit, _ = rhythm_features(audio, starts, unit_config, beats_per_bar=3)
    np.testing.assert_array_equal(unit[:, :195], scaled[:, :195])
    for i in range(195, 195 + 2 * 4, 2):
        length = np.hypot(scaled[:, i], scaled[:, i + 1])
        on = length > 0
        assert 0.05 < np.median(length[on]) < 0.9 and (~on).sum() > 30  # noisy onsets, then silence
        np.testing.assert_allclose(np.hypot(unit[on, i], unit[on, i + 1]), 1.0, atol=1e-5)
        assert not unit[~on, i : i + 2].any()
        turn = np.angle((unit[on, i] + 1j * unit[on, i + 1]) * (scaled[on, i] - 1j * scaled[on, i + 1]))
        assert np.abs(turn).max() < 1e-4
    d = json.loads(json.dumps(unit_config.to_dict()))
    assert d["unit_levels"] is True and RhythmConfig.from_dict(d) == unit_config
    assert "unit_levels" not in scaled_config.to_dict()  # a dataset built before the setting keeps its build key


def test_the_predominant_pulse_is_zero_in_silence_and_its_settings_round_trip():
    audio, _ = click_track(120.0, seconds=20.0)
    audio[int(8 * SR) :] = 0.0
    starts = frame_starts(audio.size)
    feats, _ = rhythm_features(audio, starts, LEVELS)
    assert np.all(feats[starts / SR > 8.0 + LEVELS.window_s + 1.0, 195:] == 0.0)
    assert np.abs(feats[(starts / SR > 5.0) & (starts / SR < 7.5), 195:]).max() > 0.9
    assert RhythmConfig.from_dict(json.loads(json.dumps(LEVELS.to_dict()))) == LEVELS
    halved = dataclasses.replace(LEVELS, harmonic_weight=0.5, beat_hold=0.3)
    assert RhythmConfig.from_dict(json.loads(json.dumps(halved.to_dict()))) == halved
    assert "beat_hold" not in LEVELS.to_dict() and halved.to_dict()["beat_hold"] == 0.3
    assert LEVELS.output_shape == (201,) and RhythmConfig().levels == ()


# ---------------------------------------------------------------- causality, silence, padding


@pytest.mark.parametrize("config", [VECTOR, PLANE], ids=["vector", "plane"])
def test_a_frame_does_not_depend_on_audio_after_its_slice(clicks, config):
    starts = frame_starts(clicks.size)
    before, _ = rhythm_features(clicks, starts, config)
    cut = int(starts[250]) + config.slice_samples  # frame 250's slice ends here
    other = clicks.copy()
    other[cut:] = np.random.default_rng(1).normal(0, 0.5, other.size - cut)
    after, _ = rhythm_features(other, starts, config)
    ends = starts + config.slice_samples
    np.testing.assert_array_equal(after[ends <= cut], before[ends <= cut])
    assert np.abs(after[ends > cut + 2000] - before[ends > cut + 2000]).max() > 0.01  # the change shows later


def test_a_frame_depends_only_on_its_own_samples_not_on_where_the_audio_begins(clicks):
    """The same samples prefixed with any number of zeros (here not a multiple of the hop) give the
    same values for the same frames: the onsets are taken on a grid through each frame's instants."""
    starts = frame_starts(clicks.size)
    base, _ = rhythm_features(clicks, starts, PLANE)
    for shift in (37, 80, 1001):
        shifted, _ = rhythm_features(np.concatenate([np.zeros(shift, np.float32), clicks]), starts + shift, PLANE)
        np.testing.assert_allclose(shifted, base, atol=1e-6, err_msg=f"shift {shift}")


def test_silence_gives_zeros_also_long_after_music():
    """Digital silence: every value exactly 0, from the start and once a whole window has passed
    since the music stopped (its onsets have left the window: no rounding residue may remain)."""
    starts = frame_starts(16 * SR)
    feats, _ = rhythm_features(np.zeros(16 * SR, np.float32), starts, VECTOR)
    assert not feats.any()
    for seed in range(4):
        music = random_clicks(7.0, seed=seed)
        audio = np.concatenate([music, np.zeros(8 * SR, np.float32)])
        feats, _ = rhythm_features(audio, starts, VECTOR)
        onsets_gone = starts / SR > 7.0 + VECTOR.window_s + 0.05
        assert np.abs(feats[starts / SR < 7.0]).max() > 0.3
        assert not feats[onsets_gone].any(), (seed, np.abs(feats[onsets_gone]).max())
        assert np.abs(feats).max() <= 1 + 1e-6


def test_padded_only_where_the_slice_runs_off_the_audio_not_its_history():
    audio = random_clicks(3.0, seed=2)
    starts = np.array([-600, -1, 0, 5, 16000, audio.size - 534, audio.size - 533, audio.size + 100])
    feats, padded = rhythm_features(audio, starts, PLANE)
    np.testing.assert_array_equal(padded, [True, True, False, False, False, False, True, True])
    assert feats.shape == (8, 1, 129, 5) and np.isfinite(feats).all()
    assert PLANE.span == (-PLANE.history, 534) and PLANE.history > 6.4 * SR  # history reaches before the audio
    # a frame entirely before the audio reads only zeros
    assert not feats[0].any()


# ---------------------------------------------------------------- chunking and streaming


@pytest.mark.parametrize("config", [VECTOR, PLANE], ids=["vector", "plane"])
def test_chunking_does_not_change_the_values(clicks, config):
    starts = frame_starts(clicks.size)
    whole, padded = rhythm_features(clicks, starts, config, chunk_frames=1024)
    chunked, padded7 = rhythm_features(clicks, starts, config, chunk_frames=7)
    np.testing.assert_allclose(chunked, whole, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(padded7, padded)
    reordered, _ = rhythm_features(clicks, starts[::-1], config, chunk_frames=50)  # frames in any order
    np.testing.assert_allclose(reordered[::-1], whole, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "preset",
    [
        "yalta2016_rhythm",
        "listen_to_dance_rhythm",
        "listen_to_dance_rhythm_counted",
        "listen_to_dance_clocks",
        "yalta_clock_planes",
    ],
)
@pytest.mark.parametrize("block", [1777, 16001])
def test_streaming_equals_the_whole_audio(preset, block):
    config = {**PRESETS, "yalta_clock_planes": YALTA_CLOCK_PLANES}[preset]
    audio = random_clicks(11.0, seed=block)
    starts = frame_starts(audio.size + 300)  # the last frames run past the end
    expected, expected_padded = compute_features(audio, starts, config)
    got, padded = np.full_like(expected, np.nan), np.zeros(starts.size, bool)

    def sink(k0, feats, pad):
        got[k0 : k0 + len(feats)], padded[k0 : k0 + len(feats)] = feats, pad

    stream = StreamingFeatures(starts, config, sink)
    lo, hi = config.span
    for i in range(0, audio.size, block):
        stream.push(audio[i : i + block])
        assert stream.buffer.size <= block + (hi - lo) + 534
    stream.finish()
    assert not np.isnan(got).any()
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(padded, expected_padded)


@pytest.mark.parametrize("preset", ["listen_to_dance_rhythm_counted", "listen_to_dance_rhythm_bars"])
def test_a_live_stream_reuses_its_onset_spectra_and_gives_the_same_features(preset):
    """Blocks of 5 ms, as a live session pushes them: the stream that keeps its onset spectra
    (``live``) gives exactly the features of one that computes them afresh for every frame, and
    computes a small part of them."""
    from kinectdata.features import rhythm

    config = PRESETS[preset]
    audio = random_clicks(5.0, seed=3)
    starts = frame_starts(audio.size)
    computed = []
    original = rhythm.onset_envelope

    def counting(samples, config, spectra=None, at=0, real=None):
        if spectra is not None:
            kept = lambda: sum(int(known.sum()) for _, _, known in spectra.grids.values())  # noqa: E731
            before = kept()
            out = original(samples, config, spectra, at, real)
            computed.append(kept() - before)
            return out
        return original(samples, config, spectra, at, real)

    results = []
    for live in (False, True):
        got = np.full((starts.size, *config.output_shape), np.nan, np.float32)

        def sink(k0, feats, pad, got=got):
            got[k0 : k0 + len(feats)] = feats

        stream = StreamingFeatures(starts, config, sink, beats_per_bar=3, live=live)
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(rhythm, "onset_envelope", counting)
            for i in range(0, audio.size, 80):
                stream.push(audio[i : i + 80])
            stream.finish()
        results.append(got)
    np.testing.assert_array_equal(results[1], results[0])
    hops = PRESETS[preset].parts[-1].history // 80 if hasattr(PRESETS[preset], "parts") else config.history // 80
    assert len(computed) >= starts.size - 1 and np.median(computed) < 0.05 * hops  # a few new hops a frame


# ---------------------------------------------------------------- configurations


def test_rhythm_config_round_trip_and_dispatch():
    for config in (VECTOR, PLANE, OTHER, BAR_LEVELS, COUNTED):
        d = json.loads(json.dumps(config.to_dict()))
        assert d["extractor"] == "rhythm" and feature_config(d) == config and RhythmConfig.from_dict(d) == config
    # no bar levels, no key: the dict (and so a dataset's build key) as before bar levels existed
    assert "bar_levels" not in VECTOR.to_dict() and BAR_LEVELS.to_dict()["bar_levels"] == [1, 2]
    assert "counted_levels" not in BAR_LEVELS.to_dict() and COUNTED.to_dict()["counted_levels"] is True
    assert VECTOR.output_shape == (129,) and PLANE.output_shape == (1, 129, 5) and OTHER.output_shape == (1, 60, 3)
    np.testing.assert_array_equal(PLANE.instants, [160, 240, 320, 400, 480])  # the STFT sub-frames' ends
    with pytest.raises(ConfigError, match="unknown RhythmConfig keys"):
        RhythmConfig.from_dict({**VECTOR.to_dict(), "tempo": 120})
    with pytest.raises(ConfigError, match="not a rhythm configuration"):
        RhythmConfig.from_dict({**VECTOR.to_dict(), "extractor": "mel"})


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"hop_samples": 0}, "hop_samples must be a positive integer"),
        ({"n_tempi": -3}, "n_tempi must be a positive integer"),
        ({"frame_samples": 2.5}, "frame_samples must be a positive integer"),
        ({"n_mels": True}, "n_mels must be a positive integer"),
        ({"columns": -1}, "columns must be a whole number at least 0"),
        ({"tempo_range_bpm": (240.0, 40.0)}, r"tempo_range_bpm must be \(low, high\) with 0 < low < high"),
        ({"tempo_range_bpm": (0.0, 40.0)}, "tempo_range_bpm"),
        ({"decay_s": 0}, "decay_s must be positive"),
        ({"window_s": 1.0}, r"window_s \(1 s\) must hold one beat of 40 BPM"),
        ({"columns": 8}, "the columns must lie at or after the slice start"),
        ({"columns": 2, "column_end": 600}, "slice"),
        ({"levels": (1, 0)}, "levels must be whole numbers at least 1"),
        ({"bar_levels": (0,)}, "bar_levels must be whole numbers at least 1"),
        ({"bar_levels": (1,), "columns": 5}, "levels are for the vector layout"),
        ({"beat_range_bpm": (30.0, 200.0)}, r"beat_range_bpm \(30, 200\) must be a range within tempo_range_bpm"),
        ({"levels": (1, 2), "columns": 5}, "levels are for the vector layout"),
        ({"harmonic_weight": -0.5}, "harmonic_weight must be at least 0"),
        ({"levels": (1,), "beat_hold": -0.1}, "beat_hold must be a finite number at least 0"),
        ({"levels": (1,), "beat_hold": "some"}, "beat_hold must be a finite number at least 0"),
        ({"levels": (1,), "beat_hold": float("inf")}, "beat_hold must be a finite number at least 0"),
        ({"beat_hold": 0.3}, "beat_hold holds the levels' beat: give levels or bar_levels"),
        ({"tempo_phases": "no"}, "tempo_phases must be true or false"),
        ({"levels": (1,), "counted_levels": 1}, "counted_levels must be true or false"),
        ({"counted_levels": True}, "counted_levels counts the levels: give levels or bar_levels"),
        ({"saliences": 0}, "saliences must be true or false"),
        ({"levels": (1,), "unit_levels": "yes"}, "unit_levels must be true or false"),
        ({"unit_levels": True}, "unit_levels sets the levels' amplitude: give levels or bar_levels"),
        ({"saliences": False, "tempo_phases": False}, "without the saliences .* give levels or bar_levels"),
        ({"saliences": False, "levels": (1,)}, "without the saliences .* no tempo_phases"),
        ({"planes": (129,)}, r"planes must be \(rows, columns\)"),
        ({"planes": (129, 0)}, r"planes must be \(rows, columns\)"),
        ({"planes": (129, 5), "columns": 5}, "planes are for the vector layout"),
    ],
)
def test_bad_rhythm_settings_are_config_errors(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        RhythmConfig(**kwargs)


def test_stack_presets_shapes_spans_and_round_trip():
    yalta, ltd = PRESETS["yalta2016_rhythm"], PRESETS["listen_to_dance_rhythm"]
    assert yalta.output_shape == (2, 129, 5) and ltd.output_shape == (153,)
    assert PRESETS["motion_dance_rhythm"].output_shape == (2, 129, 5)
    for config in (yalta, ltd):
        lo, hi = config.span
        # the pulse's window (6 s; 12 s for the cdhc model's), detrending and first spectrum before the slice
        assert (12.4 < -lo / SR < 12.5) if config is ltd else (6.4 < -lo / SR < 6.5)
        assert hi == (779 if config is ltd else 534)  # the mel window reaches 779 samples after the slice start
        d = json.loads(json.dumps(config.to_dict()))
        assert d["extractor"] == "stack" and feature_config(d) == config
    assert yalta.parts[0] == PRESETS["yalta2016"] and ltd.parts[0] == PRESETS["listen_to_dance"]
    assert (yalta.sample_rate, yalta.slice_samples) == (16000, 534)


def test_stacked_features_are_their_parts_concatenated_and_padded_where_any_part_is():
    audio = random_clicks(2.0, seed=9)
    starts = np.array([-100, 0, 3000, audio.size - 534, audio.size - 600])
    for name, axis_len in (("yalta2016_rhythm", 2), ("listen_to_dance_rhythm", 153)):
        config = PRESETS[name]
        feats, padded = compute_features(audio, starts, config)
        parts = [compute_features(audio, starts, p) for p in config.parts]
        assert feats.shape == (5, *config.output_shape) and feats.shape[1] == axis_len
        np.testing.assert_array_equal(feats, np.concatenate([f for f, _ in parts], axis=1))
        np.testing.assert_array_equal(padded, parts[0][1] | parts[1][1])
    # the mel window reaches 245 samples before the slice and past its end: frame 1 is padded by it alone
    assert padded.tolist() == [True, True, False, True, True]


@pytest.mark.parametrize(
    "parts, message",
    [
        ((StftConfig(),), "at least two parts"),
        ((StftConfig(), RhythmConfig()), "agree beyond their first axis"),
        ((MelConfig(), RhythmConfig(columns=5)), "agree beyond their first axis"),
        ((MelConfig(), RhythmConfig(sample_rate=22050)), "share sample rate and slice"),
        ((MelConfig(), RhythmConfig(slice_samples=640)), "share sample rate and slice"),
        ((StackConfig((MelConfig(), RhythmConfig())), MelConfig()), "cannot hold stacked features"),
    ],
)
def test_bad_stacks_are_config_errors(parts, message):
    with pytest.raises(ConfigError, match=message):
        StackConfig(parts)


def test_bad_stack_dicts_are_config_errors():
    good = PRESETS["listen_to_dance_rhythm"].to_dict()
    with pytest.raises(ConfigError, match="list of parts"):
        feature_config({**good, "extra": 1})
    with pytest.raises(ConfigError, match="list of parts"):
        feature_config({"extractor": "stack", "parts": "mel"})
    with pytest.raises(ConfigError, match="unknown feature extractor"):
        feature_config({"extractor": "stack", "parts": [{"extractor": "cqt"}, good["parts"][1]]})
    nested = {"extractor": "stack", "parts": [good, good["parts"][0]]}
    with pytest.raises(ConfigError, match="cannot hold stacked features"):
        feature_config(nested)


def test_kept_onset_spectra_move_on_with_a_long_stream_and_stay_exact():
    """A pulse reading 1 s of onsets (80-200 BPM) over 12 s of audio, its kept spectra 400 hops (2 s) a grid: the
    grids move on many times, the stream's buffer is trimmed, and the features stay those computed
    afresh."""
    from kinectdata.features.rhythm import OnsetSpectra

    config = RhythmConfig(window_s=1.0, tempo_range_bpm=(80.0, 200.0))
    audio = random_clicks(12.0, seed=5)
    starts = frame_starts(audio.size)
    results = []
    for live in (False, True):
        got = np.full((starts.size, *config.output_shape), np.nan, np.float32)

        def sink(k0, feats, pad, got=got):
            got[k0 : k0 + len(feats)] = feats

        stream = StreamingFeatures(starts, config, sink, live=live)
        if live:
            stream.state.spectra = OnsetSpectra(keep=400)
        for i in range(0, audio.size, 80):
            stream.push(audio[i : i + 80])
        stream.finish()
        results.append(got)
    assert stream.buffer_start > 0 and all(first > 0 for first, _, _ in stream.state.spectra.grids.values())
    np.testing.assert_array_equal(results[1], results[0])
