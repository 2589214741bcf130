"""The baselines a model must beat: the mean pose with smooth noise at the real speed, the retrieved
training dance, and the comparison of their FIDs with the model's."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import welch

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.baselines import (
    NOISE_CUTOFF_HZ,
    TrainingSong,
    baseline_comparison,
    mean_pose_noise,
    mean_square_steps,
    music_descriptor,
    retrieval,
)

FPS = 30.0


def real_motion(T: int = 900, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """([T, 4] values, [T, 4] mask): components moving at different speeds (a slow and a fast sway,
    a random walk, a still one), a tenth of the frames of component 2 masked (NaN there)."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) / FPS
    values = np.stack(
        [
            0.3 * np.sin(2 * np.pi * 0.5 * t),
            1.0 + 0.05 * np.sin(2 * np.pi * 2.0 * t),
            np.cumsum(rng.normal(0, 0.01, T)),
            np.full(T, 2.0),
        ],
        axis=1,
    )
    mask = np.ones_like(values, bool)
    mask[rng.random(T) < 0.1, 2] = False
    values[~mask] = np.nan
    return values, mask


def reference_mean_square_step(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per component, the mean of (x[t+1] - x[t])^2 over the t where both frames are valid, by loops."""
    T, D = values.shape
    out = []
    for d in range(D):
        steps = [(values[t + 1, d] - values[t, d]) ** 2 for t in range(T - 1) if mask[t, d] and mask[t + 1, d]]
        out.append(sum(steps) / len(steps))
    return np.array(out)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mean_pose_noise_moves_at_the_real_speed_around_the_mean_pose(seed):
    values, mask = real_motion(seed=seed)
    mean_pose = np.array([0.1, -0.2, 0.3, 5.0])
    real = reference_mean_square_step(values, mask)
    np.testing.assert_allclose(mean_square_steps([(values, mask)]), real, rtol=1e-12)
    out = mean_pose_noise(mean_pose, real, len(values), FPS, np.random.default_rng(seed))
    assert out.shape == (len(values) - 1, 4) and np.isfinite(out).all()
    np.testing.assert_allclose(np.mean(np.diff(out, axis=0) ** 2, axis=0)[:3], real[:3], rtol=1e-9)
    np.testing.assert_array_equal(out[:, 3], 5.0)  # a still component: no noise at all
    spread = out[:, :3].std(axis=0)
    assert (spread > 0).all()
    # around the mean pose: 3 Hz noise over 30 s has ~180 independent values, a standard error of ~spread / 13
    assert np.all(np.abs(out[:, :3].mean(axis=0) - mean_pose[:3]) < 0.4 * spread)


def test_mean_pose_noise_has_no_power_above_its_cutoff():
    values, mask = real_motion(T=1800)
    speed = mean_square_steps([(values, mask)])
    out = mean_pose_noise(np.zeros(4), speed, len(values), FPS, np.random.default_rng(7))
    f, power = welch(out[:, :3], fs=FPS, nperseg=256, axis=0)  # [F, 3], Hann windows: little leakage
    passband = power[f < 0.7 * NOISE_CUTOFF_HZ].mean(axis=0)
    # a 4th-order Butterworth run forwards and backwards: |H|^2 = 1 / (1 + (f / fc)^8)^2, 1.5e-5 at 2 fc
    assert np.all(power[f >= 2 * NOISE_CUTOFF_HZ].max(axis=0) < 1e-3 * passband)
    assert np.all(power[(f > NOISE_CUTOFF_HZ * 1.3) & (f < 2 * NOISE_CUTOFF_HZ)].max(axis=0) < 0.2 * passband)
    # the same check on white noise of the same speed fails: it can tell
    white = np.random.default_rng(7).normal(size=out.shape)
    f, wpower = welch(white[:, :3], fs=FPS, nperseg=256, axis=0)
    assert not np.all(wpower[f >= 2 * NOISE_CUTOFF_HZ].max(axis=0) < 1e-3 * wpower[f < 2.1].mean(axis=0))
    # a lower cutoff moves the edge
    low = mean_pose_noise(np.zeros(4), speed, len(values), FPS, np.random.default_rng(7), cutoff_hz=1.0)
    f, lpower = welch(low[:, :3], fs=FPS, nperseg=256, axis=0)
    assert np.all(lpower[f >= 2.0].max(axis=0) < 1e-3 * lpower[f < 0.7].mean(axis=0))


def test_mean_square_steps_pool_the_motions_and_skip_what_is_not_valid():
    values, _ = real_motion(T=300)
    values = values[:, [0, 1, 3]]
    other = np.random.default_rng(3).normal(size=(50, 3))
    full, full_other = np.ones_like(values, bool), np.ones_like(other, bool)
    pooled = mean_square_steps([(values, None), (other, full_other)])
    by_hand = (reference_mean_square_step(values, full) * 299 + reference_mean_square_step(other, full_other) * 49) / (
        299 + 49
    )  # pairs pooled, not the songs' means averaged
    np.testing.assert_allclose(pooled, by_hand, rtol=1e-12)
    never = np.zeros_like(values, bool)
    never[:, 0] = True
    np.testing.assert_array_equal(mean_square_steps([(values, never)])[1:], 0.0)  # never valid: no speed
    still = mean_pose_noise(np.array([1.0, 2.0, 3.0]), np.array([0.01, 0.0, 0.0]), 300, FPS, np.random.default_rng(0))
    np.testing.assert_array_equal(still[:, 1:], np.broadcast_to([2.0, 3.0], (299, 2)))
    with pytest.raises(KinectDataError, match="at least 3 frames, got 2"):
        mean_pose_noise(np.zeros(3), np.ones(3), 2, FPS, np.random.default_rng(0))
    with pytest.raises(KinectDataError, match="no motion"):
        mean_square_steps([])


def test_music_descriptor_by_hand():
    features = np.array([[1.0, 3.0], [3.0, 5.0]])  # mean (2, 4), standard deviation (1, 1)
    np.testing.assert_allclose(music_descriptor(features), np.array([2.0, 4.0, 1.0, 1.0]) / np.sqrt(22.0))
    stft_like = np.stack([np.full((1, 2, 2), v) for v in (0.0, 2.0, 4.0)])  # [3, 1, 2, 2]: mean 2, std sqrt(8/3)
    expected = np.array([2.0] * 4 + [np.sqrt(8 / 3)] * 4)
    np.testing.assert_allclose(music_descriptor(stft_like), expected / np.linalg.norm(expected))
    with pytest.raises(KinectDataError, match="at least 2 frames, got 1"):
        music_descriptor(features[:1])


def training_songs() -> list[TrainingSong]:
    far_but_alike = TrainingSong("alike", np.array([10.0, 1.0]), np.arange(5 * 2, dtype=float).reshape(5, 2))
    near = TrainingSong("near", np.array([0.5, 0.6]), 100 + np.arange(5 * 2, dtype=float).reshape(5, 2))
    return [far_but_alike, near]


def test_retrieval_takes_the_nearest_song_by_euclidean_distance_and_tiles_its_motion():
    # (1, 0) is 9.06 from "alike" (cosine 0.995) and 0.78 from "near" (cosine 0.64): Euclidean picks "near"
    motion, name = retrieval(np.array([1.0, 0.0]), 12, training_songs())
    assert name == "near"
    rows = 100 + np.arange(10.0).reshape(5, 2)
    expected = np.concatenate([rows[1:], rows[1:], rows[1:4]])  # frames 1..4, 1..4, 1..3: 11 rows
    np.testing.assert_array_equal(motion, expected)
    motion, name = retrieval(np.array([9.0, 1.0]), 3, training_songs())
    assert name == "alike"
    np.testing.assert_array_equal(motion, np.arange(10.0).reshape(5, 2)[1:3])  # longer than needed: cut
    motion, _ = retrieval(np.array([9.0, 1.0]), 5, training_songs())
    np.testing.assert_array_equal(motion, np.arange(10.0).reshape(5, 2)[1:])  # exactly as long


def test_retrieval_needs_training_motion():
    with pytest.raises(KinectDataError, match="at least one training song"):
        retrieval(np.zeros(2), 10, [])
    with pytest.raises(KinectDataError, match="training song one has no motion after its first frame"):
        retrieval(np.zeros(2), 10, [TrainingSong("one", np.zeros(2), np.zeros((1, 3)))])


def scored(fid_k, fid_g):
    values = {"FID_k": fid_k, "FID_g": fid_g}
    return SimpleNamespace(metric=lambda name: SimpleNamespace(generated=values[name]))


def test_the_model_beats_a_baseline_only_when_lower_on_both_fids():
    comparison = baseline_comparison(
        {
            "generated": scored(10.0, 20.0),
            "mean_pose_noise": scored(30.0, 40.0),
            "retrieval": scored(5.0, 50.0),
            "tie": scored(10.0, 25.0),
            "unknown": scored(None, 30.0),
        }
    )
    assert set(comparison) == {"mean_pose_noise", "retrieval", "tie", "unknown"}
    assert comparison["mean_pose_noise"] == {
        "FID_k": 10.0,
        "FID_k_baseline": 30.0,
        "FID_g": 20.0,
        "FID_g_baseline": 40.0,
        "beats": True,
    }
    assert comparison["retrieval"]["beats"] is False and comparison["retrieval"]["FID_k_baseline"] == 5.0
    assert comparison["tie"]["beats"] is False  # equal is not better
    assert comparison["unknown"]["beats"] is False and comparison["unknown"]["FID_k_baseline"] is None
    no_model = baseline_comparison({"generated": scored(None, None), "retrieval": scored(5.0, 5.0)})
    assert no_model["retrieval"]["beats"] is False


@pytest.mark.parametrize("T", [3, 4, 6, 8, 30])
def test_mean_pose_noise_for_short_motions(T):
    """However short the real motion, the noise has its rows and its speed (the filter needs room
    to pad: the noise runs on beyond both ends and is cut)."""
    values = np.random.default_rng(T).normal(size=(T, 3))
    full = np.ones_like(values, bool)
    out = mean_pose_noise(np.zeros(3), reference_mean_square_step(values, full), T, FPS, np.random.default_rng(0))
    assert out.shape == (T - 1, 3)
    np.testing.assert_allclose(
        np.mean(np.diff(out, axis=0) ** 2, axis=0), reference_mean_square_step(values, full), rtol=1e-9
    )
