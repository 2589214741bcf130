"""Jitter filters for joint positions, per joint, each sample weighted by its confidence.

- :func:`one_euro`: the 1-euro filter (Casiez, Roussel and Vogel, CHI 2012), the causal filter of
  motion capture and VR: an exponential low-pass whose cutoff rises with speed, ``min_cutoff_hz +
  beta * speed``, so that a still joint is steadied and a fast one not delayed. As the authors'
  reference code does, the speed is the raw samples' derivative smoothed at ``d_cutoff_hz``; here it
  is the joint's speed in metres per second (the norm over its axes), so that the three axes of a
  joint share one cutoff. A sample's smoothing factor is multiplied by its confidence: a joint the
  tracker only inferred (Kinect's confidence 0.5) moves the output half as far.
- :func:`zero_phase`: for offline use, a Butterworth low-pass run forwards and backwards
  (``scipy.signal.sosfiltfilt``: no delay) or a Savitzky-Golay smoother (``scipy.signal.savgol_filter``),
  applied as a normalised convolution (Knutsson and Westin 1993): the filter of ``confidence *
  position`` over the filter of ``confidence``, so that low-confidence samples count less and
  missing ones not at all; or the ``wiener`` method (:mod:`.wiener`), whose cutoff follows the motion.

Masked samples stay masked; gaps are not filled here.
"""

from __future__ import annotations

import numpy as np

from kinectdata.cleaning.recurrence import smooth
from kinectdata.cleaning.wiener import NOISE_BAND, WIENER_DEFAULTS, band_filter, noise_sigma, short_time_wiener
from kinectdata.core.errors import ConfigError
from kinectdata.core.motion import frame_clock, held_from_nearest

ONE_EURO_DEFAULTS = {"min_cutoff_hz": 1.0, "beta": 50.0, "d_cutoff_hz": 1.0}
"""Defaults for dance at 30 fps, positions in metres: a still joint smoothed below 1 Hz, a joint
moving at 0.1 m/s cut at 6 Hz, at 1 m/s at 51 Hz (no smoothing at all). A causal filter lags what
it smooths, and a dancer's joints are fast: on the synthetic dancer seen by the simulated Kinect
(3 mm of noise), a beta of 0.7 (a gentle filter for a pointer) left the joints 23 mm from the truth
against the sensor's 4.8 mm; 50 brings them to 4.5 mm (docs/cleaning.md)."""


def _alpha(cutoff_hz: np.ndarray | float, dt: np.ndarray) -> np.ndarray:
    """The exponential smoothing factor of a first-order low-pass at ``cutoff_hz`` for samples
    ``dt`` seconds apart (the 1-euro paper's ``1 / (1 + tau / Te)``, ``tau = 1 / (2 pi f_c)``)."""
    tau = 1.0 / (2.0 * np.pi * np.asarray(cutoff_hz, dtype=np.float64))
    return 1.0 / (1.0 + tau / dt)


def _valid_and_weight(
    p: np.ndarray, mask: np.ndarray | None, confidence: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """[T, J] where a sample is valid (finite, and in ``mask`` when given), and its weight: its
    confidence clipped to 0..1 (1 without confidences), 0 where not valid."""
    valid = np.isfinite(p).all(axis=-1)
    if mask is not None:
        valid &= np.asarray(mask, bool)
    weight = np.ones(valid.shape) if confidence is None else np.clip(np.asarray(confidence, np.float64), 0.0, 1.0)
    return valid, np.where(valid, weight, 0.0)


def one_euro(
    positions: np.ndarray,
    times: np.ndarray,
    mask: np.ndarray | None = None,
    confidence: np.ndarray | None = None,
    *,
    min_cutoff_hz: float = ONE_EURO_DEFAULTS["min_cutoff_hz"],
    beta: float = ONE_EURO_DEFAULTS["beta"],
    d_cutoff_hz: float = ONE_EURO_DEFAULTS["d_cutoff_hz"],
) -> np.ndarray:
    """The 1-euro filter of each joint (see the module docstring).

    Args:
        positions: [T, J, D] joint positions, metres.
        times: [T] seconds, increasing (uneven intervals are used as they are).
        mask: [T, J] True where a position is valid (default: where finite).
        confidence: [T, J] 0..1 weights (default 1).
        min_cutoff_hz: the cutoff of a still joint, Hz.
        beta: how fast the cutoff rises with speed, Hz per m/s.
        d_cutoff_hz: the cutoff of the speed's own low-pass, Hz.

    Returns:
        [T, J, D] filtered positions, NaN where masked.
    """
    p = np.asarray(positions, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    if min_cutoff_hz <= 0 or d_cutoff_hz <= 0 or beta < 0:
        raise ConfigError(f"1-euro filter: cutoffs must be positive and beta not negative, not {min_cutoff_hz}, "
                          f"{d_cutoff_hz}, {beta}")  # fmt: skip
    valid, weight = _valid_and_weight(p, mask, confidence)
    held = held_from_nearest(p, valid)  # a masked sample repeats the last valid one: no speed, and weight 0
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if len(t) > 1 else 1.0))[:, None]
    speed = np.zeros(valid.shape)
    speed[1:] = np.linalg.norm(np.diff(held, axis=0), axis=-1) / dt[1:]
    speed[~valid] = 0.0
    started = np.cumsum(valid, axis=0) > 0  # from each joint's first valid sample
    first = np.argmax(valid, axis=0)
    speed_weight = np.where(started, _alpha(d_cutoff_hz, dt), 0.0)
    smoothed_speed = smooth(speed_weight, speed, np.zeros(valid.shape[1]))
    cutoff = min_cutoff_hz + beta * smoothed_speed
    a = _alpha(cutoff, dt) * weight
    a[first, np.arange(valid.shape[1])] = np.where(valid.any(axis=0), 1.0, 0.0)  # the first sample starts it
    out = smooth(a[..., None], np.nan_to_num(held), np.zeros(p.shape[1:]))
    out[~valid] = np.nan
    return out


def zero_phase(
    positions: np.ndarray,
    fps: float,
    mask: np.ndarray | None = None,
    confidence: np.ndarray | None = None,
    *,
    method: str = "butterworth",
    cutoff_hz: float = 6.0,
    order: int = 2,
    window_s: float = 0.3,
    times: np.ndarray | None = None,
    wiener_window_s: float = WIENER_DEFAULTS["window_s"],
    over_subtraction: float = WIENER_DEFAULTS["over_subtraction"],
) -> np.ndarray:
    """A zero-phase low-pass of each joint, as a normalised convolution (see the module docstring).

    Args:
        positions: [T, J, D] joint positions on an even grid, metres.
        fps: frames per second of the grid.
        mask: [T, J] True where valid (default: where finite).
        confidence: [T, J] 0..1 weights (default 1).
        method: ``butterworth`` (``order`` and ``cutoff_hz``; run forwards and backwards, so the
            order doubles and the cutoff is where the gain is 1/2) or ``savgol`` (a cubic over
            ``window_s`` seconds).
        cutoff_hz: the Butterworth cutoff, Hz (below fps / 2).
        order: the Butterworth order.
        window_s: the Savitzky-Golay window, seconds (at least 5 frames).
        wiener_window_s, over_subtraction: the ``wiener`` method (:mod:`.wiener`: the Butterworth
            of ``order`` at the noise band's edge, then the short-time Wiener gain over windows of
            ``wiener_window_s`` seconds taking away ``over_subtraction`` times the noise's power).
        times: [T] the samples' times, seconds (default: ``positions`` taken as on an even grid).
            Given, each sample is put on the recording's frame grid
            (:func:`~kinectdata.core.motion.frame_clock`: a dropped frame is a missing sample, not
            a frame fewer), the grid is filtered, and each output is read at its own time: the
            filtered value at its frame plus the filtered velocity times the sample's offset from
            the grid. A sensor stamps each frame when its pose was captured, a few milliseconds
            off the grid (a dancer's hand at 1.5 m/s moves 3 mm in 2 ms).

    Returns:
        [T, J, D] filtered positions, NaN where masked.
    """
    from scipy import signal  # here: scipy.signal costs time at start-up

    p = np.asarray(positions, dtype=np.float64)
    valid, weight = _valid_and_weight(p, mask, confidence)
    denoise = None
    if method == "wiener":
        if wiener_window_s * fps < 4 or over_subtraction <= 0:
            raise ConfigError(f"a Wiener window must hold at least 4 frames and the over-subtraction be positive, "
                              f"not {wiener_window_s:g} s and {over_subtraction:g}")  # fmt: skip
        sos = band_filter(fps, order)

        def denoise(grid: np.ndarray, residual: np.ndarray) -> np.ndarray:
            return short_time_wiener(grid, noise_sigma(residual, sos, fps), fps, sos, window_s=wiener_window_s,
                                     over_subtraction=over_subtraction)  # fmt: skip

        method, cutoff_hz = "butterworth", NOISE_BAND * fps / 2.0
    if method == "butterworth":
        if not 0 < cutoff_hz < fps / 2:
            raise ConfigError(f"a Butterworth cutoff must lie between 0 and half the frame rate ({fps / 2:g} Hz), "
                              f"not {cutoff_hz:g} Hz")  # fmt: skip
        sos = signal.butter(order, cutoff_hz, fs=fps, output="sos")
        padding = min(p.shape[0] - 1, 3 * (2 * len(sos) + 1))

        def run(v: np.ndarray) -> np.ndarray:
            return signal.sosfiltfilt(sos, v, axis=-1, padlen=padding)
    elif method == "savgol":
        frames = max(5, int(round(window_s * fps)) | 1)
        if frames > p.shape[0]:
            raise ConfigError(f"a Savitzky-Golay window of {frames} frames is longer than the {p.shape[0]} frames")

        def run(v: np.ndarray) -> np.ndarray:
            return signal.savgol_filter(v, frames, 3, axis=-1, mode="interp")
    else:
        raise ConfigError(f"zero-phase method {method!r} is not butterworth, savgol or wiener")
    # time-last [J, D, T] and [J, T]: scipy filters the last axis without copying it first
    values = np.ascontiguousarray((np.where(valid[..., None], p, 0.0) * weight[..., None]).transpose(1, 2, 0))
    weight = np.ascontiguousarray(weight.T)
    if times is None:
        J, D, T = values.shape
        both = run(np.concatenate([values.reshape(J * D, T), weight]))
        filtered = both[: J * D].reshape(J, D, T) / _nonzero(both[J * D :])[:, None, :]
        if denoise is not None:
            raw = np.where(valid.T[:, None, :], values / np.where(weight > 0, weight, 1.0)[:, None, :], np.nan)
            flat = filtered.reshape(J * D, T).T
            filtered = denoise(flat, raw.reshape(J * D, T).T - flat).T.reshape(J, D, T)
    else:
        t = np.asarray(times, np.float64)
        # a few joints at a time: the same blocks of memory serve every group (fresh ones cost more
        # than the filter on a machine whose pages come slowly)
        filtered = np.concatenate(
            [
                _on_the_frame_grid(run, values[j : j + 4], weight[j : j + 4], t, denoise)
                for j in range(0, values.shape[0], 4)
            ]
        )
    filtered = filtered.transpose(2, 0, 1).copy()
    filtered[~valid] = np.nan
    return filtered


def _nonzero(total: np.ndarray) -> np.ndarray:
    """A normalised convolution's filtered weights, NaN where they vanish (no sample near)."""
    return np.where(np.abs(total) > 1e-9, total, np.nan)


def _on_the_frame_grid(run, values: np.ndarray, weight: np.ndarray, times: np.ndarray, denoise=None) -> np.ndarray:
    """``run`` (a zero-phase filter along the last axis) as a normalised convolution on the
    recording's frame grid, read back at ``times`` [T] (see :func:`zero_phase`'s ``times``):
    ``values`` [J, D, T] weighted samples, ``weight`` [J, T]; [J, D, T] out. A dropped frame is
    filled by the cubic through the two samples on either side of it (a normalised convolution left
    to bridge it is off by about the filter's weight at one frame times the distance moved in a
    frame: 4 cm at 3.8 m/s). Twice: a sample taken off the grid is first moved onto it along the
    first pass's velocity, so that the jitter does not enter the filter as noise. ``denoise``, when
    given, takes the filtered grid [K, J * D] and the samples' residuals from it [T, J * D] (NaN
    where there is no sample) and returns the grid denoised further (the ``wiener`` method)."""
    interval, numbers = frame_clock(times)
    frame = np.round(numbers).astype(np.int64)
    start = (times - frame * interval).mean()
    offset = (times - start - frame * interval)[:, None]  # [T, 1] s off the grid
    dropped, fill, fill_weight = _dropped_frames(frame, times, values, weight, start, interval)
    J, D, T = values.shape
    K = frame[-1] + 1
    # time-first [K, J * D] on the grid: a frame's samples are one row to gather or scatter
    samples, sample_weight = values.reshape(J * D, T).T, np.repeat(weight, D, axis=0).T  # [T, J * D]
    grid_weight = np.zeros((K, J))
    grid_weight[frame], grid_weight[dropped] = weight.T, fill_weight.T
    grid_values = np.zeros((K, J * D))
    grid_values[dropped] = fill.reshape(J * D, -1).T
    total = np.repeat(_nonzero(run(grid_weight.T)), D, axis=0).T  # [K, J * D]
    velocity = np.zeros((T, J * D))
    for last in (False, True):
        grid_values[frame] = samples - sample_weight * velocity * offset
        grid = run(grid_values.T).T / total
        if denoise is not None and last:  # the first pass only moves the samples onto the grid
            sampled = sample_weight > 0
            raw = np.where(sampled, grid_values[frame] / np.where(sampled, sample_weight, 1.0), np.nan)
            grid = denoise(grid, raw - grid[frame])
        if K > 1:
            velocity = np.nan_to_num(np.gradient(grid, interval, axis=0)[frame])
    out = grid[frame] + velocity * offset  # [T, J * D]
    return out.T.reshape(J, D, T)


def _dropped_frames(frame: np.ndarray, times: np.ndarray, values: np.ndarray, weight: np.ndarray, start: float,
                    interval: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The grid frames no sample fell on ``[M]``, their weighted values ``[J, D, M]`` and weights
    ``[J, M]`` (``values`` [J, D, T], ``weight`` [J, T]): the Lagrange cubic through the two samples
    before and the two after, at the frame's time, where all four are valid (weight their least);
    weight 0 elsewhere."""
    missing = np.setdiff1d(np.arange(frame[-1] + 1), frame)
    after = np.searchsorted(frame, missing)  # the first sample after each dropped frame
    around = after[:, None] + np.arange(-2, 2)  # [M, 4]
    inside = (around >= 0).all(axis=1) & (around < frame.size).all(axis=1)
    around = np.clip(around, 0, frame.size - 1)
    x, at = times[around], start + missing * interval  # [M, 4], [M]
    x[~inside] = np.arange(4)  # a drop without two samples on each side is not filled (weight 0 below)
    lagrange = np.ones(around.shape)
    for a in range(4):
        for b in range(4):
            if a != b:
                lagrange[:, a] *= (at - x[:, b]) / (x[:, a] - x[:, b])
    lagrange[~inside] = 0.0
    w = weight[:, around]  # [J, M, 4]
    fill_weight = np.where(inside & (w > 0).all(axis=-1), w.min(axis=-1), 0.0)  # [J, M]
    sample = values[..., around] / np.where(w > 0, w, 1.0)[:, None]  # [J, D, M, 4]: positions, unweighted
    fill = np.einsum("ma,jdma->jdm", lagrange, sample) * fill_weight[:, None]
    return missing, fill, fill_weight
