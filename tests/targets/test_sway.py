"""The network's sway along the floor brought to the dancers' (:mod:`kinectdata.targets.sway`): the
band's speed against Welch's periodogram, the fitted gain, the root's x and z scaled and nothing else."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import welch

from kinectdata.core.errors import ConfigError
from kinectdata.targets.specs import load_target_spec
from kinectdata.targets.sway import BAND_HZ, SwayGain, band_speed, calm_sway, fit_sway
from kinectdata.targets.travel import floor_columns

FPS = 30.0


def _track(seconds: float, parts: list[tuple[float, float]], seed: int = 0) -> np.ndarray:
    """[T, 2] x and z: a sine of (frequency Hz, amplitude m) per part on each axis, random phases."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FPS)) / FPS
    return np.stack(
        [sum(a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) for f, a in parts) for _ in range(2)], axis=1
    )


def _welch_band_speed(track: np.ndarray, band: tuple[float, float]) -> float:
    """The same figure by another road: the velocity's power spectral density summed over the band."""
    f, power = welch(np.gradient(track, axis=0) * FPS, fs=FPS, axis=0, nperseg=512)
    inside = (f >= band[0]) & (f <= band[1])
    return float(np.sqrt(power[inside].sum() * (f[1] - f[0])))


def test_the_beats_band_holds_a_sway_at_the_beat_and_not_the_travel_or_the_shake():
    sway = _track(120, [(2.0, 0.03)])  # a sway at the beat: 2 pi 2 Hz 3 cm = 0.377 m/s peak per axis
    speed, frames = band_speed([sway], FPS)
    assert frames == len(sway)
    step = 2 * np.pi * 2.0 / FPS  # a central difference's gain on a sine: sin(step) / step
    assert speed == pytest.approx(2 * np.pi * 2.0 * 0.03 * np.sin(step) / step, rel=0.01)  # two axes of peak / sqrt 2
    assert speed == pytest.approx(_welch_band_speed(sway, BAND_HZ), rel=0.05)
    travel_and_shake = _track(120, [(0.1, 2.0), (9.0, 0.002)], seed=1)  # 1.3 m/s of travel; 0.11 m/s of shake
    alone, _ = band_speed([travel_and_shake], FPS)
    assert alone < 0.1 * speed
    both, _ = band_speed([sway + travel_and_shake], FPS)
    assert both == pytest.approx(speed, rel=0.05)


def test_unknown_frames_split_a_track_and_short_stretches_are_left_out():
    sway = _track(60, [(1.5, 0.05)])
    holed = sway.copy()
    holed[900:910] = np.nan  # a gap
    holed[1790:] = np.nan  # and a stretch too short after it is cut
    holed[1770:1790] = sway[1770:1790]
    holed[1760:1770] = np.nan
    speed, frames = band_speed([holed], FPS)
    assert frames == 900 + (1760 - 910)
    assert speed == pytest.approx(band_speed([sway], FPS)[0], rel=0.05)
    assert band_speed([np.full((100, 2), np.nan)], FPS) == (pytest.approx(np.nan, nan_ok=True), 0)


def test_the_gain_is_the_dancers_speed_over_the_networks_and_never_above_one():
    dancers = [_track(60, [(2.0, 0.02)], seed=s) for s in range(3)]
    network = [_track(60, [(2.0, 0.05)], seed=10 + s) for s in range(3)]
    fitted = fit_sway(network, dancers, FPS)
    assert fitted.gain == pytest.approx(0.4, rel=0.02)
    assert fitted.network_speed == pytest.approx(band_speed(network, FPS)[0])
    assert fitted.dancers_speed == pytest.approx(band_speed(dancers, FPS)[0])
    assert fitted.songs == 3
    assert fit_sway(dancers, network, FPS).gain == 1.0  # a network that sways less is left as it is
    assert SwayGain.from_dict(fitted.to_dict()) == fitted
    assert "scaled by 0.40" in fitted.describe()
    with pytest.raises(ConfigError, match="no stretch"):
        fit_sway([np.zeros((10, 2))], dancers, FPS)


def test_only_the_roots_x_and_z_are_scaled():
    spec = load_target_spec("kinect_v2_positions")
    values = np.random.default_rng(3).standard_normal((40, spec.dim))
    calmed = calm_sway(values, spec, SwayGain(0.25, 0.2, 0.05, 4))
    columns = floor_columns(spec)
    root = spec.columns(spec.root, "position").start
    assert columns == [root, root + 2]
    np.testing.assert_allclose(calmed[:, columns], 0.25 * values[:, columns])
    others = np.setdiff1d(np.arange(spec.dim), columns)
    np.testing.assert_array_equal(calmed[:, others], values[:, others])
    np.testing.assert_allclose(calm_sway(values[5:6], spec, SwayGain(0.25, 0.2, 0.05, 4)), calmed[5:6])  # a frame


def test_bad_records_and_targets_that_do_not_travel_are_config_errors():
    with pytest.raises(ConfigError, match=r"\(0, 1\]"):
        SwayGain(1.5, 0.1, 0.15, 2)
    with pytest.raises(ConfigError, match="not a sway record"):
        SwayGain.from_dict({"gain": 0.5})
    with pytest.raises(ConfigError, match="half the frame rate"):
        band_speed([np.zeros((100, 2))], 6.0)
    flat = load_target_spec("listen_to_dance")
    with pytest.raises(ConfigError, match="sway: .*3-D joint positions"):
        calm_sway(np.zeros((2, flat.dim)), flat, SwayGain(0.5, 0.2, 0.1, 1))
