"""The short-time Wiener smoother: a low-pass whose cutoff follows the motion, second by second.

A fixed low-pass must choose one cutoff for the whole dance: high enough for its fastest passage,
so it leaves the noise of every slow one. Here each joint axis is cut into overlapping windows of
``window_s`` seconds (a short-time Fourier transform) and each window's frequencies are kept in
proportion to how far they stand above the tracker's noise: the gain ``max(0, 1 - a * N / |X|^2)``
of spectral subtraction (Boll 1979) with an over-subtraction factor ``a`` (Berouti, Schwartz and
Makhoul 1979), where ``N`` is the noise's power in that frequency bin. A held pose keeps its mean
and loses its jitter; a fast kick keeps the frequencies it has.

The noise is measured on the recording itself, in the band above :data:`NOISE_BAND` of the Nyquist
frequency (above 10 Hz at 30 fps), where a dancer's joints have almost nothing of their own: the
samples minus a zero-phase Butterworth low-pass at that band's edge, as a robust deviation (the
median absolute residual; a jump does not inflate it), scaled by how much of white noise that
filter leaves. That low-pass also runs before the Wiener gain, removing what is left of the noise
above the band (its response is in ``N``).
"""

from __future__ import annotations

import numpy as np

from kinectdata.core.motion import held_from_nearest

WIENER_DEFAULTS = {"window_s": 1.2, "over_subtraction": 2.0}
"""Defaults for dance: windows of 1.2 s (36 frames at 30 fps; its bins 0.83 Hz apart) and twice the
noise taken away. On the synthetic dancer seen by the simulated Kinect, windows of 0.8-2 s and
factors 2-2.5 come within 1 % of each other; longer windows blur a move's onset into its neighbours
and lose (docs/notebook/2026-12-cleaning.md)."""

NOISE_BAND = 2.0 / 3.0
"""The noise is measured, and the low-pass before the gain cuts, above this fraction of the Nyquist
frequency (10 Hz at 30 fps)."""

_MAD_TO_SIGMA = 1.4826  # the standard deviation of a normal variable over its median absolute deviation


def band_filter(fps: float, order: int = 2) -> np.ndarray:
    """The Butterworth low-pass (second-order sections) at :data:`NOISE_BAND` of the Nyquist frequency,
    run forwards and backwards before the gain."""
    from scipy import signal

    return signal.butter(order, NOISE_BAND * fps / 2.0, fs=fps, output="sos")


def _power_response(sos: np.ndarray, frequencies_hz: np.ndarray, fps: float) -> np.ndarray:
    """|H(f)|^4: the power response of ``sos`` run forwards and backwards, at ``frequencies_hz``."""
    from scipy import signal

    _, h = signal.sosfreqz(sos, worN=frequencies_hz, fs=fps)
    return np.abs(h) ** 4


def noise_sigma(residual: np.ndarray, sos: np.ndarray, fps: float) -> np.ndarray:
    """The noise's standard deviation per row, from ``residual`` [T, R] (the samples minus their
    low-pass by ``sos`` forwards and backwards, NaN where there is no sample): the median absolute
    residual as a deviation, over the share of white noise's variance that the low-pass leaves.
    Returns [R], the residual's units; 0 for a row without samples."""
    f = np.linspace(0.0, fps / 2.0, 1025)
    left = np.mean((1.0 - np.sqrt(_power_response(sos, f, fps))) ** 2)  # the residual of white noise, per unit variance
    r = np.asarray(residual, np.float64)
    has = np.isfinite(r).any(axis=0)
    spread = np.zeros(r.shape[1])
    if has.any():
        centred = r[:, has] - np.nanmedian(r[:, has], axis=0)
        spread[has] = _MAD_TO_SIGMA * np.nanmedian(np.abs(centred), axis=0)
    return spread / np.sqrt(left)


def short_time_wiener(
    smoothed: np.ndarray,
    sigma: np.ndarray,
    fps: float,
    sos: np.ndarray,
    *,
    window_s: float = WIENER_DEFAULTS["window_s"],
    over_subtraction: float = WIENER_DEFAULTS["over_subtraction"],
) -> np.ndarray:
    """The short-time Wiener gain applied to each row (see the module docstring).

    Args:
        smoothed: [K, R] rows of samples on an even grid, already low-passed by ``sos`` forwards and
            backwards; NaN where there is no sample (held from the nearest sample for the transform,
            NaN again on the way out).
        sigma: [R] the noise's standard deviation before the low-pass, as :func:`noise_sigma` gives it.
        fps: samples per second.
        sos: the low-pass the rows went through.
        window_s: the transform's window, seconds (a Hann window, three quarters overlapping).
        over_subtraction: ``a``, how many times the noise's power is taken away.

    Returns:
        [K, R], the same units.
    """
    from scipy import signal

    grid = np.asarray(smoothed, np.float64)
    have = np.isfinite(grid)
    x = np.nan_to_num(held_from_nearest(grid, have) if not have.all() else grid).T  # [R, K]: along the last axis
    K = x.shape[1]
    n = min(K, max(4, int(round(window_s * fps))))
    mean = x.mean(axis=1, keepdims=True)
    step = dict(fs=fps, window="hann", nperseg=n, noverlap=n - max(1, n // 4))
    f, _, spectra = signal.stft(x - mean, boundary="odd", padded=True, axis=-1, **step)  # [R, F, W]
    window = signal.get_window("hann", n)
    white = window @ window / window.sum() ** 2  # E|X|^2 of unit white noise in scipy's "spectrum" scaling
    noise = (np.asarray(sigma, np.float64) ** 2)[:, None, None] * white * _power_response(sos, f, fps)[None, :, None]
    power = np.abs(spectra) ** 2
    gain = np.clip(1.0 - over_subtraction * noise / np.maximum(power, np.finfo(float).tiny), 0.0, 1.0)
    gain[:, 0, :] = 1.0  # a window's mean is the pose held, not noise
    _, out = signal.istft(gain * spectra, boundary=True, time_axis=-1, freq_axis=-2, **step)
    out = (out[:, :K] + mean).T
    out[~have] = np.nan
    return out
