"""Beat following, metrical levels and chance levels on motions with known periods and phases."""

from __future__ import annotations

import numpy as np
import pytest

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.beat_following import (
    TEMPO_PRIOR_BPM,
    RecordingBeats,
    _prior_match_rate,
    beat_following,
    dominant_level,
    dominant_period,
    metrical_level,
)

FPS = 30.0


def bouncer(period_s: float, seconds: float = 40.0, *, phase_s: float = 0.0, seed: int = 0, joints: int = 8):
    """[T, J, 3] metres: every joint bounces down and up once per ``period_s`` (lowest at
    ``phase_s + k * period_s``), over a slow sway in x, with 2 mm of sensor noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FPS)) / FPS
    pos = np.zeros((t.size, joints, 3))
    for j in range(joints):
        pos[:, j, 0] = 0.1 * j + 0.2 * np.sin(2 * np.pi * t / 7.3) + rng.normal(0, 0.002, t.size)
        pos[:, j, 1] = 0.2 * j - rng.uniform(0.03, 0.06) * np.cos(2 * np.pi * (t - phase_s) / period_s)
        pos[:, j, 1] += rng.normal(0, 0.002, t.size)
        pos[:, j, 2] = 2.5 + rng.normal(0, 0.002, t.size)
    return pos


def beats(period_s: float, seconds: float = 40.0, first: float = 0.0) -> np.ndarray:
    return np.arange(first, seconds, period_s)


@pytest.mark.parametrize(
    ("motion_beats", "level"), [(1, "beat"), (2, "two beats"), (4, "bar"), (8, "two bars"), (0.5, "half beat")]
)
def test_dominant_period_and_its_metrical_level(motion_beats, level):
    beat = 0.5
    pos = bouncer(beat * motion_beats, seconds=60.0)
    estimate = dominant_period(pos, None, FPS, max_lag_s=2 * 4 * beat * 1.2)
    assert estimate.period_s == pytest.approx(beat * motion_beats, rel=0.03)
    assert metrical_level(estimate.period_s, beat) == level


def test_a_motion_that_repeats_per_beat_is_at_the_beat_not_its_multiples():
    """A bounce every beat plus a sway every bar: the autocorrelation peaks at 1, 2, 3, 4 beats;
    the shortest strong one is the period."""
    beat = 0.6
    pos = bouncer(beat, seconds=60.0)
    t = np.arange(len(pos)) / FPS
    pos[:, :, 1] += 0.01 * np.sin(2 * np.pi * t / (4 * beat))[:, None]
    estimate = dominant_period(pos, None, FPS, max_lag_s=2 * 4 * beat * 1.2)
    assert metrical_level(estimate.period_s, beat) == "beat"
    assert len(estimate.peaks) >= 4


def test_metrical_level_tolerance_is_ten_percent():
    assert metrical_level(0.545, 0.5) == "beat"
    assert metrical_level(0.56, 0.5) is None
    assert metrical_level(1.5, 0.5, beats_per_bar=3) == "bar"
    assert metrical_level(None, 0.5) is None


def test_white_noise_has_no_dominant_period_at_the_beat():
    pos = np.random.default_rng(3).normal(0, 0.01, (1200, 8, 3))
    estimate = dominant_period(pos, None, FPS, max_lag_s=5.0)
    assert estimate.period_s is None or metrical_level(estimate.period_s, 0.5) is None


def test_prior_match_rate_equals_monte_carlo():
    rng = np.random.default_rng(0)
    tempi = np.exp(rng.uniform(*np.log(TEMPO_PRIOR_BPM), 400_000))
    for period in (0.35, 0.5, 0.9, 1.05):
        expected = np.mean(np.abs(period / (60 / tempi) - 1) <= 0.1)
        assert _prior_match_rate(period) == pytest.approx(expected, abs=0.003)


def _set(periods, *, phase_s=0.0, motion_periods=None, seconds=40.0):
    recs = []
    for i, p in enumerate(periods):
        mp = p if motion_periods is None else motion_periods[i]
        recs.append(
            RecordingBeats(f"r{i}", bouncer(mp, seconds, phase_s=phase_s, seed=i), None, FPS, beats(p, seconds))
        )
    return recs


def test_a_tie_between_levels_goes_to_the_finer_one_whatever_the_songs_order():
    """Three songs danced at two beats and three at the bar: the same dominant level, and the same
    tempo rank read at it, with the songs listed either way round (the first listed once decided:
    the rank was read at the bar one way and at two beats the other)."""
    periods = [0.75, 0.63, 0.55, 0.48, 0.70, 0.52]
    motion = [2 * p for p in periods[:3]] + [4 * p for p in periods[3:]]
    songs = _set(periods, motion_periods=motion)
    forward, backward = beat_following(songs, draws=50), beat_following(songs[::-1], draws=50)
    assert forward.levels == {"two beats": 3, "bar": 3} and list(backward.levels) == ["bar", "two beats"]
    assert forward.dominant_level == backward.dominant_level == "two beats"
    assert forward.tempo_correlation is not None
    assert forward.tempo_correlation == pytest.approx(backward.tempo_correlation)
    assert dominant_level({"none": 3, "bar": 3}) == "bar" and dominant_level({"none": 4, "bar": 3}) == "none"
    assert dominant_level({"two bars": 2, "beat": 2, "bar": 1}) == "beat" and dominant_level({}) == "none"


def test_motion_locked_to_the_beat_follows_it_significantly():
    periods = [0.75, 0.63, 0.55, 0.48, 0.41]  # 80..146 BPM
    result = beat_following(_set(periods), draws=300)
    assert result.at_beat.value == 1.0 and result.in_metre.value == 1.0
    assert result.at_beat.chance < 0.3 and result.at_beat.p_value < 0.01
    assert result.in_metre.chance < 0.6 and result.in_metre.p_value < 0.05
    assert result.levels == {"beat": 5}
    assert result.tempo_correlation == pytest.approx(1.0)
    assert result.tempo_p_value == pytest.approx(1 / 120) and result.follows_tempo  # 5 songs: 5! orderings
    assert result.beat_align_music.value > result.beat_align_music.chance + 3 * result.beat_align_music.chance_spread
    assert result.beat_align_music.p_value < 0.01 and result.on_beat and result.follows_beat
    assert result.beat_align_other_songs < result.beat_align_music.value
    lines = result.verdicts("generated motion")
    assert lines[0].startswith("generated motion follows the beat: yes")
    assert lines[1].startswith("generated motion moves on the beats: yes")
    assert lines[2].startswith("generated motion follows the tempo: yes")


def test_motion_at_the_right_tempo_but_off_phase_follows_the_beat_but_not_on_the_beats():
    """Lowest half-way between the beats: the period is right, the phase is not. Speed minima (at
    the bottom and top of the bounce) then sit a quarter beat from every music beat."""
    periods = [0.75, 0.63, 0.55, 0.48, 0.41]
    recs = [
        RecordingBeats(f"r{i}", bouncer(p, phase_s=p / 4, seed=i), None, FPS, beats(p)) for i, p in enumerate(periods)
    ]
    result = beat_following(recs, draws=300)
    assert result.follows_beat
    assert not result.on_beat
    assert result.beat_align_music.p_value > 0.5  # below its chance level: anti-phase


def test_motion_of_another_tempo_does_not_follow_the_beat():
    periods = [0.75, 0.63, 0.55, 0.48, 0.41]
    result = beat_following(_set(periods, motion_periods=[0.83] * 5), draws=200)
    assert result.at_beat.value == 0.0 and not result.follows_beat
    assert result.tempo_correlation is None or result.tempo_correlation < 0.9  # the same period for every song
    assert "follows the beat: no" in result.verdicts()[0]


def test_jitter_scores_a_high_beat_align_score_but_not_above_its_chance_level():
    """Many speed minima: every music beat has one nearby, so the score is high, and it is just as
    high against beats at any phase."""
    rng = np.random.default_rng(5)
    periods = [0.75, 0.63, 0.55, 0.48, 0.41]
    recs = [
        RecordingBeats(f"r{i}", rng.normal(0, 0.005, (1200, 8, 3)), None, FPS, beats(p)) for i, p in enumerate(periods)
    ]
    result = beat_following(recs, draws=300)
    assert result.beat_align_music.value > 0.2
    assert result.beat_align_music.p_value > 0.05
    assert not result.on_beat and not result.follows_beat


def test_motion_at_two_beats_follows_the_metre_and_its_tempo():
    """Like the synthetic dancer's steps: a period of two beats, at every tempo."""
    periods = [0.75, 0.63, 0.55, 0.48, 0.41]
    result = beat_following(_set(periods, motion_periods=[2 * p for p in periods]), draws=200)
    assert result.levels == {"two beats": 5} and result.dominant_level == "two beats"
    assert result.at_beat.value == 0.0 and result.in_metre.value == 1.0 and result.follows_beat
    assert result.tempo_correlation == pytest.approx(1.0)
    assert "follows the beat: yes (at two beats: period" in result.verdicts()[0]


def test_motion_at_the_bar_follows_the_tempo_in_each_songs_metre():
    """Waltzes in 3 beside songs in 4, every motion repeating once a bar: the bar lengths rank
    otherwise than the beats (a waltz's slow beat makes a short bar), and the rank correlation
    compares the motion's period with the bar's, so it is perfect (with the beat periods it is not)."""
    from scipy.stats import spearmanr

    songs = [(0.70, 3), (0.62, 4), (0.55, 4), (0.48, 4), (0.60, 3)]  # beat period s, beats per bar
    seconds = 60.0
    recs = [
        RecordingBeats(
            f"r{i}", bouncer(beat * bar, seconds, seed=i), None, FPS, beats(beat, seconds), beats_per_bar=bar
        )
        for i, (beat, bar) in enumerate(songs)
    ]
    result = beat_following(recs, draws=100)
    assert result.levels == {"bar": 5}
    assert result.tempo_correlation == pytest.approx(1.0) and result.follows_tempo
    bars = [beat * bar for beat, bar in songs]
    assert spearmanr(bars, [beat for beat, _ in songs]).statistic < 0.5  # what the beat periods would give


def test_one_recording_uses_the_tempo_prior_for_the_period_chance():
    result = beat_following(_set([0.5]), draws=100)
    assert result.at_beat.chance == pytest.approx(_prior_match_rate(result.recordings[0].period.period_s), abs=1e-3)
    assert result.tempo_correlation is None and result.beat_align_other_songs is None


def test_no_recordings_is_an_error():
    with pytest.raises(KinectDataError):
        beat_following([])


def test_three_songs_cannot_show_tempo_following():
    """A perfect rank correlation over 3 songs happens in 1 of 6 orderings: not significant."""
    result = beat_following(_set([0.7, 0.55, 0.42]), draws=50)
    assert result.tempo_correlation == pytest.approx(1.0)
    assert result.tempo_p_value == pytest.approx(1 / 6) and not result.follows_tempo


def test_the_rhythm_of_an_orientation_target_is_measured_on_the_whole_body():
    """yalta65 positions three joints; with the dataset's rest skeleton the evaluation sees the 21
    joints its orientations reach, exactly the dancer's (against the synthesiser's own positions),
    and a masked orientation takes the joints below it out."""
    from kinectdata.evaluation.evaluate import body_positions
    from kinectdata.synth import synthesize_recording
    from kinectdata.targets.skeleton import bone_offsets
    from kinectdata.targets.specs import extract_targets, load_target_spec

    spec = load_target_spec("yalta65")
    motion = synthesize_recording(seed=4, duration_s=10.0).true_motion
    values, mask = extract_targets(motion, spec)
    config = {"skeleton": bone_offsets(motion, spec), "root_centre": False}
    positions, placed = body_positions(values, mask, spec, config)
    assert positions.shape[1] == 21 and placed.all()
    body = motion.positions[:, np.isfinite(motion.positions).all(axis=(0, 2))]  # joints compared by coordinates
    found = {tuple(np.round(p, 9)) for p in positions[0]}
    assert found <= {tuple(np.round(p, 9)) for p in body[0]}
    mask[:, spec.columns("KneeLeft", "orientation")] = False
    _, placed = body_positions(values, mask, spec, config)
    assert placed.shape[1] == 20  # AnkleLeft hangs off KneeLeft's frame: no longer placed
    only, _ = body_positions(values, mask, load_target_spec("yalta65"), {"skeleton": {}})
    assert only.shape[1] == 3  # no rest skeleton: the target's own positions
