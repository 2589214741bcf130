"""The pulse features (``kinectdata.features.rhythm``) computed independently, for the tests: the
onset envelope from scipy's window, librosa's mel filterbank and plain loops, and each frame's
values by evaluating the windowed Fourier sum term by term (no recursion). Slow but simple.

Import as ``from rhythm_reference import ...`` (``tests/`` is on the path, as for ``helpers``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import get_window


def reference_tempi(config) -> np.ndarray:
    """[K] BPM: ``lo * (hi / lo) ** (k / (K - 1))``, evenly spaced in log tempo, both ends included."""
    lo, hi = config.tempo_range_bpm
    k = np.arange(config.n_tempi)
    return lo * (hi / lo) ** (k / (config.n_tempi - 1))


def reference_onsets(audio: np.ndarray, config) -> np.ndarray:
    """o [H], H = len // hop + 1: value n from the window of ``frame_samples`` ending at sample
    ``n * hop`` (zeros before the audio): periodic Hann (scipy), power spectrum, librosa's Slaney mel
    bands without area normalisation, dB floored at -100, rises summed over bands, minus the mean
    of the last ``round(detrend_s * rate)`` values (fewer at the start), clipped at 0."""
    import librosa

    x = np.asarray(audio, np.float64)
    hop, size = config.hop_samples, config.frame_samples
    hops = x.size // hop + 1
    window = get_window("hann", size, fftbins=True)
    bank = librosa.filters.mel(
        sr=config.sample_rate, n_fft=size, n_mels=config.n_mels, fmin=0.0, fmax=config.fmax, htk=False, norm=None
    )
    db = np.empty((hops, config.n_mels))
    for n in range(hops):
        end = n * hop
        segment = np.zeros(size)
        lo = max(end - size, 0)
        segment[size - (end - lo) :] = x[lo:end]
        power = np.abs(np.fft.rfft(segment * window)) ** 2
        db[n] = 10 * np.log10(np.maximum(bank @ power, 1e-10))
    flux = np.zeros(hops)
    for n in range(1, hops):
        flux[n] = np.clip(db[n] - db[n - 1], 0, None).sum()
    k = max(1, round(config.detrend_s * config.sample_rate / hop))
    mean = np.array([flux[max(0, n - k + 1) : n + 1].mean() for n in range(hops)])
    return np.clip(flux - mean, 0, None)


def reference_pulse(onsets: np.ndarray, n: int, config) -> np.ndarray:
    """[3 K] the values at hop n of ``onsets`` (which must reach back a whole window): per tempo
    [salience, salience cos(phase), salience sin(phase)] of ``T = sum_{m < L} o[n - m] w[m]
    exp(i omega m)``, ``w[m] = exp(-m / (decay_s rate))``, L = ceil(window_s rate)."""
    rate = config.sample_rate / config.hop_samples
    length = math.ceil(config.window_s * rate)
    assert n - length + 1 >= 0, "the reference needs a whole window of onsets"
    m = np.arange(length)
    weighted = onsets[n - m] * np.exp(-m / (config.decay_s * rate))
    omega = 2 * np.pi * reference_tempi(config) / 60 / rate
    pulse = np.array([np.sum(weighted * np.exp(1j * w * m)) for w in omega])
    total = weighted.sum()
    if total == 0:
        return np.zeros(3 * config.n_tempi)
    salience = np.abs(pulse) / total
    phase = np.angle(pulse)
    return np.stack([salience, salience * np.cos(phase), salience * np.sin(phase)], axis=1).reshape(-1)


def reference_frames(audio: np.ndarray, starts: np.ndarray, config) -> np.ndarray:
    """[F, *config.output_shape] each frame's values at each of its instants (``start + column_end
    - j * column_hop``, or ``start + slice_samples`` without columns), from a window ending exactly
    there: the onsets of the audio shifted so that the instant falls on the hop grid (samples past
    the end are zeros). Frames must lie a whole window plus the detrending after the audio's start."""
    x = np.concatenate([np.asarray(audio, np.float64), np.zeros(4 * config.frame_samples + config.slice_samples)])
    if config.columns:
        instants = config.column_end - config.column_hop * np.arange(config.columns - 1, -1, -1)
    else:
        instants = np.array([config.slice_samples])
    hop = config.hop_samples
    envelopes: dict[int, np.ndarray] = {}
    out = []
    for start in (int(s) for s in starts):
        columns = []
        for instant in instants:
            e = start + int(instant)
            phase = e % hop
            if phase not in envelopes:
                envelopes[phase] = reference_onsets(x[phase:], config)
            columns.append(reference_pulse(envelopes[phase], (e - phase) // hop, config))
        values = np.stack(columns, axis=1)  # [3K, c]
        out.append(values[None] if config.columns else values[:, 0])
    return np.array(out)


def ideal_pulse(t: float, clicks: np.ndarray, tempi_bpm: np.ndarray, config) -> np.ndarray:
    """[K] complex: the windowed Fourier sum of unit impulses at the times ``clicks`` (s), in
    continuous time at time ``t``: ``sum_i exp(-(t - t_i) / decay_s) exp(i 2 pi f_k (t - t_i))``
    over the clicks in the past ``window_s``, divided by the sum of the weights."""
    lag = t - clicks[(clicks <= t) & (clicks > t - config.window_s)]
    weights = np.exp(-lag / config.decay_s)
    return (weights[None, :] * np.exp(2j * np.pi * (tempi_bpm[:, None] / 60) * lag[None, :])).sum(1) / weights.sum()


def click_track(bpm: float, seconds: float = 14.0, first: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """(float32 audio at 16 kHz, click times in s): 5 ms 1.5 kHz clicks every 60 / bpm s in digital silence."""
    n = int(seconds * 16000)
    x = np.zeros(n)
    burst = 0.5 * np.sin(2 * np.pi * 1500 * np.arange(80) / 16000) * np.exp(-np.arange(80) / 20)
    times = np.arange(first, seconds, 60.0 / bpm)
    samples = np.round(times * 16000).astype(int)
    for i in samples:
        x[i : i + 80] += burst[: n - i]
    return x.astype(np.float32), samples / 16000


def accented_eighths(bpm: float, seconds: float = 30.0, first: float = 0.3) -> np.ndarray:
    """float32 audio at 16 kHz: 30 ms noise bursts at twice ``bpm``, those on the beat three times as loud as
    those halfway between, over noise at -60 dBFS: onsets most periodic at twice the beat's rate."""
    n = int(seconds * 16000)
    x = np.random.default_rng(0).normal(0, 1e-3, n)
    noise = 0.3 * np.random.default_rng(1).normal(0, 1, 480) * np.hanning(480)
    for k, t in enumerate(np.arange(first, seconds - 0.1, 30.0 / bpm)):
        i = int(round(t * 16000))
        x[i : i + 480] += noise if k % 2 == 0 else noise / 3
    return x.astype(np.float32)
