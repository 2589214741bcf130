"""The short-time Wiener smoother (kinectdata.cleaning.wiener): it reads the tracker's noise from the
band above the dance, keeps a clean swing whole and in time, and on a dance whose pace changes beats
every fixed Butterworth cutoff (scipy's own filter, the reference)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from kinectdata.cleaning.jitter import zero_phase
from kinectdata.cleaning.wiener import band_filter, noise_sigma
from kinectdata.core.errors import ConfigError

FPS = 30.0


def _pace_changing(seconds: float = 40.0) -> np.ndarray:
    """[T] metres: 10 s of a slow sway (0.3 Hz, 5 cm), then 10 s of a fast swing (3.5 Hz, 5 cm), twice."""
    t = np.arange(int(seconds * FPS)) / FPS
    fast = (t % 20.0) >= 10.0
    return np.where(fast, 0.05 * np.sin(2 * np.pi * 3.5 * t), 0.05 * np.sin(2 * np.pi * 0.3 * t))


def test_the_noise_level_is_read_from_the_band_above_the_dance():
    # the estimate's own spread over 2 minutes of white noise: 2.8 % (200 draws)
    rng = np.random.default_rng(0)
    truth = _pace_changing(120.0)
    sos = band_filter(FPS)
    for sigma in (0.001, 0.003, 0.01):
        noisy = truth[:, None] + rng.normal(0.0, sigma, (truth.size, 3))
        residual = noisy - signal.sosfiltfilt(sos, noisy, axis=0)
        np.testing.assert_allclose(noise_sigma(residual, sos, FPS), sigma, rtol=0.1)
    gapped = residual.copy()
    gapped[100:1000, 1] = np.nan
    gapped[:, 2] = np.nan
    found = noise_sigma(gapped, sos, FPS)
    assert found[1] == pytest.approx(0.01, rel=0.1) and found[2] == 0.0


def test_a_dance_whose_pace_changes_is_followed_better_than_by_any_fixed_cutoff():
    rng = np.random.default_rng(1)
    truth = _pace_changing()
    p = np.zeros((truth.size, 1, 3))
    p[:, 0, 1] = truth + rng.normal(0.0, 0.003, truth.size)
    inner = slice(30, -30)

    def error(out):
        return float(np.sqrt(np.mean((out[inner] - truth[inner]) ** 2)))

    wiener = error(zero_phase(p, FPS, method="wiener")[:, 0, 1])
    fixed = {
        cutoff: error(signal.sosfiltfilt(signal.butter(2, cutoff, fs=FPS, output="sos"), p[:, 0, 1]))
        for cutoff in (2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
    }
    assert wiener < 0.85 * min(fixed.values()), (wiener, fixed)
    assert wiener < 0.5 * 0.003


def test_a_swing_well_above_the_noise_passes_whole_and_in_time():
    rng = np.random.default_rng(2)
    t = np.arange(600) / FPS
    swing = 0.1 * np.sin(2 * np.pi * 2.0 * t)
    p = np.zeros((600, 1, 3))
    p[:, 0, 0] = swing + rng.normal(0.0, 0.0002, 600)
    out = zero_phase(p, FPS, method="wiener", times=t)[:, 0, 0]
    inner = slice(30, -30)
    assert np.abs(out - swing)[inner].max() < 0.002  # 2 % of the swing
    lag = np.argmax(np.correlate(out[inner], swing[inner], "full")) - (len(swing[inner]) - 1)
    assert lag == 0


def test_a_long_gap_stays_masked_and_spoils_nothing_around_it():
    rng = np.random.default_rng(3)
    truth = _pace_changing(20.0)
    p = np.zeros((truth.size, 2, 3))
    p[:, :, 2] = truth[:, None] + rng.normal(0.0, 0.003, (truth.size, 2))
    mask = np.ones(p.shape[:2], bool)
    mask[200:260, 0] = False
    out = zero_phase(p, FPS, mask, method="wiener", times=np.arange(truth.size) / FPS)
    assert np.isnan(out[200:260, 0]).all() and np.isfinite(out[~(~mask)]).all()
    ok = mask[:, 0]
    ok[:30] = ok[-30:] = False
    assert np.sqrt(np.mean((out[ok, 0, 2] - truth[ok]) ** 2)) < 0.6 * 0.003


def test_a_wiener_window_too_short_is_one_line():
    with pytest.raises(ConfigError, match="at least 4 frames"):
        zero_phase(np.zeros((100, 1, 3)), FPS, method="wiener", wiener_window_s=0.05)
