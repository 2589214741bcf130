"""Log-mel spectra, one per motion frame: the audio input of the "Listen to Dance" pipeline (Lee et al. 2018).

For motion frame ``k`` the caller gives ``starts[k]``, the index in the mono audio of the frame's
slice (as for the STFT features: ``round(k * sample_rate / fps)``). One analysis window of
``n_fft = 1024`` samples (64 ms at 16 kHz) is centred ``centre_offset = 267`` samples after it,
the middle of a 30 fps frame's 533.3-sample slice: it covers audio from 15 ms before the frame's
time to 49 ms after. The paper gives no analysis parameters; these follow DC-TTS (whose blocks the
CDHC network reuses): a Hann window (periodic, ``scipy.signal.get_window("hann", n_fft)``), 80
mel bands on the Slaney mel scale (linear below 1 kHz, logarithmic above; librosa's default
``htk=False``) from ``fmin = 0`` to ``fmax = 8000`` Hz (Nyquist at 16 kHz), triangular filters of
peak 1 (librosa's ``norm=None``).

Scaling, per frame and with no per-recording statistics, so features can be computed live:

- magnitude ``|X| * 2 / sum(window)`` of the rFFT (a full-scale sine at a bin centre gives 1.0),
  squared: power ``P`` [n_fft // 2 + 1];
- band energies ``E = W @ P`` (``W`` [n_mels, n_fft // 2 + 1], :func:`mel_filterbank`);
- ``dB = 10 * log10(max(E, 10**(db_range[0] / 10)))`` (a sine at a band's centre frequency at full
  scale: 0 dB; silence: the floor);
- ``(dB - db_range[0]) / (db_range[1] - db_range[0])`` clipped into 0..1, with ``db_range = (-80,
  20)``: the floor maps to 0, full-scale sounds to about 0.8 (broadband sounds summed over a wide
  band can reach 1; louder is clipped).

Output ``float32 [N, n_mels]`` and ``padded`` bool [N]: True where the window runs off either end
of the audio (those samples count as zeros), e.g. the first frame, whose window starts 245
samples before the audio. Each frame depends only on its own window's samples, so results are the
same whatever the chunking and however the audio is streamed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.features.config_dict import config_from_dict, config_to_dict

__all__ = ["MelConfig", "mel_features", "mel_filterbank"]


@dataclass(frozen=True)
class MelConfig:
    """Parameters of :func:`mel_features`. Frozen, hashable, JSON-able via :meth:`to_dict`.

    Attributes:
        sample_rate: Hz of the samples the caller passes (recorded, not resampled here).
        slice_samples: samples per motion frame's slice (534 at 16 kHz / 30 fps; the builder checks
            it against the frame rate).
        n_fft: window and FFT length, samples.
        centre_offset: samples from a frame's slice start to its window's centre.
        window: a ``scipy.signal.get_window`` name, taken periodic.
        n_mels: mel bands. fmin, fmax: band edges, Hz (fmax at most the Nyquist frequency).
        db_range: (floor, top) dB mapped onto 0..1.
    """

    extractor: ClassVar[str] = "mel"

    sample_rate: int = 16000
    slice_samples: int = 534
    n_fft: int = 1024
    centre_offset: int = 267
    window: str = "hann"
    n_mels: int = 80
    fmin: float = 0.0
    fmax: float = 8000.0
    db_range: tuple[float, float] = (-80.0, 20.0)

    def __post_init__(self) -> None:
        for name in ("sample_rate", "slice_samples", "n_fft", "n_mels"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 1:
                raise ConfigError(f"{name} must be a positive integer, got {value!r}")
            object.__setattr__(self, name, int(value))
        object.__setattr__(self, "centre_offset", int(self.centre_offset))
        if not 0 <= self.fmin < self.fmax <= self.sample_rate / 2:
            raise ConfigError(f"need 0 <= fmin < fmax <= {self.sample_rate / 2:g} Hz, got {self.fmin}, {self.fmax}")
        lo, hi = (float(v) for v in self.db_range)
        if not lo < hi:
            raise ConfigError(f"db_range must be (low, high) with low < high, got {self.db_range!r}")
        object.__setattr__(self, "db_range", (lo, hi))

    @property
    def output_shape(self) -> tuple[int]:
        """Shape of one motion frame's features: ``(n_mels,)``."""
        return (self.n_mels,)

    @property
    def span(self) -> tuple[int, int]:
        """Samples a frame reads, relative to its slice start: ``[lo, hi)`` (-245, 779)."""
        lo = self.centre_offset - self.n_fft // 2
        return lo, lo + self.n_fft

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able dict of every field, with ``"extractor": "mel"``."""
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MelConfig:
        """The config of a :meth:`to_dict` dict; unknown keys raise ConfigError."""
        return config_from_dict(cls, d, "a mel")


def _hz_to_mel(hz: np.ndarray) -> np.ndarray:
    """Slaney's mel scale: 3 mels per 200 Hz below 1 kHz, then 27 mels per factor 6.4."""
    hz = np.asarray(hz, dtype=np.float64)
    log_part = 15.0 + np.log(np.maximum(hz, 1e-10) / 1000.0) / (np.log(6.4) / 27.0)
    return np.where(hz >= 1000.0, log_part, hz * 3.0 / 200.0)


def _mel_to_hz(mel: np.ndarray) -> np.ndarray:
    mel = np.asarray(mel, dtype=np.float64)
    return np.where(mel >= 15.0, 1000.0 * np.exp((np.log(6.4) / 27.0) * (mel - 15.0)), mel * 200.0 / 3.0)


def mel_filterbank(sample_rate: int, n_fft: int, n_mels: int, fmin: float, fmax: float) -> np.ndarray:
    """Triangular filters [n_mels, n_fft // 2 + 1], peak 1, on the Slaney mel scale.

    Band ``m`` rises from mel point ``m`` to ``m + 1`` and falls to ``m + 2`` of ``n_mels + 2``
    points evenly spaced in mels from ``fmin`` to ``fmax``; weights are linear in Hz between them
    (librosa's ``filters.mel(htk=False, norm=None)``).
    """
    bins = np.linspace(0.0, sample_rate / 2, n_fft // 2 + 1)
    edges = _mel_to_hz(np.linspace(_hz_to_mel(fmin), _hz_to_mel(fmax), n_mels + 2))
    width = np.diff(edges)
    ramps = edges[:, None] - bins[None, :]
    rising = -ramps[:-2] / width[:-1, None]
    falling = ramps[2:] / width[1:, None]
    return np.maximum(0.0, np.minimum(rising, falling))


@functools.lru_cache(maxsize=8)
def _plan(config: MelConfig) -> tuple[np.ndarray, np.ndarray]:
    from scipy.signal import get_window

    window = get_window(config.window, config.n_fft, fftbins=True).astype(np.float64)
    bank = mel_filterbank(config.sample_rate, config.n_fft, config.n_mels, config.fmin, config.fmax)
    return window * (2.0 / window.sum()), np.ascontiguousarray(bank.T)


def mel_features(
    samples: np.ndarray, starts: np.ndarray, config: MelConfig, *, chunk_frames: int = 1024
) -> tuple[np.ndarray, np.ndarray]:
    """The scaled log-mel spectrum of each motion frame (see the module docstring).

    Args:
        samples: [S] mono audio, float, nominally -1..1, at ``config.sample_rate``.
        starts: [N] int slice start of each motion frame (may run off either end).
        config: a :class:`MelConfig`.
        chunk_frames: frames computed at once (bounds memory: about 20 kB per frame).

    Returns:
        ``(features, padded)``: float32 [N, n_mels] in 0..1, and bool [N].
    """
    x = np.asarray(samples, dtype=np.float64)
    if x.ndim != 1:
        raise ConfigError(f"samples must be [S] mono, got shape {x.shape}")
    starts = np.asarray(starts, dtype=np.int64)
    window, bank_t = _plan(config)
    lo, hi = config.span
    floor, top = config.db_range
    out = np.empty((starts.size, config.n_mels), np.float32)
    padded = (starts + lo < 0) | (starts + hi > x.size)
    offsets = np.arange(config.n_fft)
    for c0 in range(0, starts.size, chunk_frames):
        s = starts[c0 : c0 + chunk_frames] + lo
        first, last = int(s.min()), int(s.max()) + config.n_fft
        region = np.zeros(last - first)
        a, b = max(first, 0), min(last, x.size)
        if b > a:
            region[a - first : b - first] = x[a:b]
        frames = region[(s - first)[:, None] + offsets] * window
        power = np.abs(np.fft.rfft(frames, axis=1)) ** 2
        energy = power @ bank_t
        db = 10.0 * np.log10(np.maximum(energy, 10.0 ** (floor / 10.0)))
        out[c0 : c0 + s.size] = np.clip((db - floor) / (top - floor), 0.0, 1.0)
    return out, padded
