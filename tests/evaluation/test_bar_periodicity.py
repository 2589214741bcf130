"""Bar periodicity: how much a motion repeats after one and two bars of its song, against every
pairing of the motions with the songs (an exact permutation test computed here independently), and
the metre carried by each recording."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from kinectdata.evaluation.beat_following import (
    BAR_TOLERANCE,
    RecordingBeats,
    bar_lags_s,
    bar_periodicity,
    beat_following,
    metrical_level,
    vertical_autocorrelation,
)

FPS = 30.0
SECONDS = 40.0
# (beat period s, beats per bar): distinct tempi (103-150 BPM), waltzes and songs in 4, whose
# two-bar periods (2.4, 3.44, 2.76, 4.0, 4.64 s) are far enough apart that each motion repeats
# best after its own song's bars
SONGS = ((0.40, 3), (0.43, 4), (0.46, 3), (0.50, 4), (0.58, 4))


def swinger(period_s: float, seed: int, seconds: float = SECONDS, joints: int = 6) -> np.ndarray:
    """[T, J, 3]: every joint rises and falls once per ``period_s`` (a sinusoid of 4-6 cm), with 2 mm noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FPS)) / FPS
    pos = rng.normal(0, 0.002, (t.size, joints, 3))
    pos[:, :, 0] += 0.1 * np.arange(joints)
    pos[:, :, 1] += (
        0.2 * np.arange(joints) + rng.uniform(0.04, 0.06, joints) * np.sin(2 * np.pi * t / period_s)[:, None]
    )
    pos[:, :, 2] += 2.5
    return pos


def recordings(pairing: list[int]) -> list[RecordingBeats]:
    """Motion i, which repeats every two bars of song i, with the beats of song ``pairing[i]``."""
    out = []
    for i, j in enumerate(pairing):
        beat, bar = SONGS[j]
        motion = swinger(2 * SONGS[i][1] * SONGS[i][0], seed=i)
        out.append(RecordingBeats(f"m{i}", motion, None, FPS, np.arange(0.1, SECONDS, beat), beats_per_bar=bar))
    return out


def reference_window_max(curve: np.ndarray, fps: float, lags_s, tolerance: float) -> float:
    """The highest value of ``curve`` (lags 0..L frames) over the frames less than one frame outside
    [lag (1 - tolerance), lag (1 + tolerance)] for any of the lags (on a frame grid the window's edges
    fall between frames: the frames bracketing them count), leaving out lag 0; NaN when none is on the curve."""
    frames = np.arange(len(curve))
    best = []
    for lag in lags_s:
        inside = (frames > lag * (1 - tolerance) * fps - 1) & (frames < lag * (1 + tolerance) * fps + 1) & (frames > 0)
        if inside.any():
            best.append(curve[inside].max())
    return max(best) if best else float("nan")


def reference_scores(recs: list[RecordingBeats], songs: list[tuple[float, int]]) -> np.ndarray:
    """[motion, song]: each motion's vertical autocorrelation up to the longest two bars (and
    tolerance), its highest value near one or two bars of each song (from the songs' known tempo and
    metre); 0 where none of those lags is on the curve."""
    n = len(recs)
    lags = [(bar * beat, 2 * bar * beat) for beat, bar in songs]
    longest = max(two for _, two in lags) * (1 + BAR_TOLERANCE)
    scores = np.zeros((n, n))
    for i, rec in enumerate(recs):
        curve = vertical_autocorrelation(rec.positions, None, FPS, longest)
        for j in range(n):
            value = reference_window_max(curve, FPS, lags[j], BAR_TOLERANCE)
            scores[i, j] = 0.0 if np.isnan(value) else value
    return scores


def reference_test(recs: list[RecordingBeats], songs: list[tuple[float, int]]):
    """(observed mean, chance, chance spread, exact one-sided p, mean against the other songs, the
    score matrix): every permutation of the songs scored with itertools."""
    scores = reference_scores(recs, songs)
    n = len(recs)
    observed = float(np.mean([scores[i, i] for i in range(n)]))
    means = np.array([np.mean([scores[i, p[i]] for i in range(n)]) for p in itertools.permutations(range(n))])
    p = sum(m >= observed - 1e-12 for m in means) / len(means)
    others = float(np.mean([scores[i, j] for i in range(n) for j in range(n) if i != j]))
    return observed, means.mean(), means.std(), p, others, scores


def test_bar_periodicity_is_the_highest_value_near_the_lags():
    curve = np.zeros(31)  # lags 0..30 frames at 10 fps: up to 3 s
    curve[0] = 1.0
    curve[19], curve[21], curve[22] = 0.3, 0.5, 0.9  # 1.9, 2.1 and 2.2 s
    assert bar_periodicity(curve, 10.0, [2.0], 0.05) == pytest.approx(0.5)  # 1.9..2.1 s: 2.2 s is outside
    assert bar_periodicity(curve, 10.0, [2.0], 0.1) == pytest.approx(0.9)  # 1.8..2.2 s
    assert bar_periodicity(curve, 10.0, [1.0, 2.0], 0.05) == pytest.approx(0.5)  # 1 s holds only zeros
    assert bar_periodicity(curve, 10.0, [2.0, 4.0], 0.05) == pytest.approx(0.5)  # 4 s is beyond the curve
    assert bar_periodicity(curve, 10.0, [0.02], 0.05) == pytest.approx(0.0)  # lag 0 itself never counts
    assert np.isnan(bar_periodicity(curve, 10.0, [3.5, 7.0], 0.05))
    curve[20] = np.nan
    assert bar_periodicity(curve, 10.0, [2.0], 0.05) == pytest.approx(0.5)  # NaN lags are skipped
    rng = np.random.default_rng(0)
    for _ in range(20):  # against the reference window on random curves and lags
        curve = rng.uniform(-1, 1, 200)
        lags = rng.uniform(0.2, 6.0, 2)
        assert bar_periodicity(curve, 30.0, lags, 0.05) == reference_window_max(curve, 30.0, lags, 0.05)


def test_bar_lags_are_one_and_two_bars_of_the_songs_metre():
    for beat, bar in SONGS:
        rec = RecordingBeats("r", np.zeros((300, 2, 3)), None, FPS, np.arange(0.0, 10.0, beat), beats_per_bar=bar)
        assert bar_lags_s(rec) == pytest.approx((bar * beat, 2 * bar * beat))


def test_motions_that_repeat_with_their_own_songs_bars_are_above_chance_with_the_exact_p_value():
    recs = recordings([0, 1, 2, 3, 4])
    result = beat_following(recs, draws=30)
    observed, chance, spread, p, others, scores = reference_test(recs, list(SONGS))
    # the data are what they are meant to be: each motion repeats after its own song's bars at least as
    # well as after any other's (motion 0, every 2.4 s, also after 2.32 s, within 5 % of song 4's bar)
    assert np.all(np.diag(scores) > 0.85)  # below 1: sensor noise, the drift removal's edges
    assert all(scores[i, i] >= np.delete(scores[i], i).max() - 1e-12 for i in range(len(SONGS)))
    figure = result.bar_periodicity
    assert figure.value == pytest.approx(observed, abs=1e-9)
    assert figure.chance == pytest.approx(chance, abs=1e-9)
    assert figure.chance == pytest.approx(scores.mean(), abs=1e-9)  # every pairing: each cell (n-1)! times
    assert figure.chance_spread == pytest.approx(spread, abs=1e-9)
    assert figure.p_value == pytest.approx(p) and p == pytest.approx(1 / 120)  # only the true pairing
    assert figure.chance_from == "every pairing of the motions with the songs"
    assert result.bar_periodicity_other_songs == pytest.approx(others, abs=1e-9)
    assert result.follows_bars
    assert [r.beats_per_bar for r in result.recordings] == [bar for _, bar in SONGS]
    (line,) = [v for v in result.verdicts("real motion") if "repeats with" in v]
    assert line.startswith("real motion repeats with its song's bars: yes (autocorrelation after one or two bars ")
    assert "p = 0.0083)" in line
    record = result.to_dict()
    assert record["follows_bars"] is True and record["bar_periodicity"]["above_chance"] is True
    assert record["bar_periodicity"]["p_value"] == pytest.approx(1 / 120)
    assert record["bar_periodicity_other_songs"] == pytest.approx(others, abs=1e-9)
    assert {name: r["beats_per_bar"] for name, r in record["recordings"].items()} == {
        f"m{i}": bar for i, (_, bar) in enumerate(SONGS)
    }


@pytest.mark.parametrize("pairing", [[1, 2, 3, 4, 0], [3, 4, 0, 1, 2], [4, 3, 1, 0, 2]])
def test_motions_paired_with_the_wrong_songs_do_not_repeat_with_their_bars(pairing):
    recs = recordings(pairing)
    songs = [SONGS[j] for j in pairing]
    result = beat_following(recs, draws=30)
    observed, chance, _, p, others, _ = reference_test(recs, songs)
    assert result.bar_periodicity.value == pytest.approx(observed, abs=1e-9)
    assert result.bar_periodicity.chance == pytest.approx(chance, abs=1e-9)
    assert result.bar_periodicity.p_value == pytest.approx(p)
    assert result.bar_periodicity_other_songs == pytest.approx(others, abs=1e-9)
    assert p > 0.05 and not result.follows_bars
    assert any(v.startswith("motion repeats with its song's bars: no (") for v in result.verdicts())


def test_one_recording_has_no_bar_periodicity_figure():
    result = beat_following(recordings([0])[:1], draws=20)
    assert result.bar_periodicity is None and result.bar_periodicity_other_songs is None
    assert not result.follows_bars
    assert not any("repeats with" in v for v in result.verdicts())
    record = result.to_dict()
    assert record["bar_periodicity"] is None and record["follows_bars"] is False


def test_a_motion_too_short_for_the_longest_bars_scores_zero_there():
    """A motion of 5 s (lags up to 2.5 s) paired with songs whose bars it cannot reach: those cells
    count as 0 (no evidence of repeating), not as missing."""
    beats = np.arange(0.1, 5.0, 0.5)
    short = RecordingBeats("short", swinger(4.0, 0, seconds=5.0), None, FPS, beats, beats_per_bar=4)  # bars 2, 4 s
    long = RecordingBeats("long", swinger(3.0, 1), None, FPS, np.arange(0.1, SECONDS, 0.5), beats_per_bar=3)
    result = beat_following([short, long], draws=10)
    curve_short = vertical_autocorrelation(short.positions, None, FPS, 4.0 * 1.05)  # cut to 2.5 s
    curve_long = vertical_autocorrelation(long.positions, None, FPS, 4.0 * 1.05)
    scores = np.array(
        [
            [reference_window_max(c, FPS, lags, BAR_TOLERANCE) for lags in ((2.0, 4.0), (1.5, 3.0))]
            for c in (curve_short, curve_long)
        ]
    )
    assert np.isfinite(scores).all()  # every motion reaches one bar of each song
    assert result.bar_periodicity.value == pytest.approx(np.mean(np.diag(scores)), abs=1e-9)
    assert result.bar_periodicity.chance == pytest.approx(scores.mean(), abs=1e-9)


def test_a_waltz_that_repeats_every_six_beats_is_at_two_bars_only_in_three():
    beat = 0.5
    rec3 = RecordingBeats("w", swinger(6 * beat, 0), None, FPS, np.arange(0.1, SECONDS, beat), beats_per_bar=3)
    rec4 = RecordingBeats("w", rec3.positions, None, FPS, rec3.beats_s)  # the default metre: 4
    in3, in4 = beat_following([rec3], draws=20).recordings[0], beat_following([rec4], draws=20).recordings[0]
    assert in3.period.period_s == pytest.approx(3.0, rel=0.03) and in4.period.period_s == pytest.approx(3.0, rel=0.03)
    assert in3.level == "two bars" and in3.in_metre and in3.beats_per_bar == 3
    assert in4.level is None and not in4.in_metre and in4.beats_per_bar == 4
    assert metrical_level(3.0, beat, 3) == "two bars" and metrical_level(3.0, beat) is None


def test_with_more_songs_than_are_paired_exhaustively_the_p_value_counts_the_observed_pairing():
    """Nine songs (9! pairings): random pairings are drawn, and the p-value is at least one over the
    draws plus one, never 0 (the observed pairing is one of the possible ones)."""
    songs = list(zip(np.linspace(0.38, 0.62, 9), (3, 4, 3, 4, 3, 4, 3, 4, 3)))
    recs = [
        RecordingBeats(f"m{i}", swinger(2 * bar * beat, i), None, FPS, np.arange(0.1, SECONDS, beat), beats_per_bar=bar)
        for i, (beat, bar) in enumerate(songs)
    ]
    result = beat_following(recs, draws=200)
    figure = result.bar_periodicity
    assert figure.chance_from == "200 random pairings"
    scores = reference_scores(recs, songs)
    assert figure.value == pytest.approx(np.mean(np.diag(scores)), abs=1e-9)
    # the exact chance level (every pairing: each cell (n-1)! times) is the matrix's mean; 200 pairings near it
    assert figure.chance == pytest.approx(scores.mean(), abs=4 * scores.std() / np.sqrt(200 * 9))
    assert 1 / 201 <= figure.p_value < 0.05 and result.follows_bars
