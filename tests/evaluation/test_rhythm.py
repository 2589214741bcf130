"""Rhythm evaluation on generated motion and beats with known answers, against hand counts and direct numpy."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.figures import rhythm_plot
from kinectdata.evaluation.rhythm import (
    autocorrelation_peaks,
    beat_align_score,
    beat_alignment_report,
    beat_period_s,
    motion_beat_fmeasure,
    motion_beats,
    rhythm_report,
    trajectory_autocorrelation,
)
from kinectdata.features.beats import music_beats

FPS = 30.0


def dancer(seed: int, seconds: float = 20.0, joints: int = 15) -> np.ndarray:
    """[T, J, 2] pixels: y bobs with a 0.5 s period over a slow drift; the body travels across the floor
    and back in x (plus a random walk) and a little in y; every joint has its own noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FPS)) / FPS
    travel_x = 200 * np.sin(2 * np.pi * t / 17) + 5 * t + np.cumsum(rng.normal(0, 1.5, t.size))
    drift_y = 30 * np.sin(2 * np.pi * t / 11) + 1.0 * t
    bob = 12 * np.sin(2 * np.pi * t / 0.5 + 0.3)
    pos = np.empty((t.size, joints, 2))
    for j in range(joints):
        pos[:, j, 0] = 300 + 10 * j + travel_x + rng.normal(0, 3, t.size)
        pos[:, j, 1] = 200 + 15 * j + drift_y + rng.uniform(0.6, 1.2) * bob + rng.normal(0, 3, t.size)
    return pos


def holes(shape: tuple[int, int], seed: int) -> np.ndarray:
    """[T, J] mask: 20% of the values missing at random, joint 3 lost for 2 s, joint 5 lost for 70% of the time."""
    rng = np.random.default_rng(seed)
    mask = rng.random(shape) > 0.2
    mask[100:160, 3] = False
    mask[: int(0.7 * shape[0]), 5] = False
    return mask


def pairs_corrcoef(x: np.ndarray, valid: np.ndarray, lag: int) -> float:
    """Pearson correlation of (x[t], x[t + lag]) over the pairs where both frames are valid."""
    both = [t for t in range(x.size - lag) if valid[t] and valid[t + lag]]
    return float(np.corrcoef(x[both], x[[t + lag for t in both]])[0, 1])


def moving_average_removed(x: np.ndarray, valid: np.ndarray, window: int) -> np.ndarray:
    """x minus the mean of its valid values within +-window // 2 frames, written as a loop."""
    half = window // 2
    out = np.full(x.size, np.nan)
    for t in np.flatnonzero(valid):
        lo, hi = max(0, t - half), min(x.size, t + half + 1)
        out[t] = x[t] - x[lo:hi][valid[lo:hi]].mean()
    return out


@pytest.mark.parametrize("masked", [False, True])
def test_dancer_y_peaks_at_the_beat_period_and_x_does_not(masked):
    pos = dancer(seed=1)
    mask = holes(pos.shape[:2], seed=2) if masked else None
    report = rhythm_report(pos, mask, FPS, 0.5, "ground truth")
    tolerance = max(0.05, 2 / FPS)
    assert report["tolerance_s"] == pytest.approx(tolerance)
    y, x = report["axes"]["y"], report["axes"]["x"]
    assert y["peak_at_beat"] and abs(y["nearest_peak"]["lag_s"] - 0.5) <= tolerance
    assert abs(y["nearest_peak"]["error_percent"]) == pytest.approx(100 * abs(y["nearest_peak"]["lag_s"] - 0.5) / 0.5)
    assert any(abs(p["lag_s"] - 1.0) <= tolerance for p in y["peaks"])  # the second beat
    assert not x["peak_at_beat"]
    assert not any(abs(p["lag_s"] - 0.5) <= tolerance for p in x["peaks"])
    assert y["autocorrelation_at_beat"] > 0.6 > x["autocorrelation_at_beat"]
    assert report["beat_period_source"] == "ground truth"
    assert report["joints_used"] == (14 if masked else 15)  # joint 5 is valid in only 30% of the frames
    json.dumps(report, allow_nan=False)


def test_masked_values_are_never_read():
    pos = dancer(seed=3, seconds=8.0)
    mask = holes(pos.shape[:2], seed=4)
    garbage = pos.copy()
    garbage[~mask] = 1e9
    as_nan = pos.copy()
    as_nan[~mask] = np.nan
    expected = trajectory_autocorrelation(pos, mask, 40, 61)
    np.testing.assert_array_equal(trajectory_autocorrelation(garbage, mask, 40, 61), expected)
    np.testing.assert_allclose(trajectory_autocorrelation(as_nan, None, 40, 61), expected, rtol=0, atol=1e-12)


def test_autocorrelation_equals_direct_corrcoef():
    rng = np.random.default_rng(5)
    t = np.arange(300)
    a = np.sin(2 * np.pi * t / 23) + rng.normal(0, 0.5, t.size)
    b = np.convolve(rng.normal(size=t.size + 4), np.ones(5) / 5, mode="valid")  # smooth noise
    ac = trajectory_autocorrelation(a[:, None, None], None, 40, None)
    assert ac.shape == (41, 1) and ac[0, 0] == pytest.approx(1.0)
    for lag in (1, 7, 23, 40):
        assert ac[lag, 0] == pytest.approx(np.corrcoef(a[:-lag], a[lag:])[0, 1], abs=1e-12)

    # two joints, masked frames, drift removal: the mean over joints of each joint's correlation over valid pairs
    valid = rng.random((t.size, 2)) > 0.15
    pos = np.stack([a, b], axis=1)[:, :, None] + 0.02 * t[:, None, None]  # plus a linear drift
    ac = trajectory_autocorrelation(pos, valid, 30, 25)
    residual = [moving_average_removed(pos[:, j, 0], valid[:, j], 25) for j in range(2)]
    for lag in range(31):
        expected = np.mean([pairs_corrcoef(residual[j], valid[:, j], lag) for j in range(2)])
        assert ac[lag, 0] == pytest.approx(expected, abs=1e-10)

    # a joint that never moves counts at no lag (no variance), as numpy's corrcoef has none for it
    still = np.concatenate([pos, np.full_like(pos[:, :1], 0.7)], axis=1)
    np.testing.assert_allclose(
        trajectory_autocorrelation(still, None, 30, 25), trajectory_autocorrelation(pos, None, 30, 25), atol=1e-12
    )


def test_autocorrelation_peaks():
    lags = np.arange(61)
    peaks = autocorrelation_peaks(np.cos(2 * np.pi * lags / 10.4), fps=20.0)
    assert [round(lag * 20.0 / 10.4) for lag, _ in peaks] == [1, 2, 3, 4, 5]
    for k, (lag, height) in enumerate(peaks, start=1):
        assert lag == pytest.approx(k * 10.4 / 20.0, abs=0.1 / 20.0)  # sub-frame
        assert height == pytest.approx(1.0, abs=0.01)
    ripple = np.exp(-lags / 10) + 0.02 * np.cos(2 * np.pi * lags / 7)  # bumps less prominent than 0.1
    assert autocorrelation_peaks(ripple, fps=20.0) == []
    cut = np.cos(2 * np.pi * lags / 10.0)
    cut[25:] = np.nan  # searched up to the first NaN only
    assert [round(lag * 20.0) for lag, _ in autocorrelation_peaks(cut, fps=20.0)] == [10, 20]


def test_beat_align_score_by_hand():
    music, motion = [1.0, 2.0, 3.0], [1.02, 2.1]
    by_music = (math.exp(-(0.02**2) / 0.005) + math.exp(-(0.1**2) / 0.005) + math.exp(-(0.9**2) / 0.005)) / 3
    by_motion = (math.exp(-(0.02**2) / 0.005) + math.exp(-(0.1**2) / 0.005)) / 2  # 2 sigma^2 = 0.005 s^2
    assert beat_align_score(music, motion) == pytest.approx(by_music, rel=1e-12)
    assert beat_align_score(music, motion, direction="motion_to_music") == pytest.approx(by_motion, rel=1e-12)
    assert beat_align_score(music, motion, sigma_s=0.1) == pytest.approx(
        (math.exp(-(0.02**2) / 0.02) + math.exp(-(0.1**2) / 0.02) + math.exp(-(0.9**2) / 0.02)) / 3, rel=1e-12
    )
    assert beat_align_score(music, music) == 1.0
    assert beat_align_score(music, []) == 0.0
    with pytest.raises(KinectDataError, match="motion beats, and there are none"):
        beat_align_score(music, [], direction="motion_to_music")
    with pytest.raises(KinectDataError, match="direction"):
        beat_align_score(music, motion, direction="both")


def test_fmeasure_by_hand():
    music = [1.0, 2.0, 3.0, 4.0]
    motion = [1.05, 1.08, 2.5, 3.09, 4.2]  # within 0.1 s: 1.05 -> 1 (1.08 too, but 1 matches once), 3.09 -> 3
    precision, recall = 2 / 5, 2 / 4
    expected = 2 * precision * recall / (precision + recall)
    assert motion_beat_fmeasure(music, motion, 0.1) == pytest.approx(expected)
    assert motion_beat_fmeasure(music, music, 0.1) == 1.0
    assert motion_beat_fmeasure(music, [], 0.1) == 0.0
    report = beat_alignment_report(music, motion, fps=20.0, window_s=0.1)  # 2 frames at 20 fps
    assert report["f_measure"] == pytest.approx(expected)
    assert (report["precision"], report["recall"]) == pytest.approx((precision, recall))
    assert report["window_s"] == pytest.approx(0.1) and report["window_frames"] == 2
    assert report["direction"] == "music_to_motion" and report["sigma_s"] == 0.05 and report["sigma_frames"] == 1.0
    at_60 = beat_alignment_report(music, motion, fps=60.0)
    assert at_60["sigma_frames"] == pytest.approx(3.0)
    assert at_60["window_s"] == pytest.approx(0.1) and at_60["f_measure"] == pytest.approx(expected)  # not per frame
    with pytest.raises(KinectDataError, match="beat 2 at 1.0 s comes after 2.0 s"):
        motion_beat_fmeasure([1.0, 2.0, 1.0], motion, 0.1)


@pytest.mark.parametrize("fps", [30.0, 60.0])
def test_motion_beats_are_the_speed_minima(fps):
    t = np.arange(int(6 * fps)) / fps
    pos = np.zeros((t.size, 3, 2))
    pos[:, 0, 0] = 40 * np.sin(2 * np.pi * t)  # speed |cos|: minima at 0.25 + 0.5 k s
    pos[:, 1, 1] = 25 * np.sin(2 * np.pi * t)
    pos[:, 2] = 100.0  # still
    expected = 0.25 + 0.5 * np.arange(12)
    mask = np.ones(pos.shape[:2], bool)
    mask[40:44, 1] = False
    for m in (None, mask):
        beats = motion_beats(pos, m, fps)
        assert beats.shape == expected.shape
        assert np.max(np.abs(beats - expected)) <= 1 / fps


@pytest.mark.parametrize("bpm", [120.0, 100.0])  # 100: not librosa's starting guess of 120
def test_music_beats_of_a_click_track(bpm):
    pytest.importorskip("librosa", reason="librosa (the 'music' extra) is not installed")
    rate, seconds, period = 16000, 20.0, 60.0 / bpm
    samples = np.zeros(int(rate * seconds), np.float32)
    click = (np.sin(2 * np.pi * 1000 * np.arange(160) / rate) * np.exp(-np.arange(160) / 48)).astype(np.float32)
    clicks = np.arange(0.23, seconds - 0.05, period)
    for start in clicks:
        samples[int(start * rate) : int(start * rate) + click.size] += click
    beats, tempo = music_beats(samples, rate)
    assert beat_period_s(beats) == pytest.approx(period, rel=0.02)
    assert tempo == pytest.approx(bpm, rel=0.02)
    inner = beats[1:-1]  # the tracker may place the first and last beats off the clicks
    assert np.max(np.min(np.abs(inner[:, None] - clicks[None, :]), axis=1)) < 0.03


def test_music_beats_without_librosa(monkeypatch):
    monkeypatch.setitem(sys.modules, "librosa", None)  # import librosa raises ImportError
    with pytest.raises(KinectDataError, match=r"pip install 'kinectdata\[music\]'"):
        music_beats(np.zeros(16000, np.float32), 16000)


def test_bad_input_is_reported():
    assert beat_period_s([0.1, 0.6, 1.2, 1.6]) == pytest.approx(0.5)  # median of 0.5, 0.6, 0.4
    with pytest.raises(KinectDataError, match="at least 2 beats, got 1"):
        beat_period_s([1.0])
    with pytest.raises(KinectDataError, match=r"\[T, J, C\]"):
        trajectory_autocorrelation(np.zeros((10, 3)), None, 2, None)
    with pytest.raises(KinectDataError, match="mask shape"):
        rhythm_report(np.zeros((100, 2, 2)), np.ones((100, 3), bool), FPS, 0.5, "ground truth")
    with pytest.raises(KinectDataError, match="cannot show a beat period"):
        rhythm_report(dancer(seed=0, seconds=1.0), None, FPS, 0.5, "ground truth")


def test_rhythm_plot_writes_a_png(tmp_path):
    report = json.loads(json.dumps(rhythm_report(dancer(seed=6, seconds=8.0), None, FPS, 0.5, "beat tracker")))
    path = rhythm_plot(report, tmp_path / "plots" / "rhythm.png", title="synthetic dancer")
    assert path == tmp_path / "plots" / "rhythm.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in path.parent.iterdir()] == ["rhythm.png"]  # no temporary file left
