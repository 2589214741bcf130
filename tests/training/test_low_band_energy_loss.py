"""The free-running loss's slow-motion term: the speed of the motion below about 1.5 Hz, against a
scipy smoother and a numpy divergence computed another way."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

torch = pytest.importorskip("torch")

from kinectdata.models.losses import LOW_BAND_HZ, low_passed, masked_low_band_energy_loss  # noqa: E402

FPS = 30.0


def _sway_and_shake(slow: float, fast: float, frames: int = 240) -> np.ndarray:
    """[1, T, 2] a 0.5 Hz sway of amplitude ``slow`` plus a 6 Hz shake of amplitude ``fast``."""
    t = np.arange(frames) / FPS
    one = slow * np.sin(2 * np.pi * 0.5 * t) + fast * np.sin(2 * np.pi * 6.0 * t)
    return np.stack([one, 0.5 * one], axis=1)[None]


def test_the_smoother_is_scipys_gaussian_over_the_frames_it_reaches_whole():
    x = np.random.default_rng(0).normal(size=(2, 120, 3))
    mask = np.ones(x.shape, bool)
    mask[1, 50, 2] = False
    out, valid = low_passed(torch.from_numpy(x), torch.from_numpy(mask), FPS)
    sigma = FPS / (2 * math.pi * LOW_BAND_HZ)
    reach = math.ceil(3 * sigma)
    reference = gaussian_filter1d(x, sigma, axis=1, truncate=reach / sigma, mode="constant")[:, reach:-reach]
    np.testing.assert_allclose(out.numpy()[valid.numpy()], reference[valid.numpy()], atol=1e-12)
    assert not valid[1, 50 - 2 * reach : 50 + 1, 2].any() and valid[1, :, :2].all() and valid[0].all()


def test_the_slow_part_is_what_counts():
    """A motion with the target's shake but no sway costs; one with its sway but no shake hardly."""
    real = torch.from_numpy(_sway_and_shake(0.2, 0.02))
    mask = torch.ones(real.shape, dtype=torch.bool)
    no_sway = float(masked_low_band_energy_loss(torch.from_numpy(_sway_and_shake(0.02, 0.02)), real, mask, FPS, 60))
    no_shake = float(masked_low_band_energy_loss(torch.from_numpy(_sway_and_shake(0.2, 0.0)), real, mask, FPS, 60))
    assert no_shake < 0.01 < 1.0 < no_sway


def test_the_divergence_of_the_smoothed_speeds_per_chunk():
    """Against numpy: twice the Itakura-Saito divergence of each chunk's mean squared change of the
    smoothed motions, the made one's floored at 1 % of the target's mean."""
    rng = np.random.default_rng(1)
    real, made = rng.normal(size=(1, 150, 2)), 0.5 * rng.normal(size=(1, 150, 2))
    mask = np.ones(real.shape, bool)
    loss = float(masked_low_band_energy_loss(torch.from_numpy(made), torch.from_numpy(real),
                                             torch.from_numpy(mask), FPS, 40))  # fmt: skip
    sigma = FPS / (2 * math.pi * LOW_BAND_HZ)
    reach = math.ceil(3 * sigma)

    def smooth(x):
        return gaussian_filter1d(x, sigma, axis=1, truncate=reach / sigma, mode="constant")[:, reach:-reach]

    def chunk_energy(x):
        squared = np.diff(smooth(x), axis=1) ** 2
        return np.stack([squared[:, a : a + 40].mean(axis=1) for a in range(0, squared.shape[1], 40)], axis=1)

    m, r = chunk_energy(made), chunk_energy(real)
    floor = 1e-2 * r.mean() + 1e-12
    ratio = (r + floor) / (m + floor)
    assert loss == pytest.approx(float(np.mean(2 * (ratio - np.log(ratio) - 1))), rel=1e-9)


def test_windows_shorter_than_the_smoother_cost_nothing():
    x = torch.zeros((1, 10, 2), requires_grad=True)
    loss = masked_low_band_energy_loss(x, torch.ones((1, 10, 2)), torch.ones((1, 10, 2), dtype=torch.bool), FPS)
    assert float(loss.detach()) == 0.0
    loss.backward()
