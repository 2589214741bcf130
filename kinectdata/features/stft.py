"""Short-time spectra of the audio slice of each motion frame: the network input of Yalta et al. (2016).

For motion frame ``k`` the caller gives ``starts[k]``, the index in the 16 kHz mono audio of the
frame's audio slice (``slice_samples = 534`` samples, 33 ms: one 30 fps motion frame). The slice
becomes ``n_frames = 5`` STFT frames of ``frame_samples = 160`` samples (10 ms) at hop
``hop_samples = 80`` (5 ms), i.e. slice offsets 0, 80, 160, 240 and 320. They cover the slice's
first 480 samples; **its last 54 samples are not used** (the paper's numbers, 534 samples -> 5
frames of 160 at hop 80, leave them over; a sixth frame would need 560). Each STFT frame is
multiplied by a periodic Hamming window (``scipy.signal.get_window("hamming", 160,
fftbins=True)``, as in the authors' code), zero-padded to ``n_fft = 256`` points and
transformed with a real FFT: 129 bins, ``sample_rate / n_fft = 62.5`` Hz apart (bin ``k`` is
``k * 62.5`` Hz; 1000 Hz is bin 16). Each STFT frame (one column of the 129 x 5 output) is then
normalised on its own, along the frequency axis. Output: ``float32 [N, 1, 129, 5]`` (channel,
frequency bin, STFT frame), the ``input`` array of the network.

Normalisations (:class:`StftConfig`):

``"frame_minmax"`` (preset ``"yalta2016"``, the paper: "the power is normalised to the range
0.1..0.9 along the frequency axis"):

- ``power="log"`` (the default): power in dB, ``10*log10(|X|^2)``, floored at the frame's
  maximum minus ``top_db = 80`` dB, then min-max into ``out_range = (0.1, 0.9)``:
  ``0.1 + 0.8 * (v - min) / (max - min)``. The paper does not say linear or log; log is the
  default because min-max of *linear* power puts almost every bin at the floor: a music frame's
  power spans 50-90 dB, so on the benchmark's music 61% of the linear values lie within 1e-3 of
  0.1 and 93% below 0.2 (log: 4% and 10%); the network would see a handful of peaks. The 80
  dB floor keeps a frame's range from being set by numerical noise in near-empty bins (e.g.
  above the low-pass of a resampled recording).
- ``power="linear"``: ``|X|^2`` min-max into ``out_range`` likewise (no floor).
- **Silence.** A frame is silent when the mean square of its 160 raw (unwindowed) samples is
  below ``silence_db = -60`` dB re full scale (tested as ``mean(x^2) < 10**(silence_db/10)``,
  equivalent to ``10*log10(mean(x^2)) < silence_db`` without taking the log of 0), or when its
  spectrum is flat: all bins equal to within rounding, ``min >= max * (1 - 1e-9)`` on the power
  (an exact ``max == min`` test misses the one case that occurs, a frame holding one non-zero
  sample, e.g. the last sample of the audio before the zero padding: its power spectrum is
  mathematically flat, but the FFT's rounding leaves ~1e-15 relative ripple that min-max would
  blow up to the full 0.1..0.9 range). A silent frame is the constant column ``out_range[0]`` =
  0.1: every silent frame gives exactly the same values whatever it holds below the threshold,
  so a network fed silence sees one fixed input (the paper's Figure 7: the motion stops).
  The rule uses the raw mean square, so a *DC offset* counts as sound: a constant slice at -40
  dBFS is not silent (its features are the window's spectrum). Remove DC before extracting if
  the recordings have an offset.
- The computation is done in the equivalent, better-conditioned form ``r = |X|^2 / max|X|^2``,
  ``L = log10(max(r, 10**(-top_db/10)))``, ``0.1 + 0.8 * (L - min L) / (0 - min L)``: the frame
  maximum is ``L = 0`` exactly and no log of 0 is ever taken. The maximum bin of a non-silent
  frame comes out exactly ``float32(0.9)``, the minimum exactly ``float32(0.1)``.

``"fixed_db"`` (preset ``"motion_dance"``, the authors' later public code, audiofhrozen/motion_dance
``local/inlib/datastft.py`` and ``local/evaluate.py``): magnitude spectrum in dB,
``20*log10(|X| / sum(window) * 2 + amin)`` with ``amin = 1e-6``, the one-sided factor 2 applied
to bins ``1 .. n_fft/2 - 1`` (1..127) but not to DC (0) and Nyquist (128); their code's slice
``s[1:-2]`` also left bin 127 undoubled, an off-by-one we do not reproduce (bin 127 is 6.02 dB
higher than theirs wherever |X| dominates ``amin``: up to +0.0867 after the mapping). The dB
are mapped linearly from the fixed range ``db_range = (-120, 5)`` into ``out_range = (-0.9,
0.9)``, ``-0.9 + 1.8 * (dB + 120) / 125`` (evaluated as one affine map of ``log10``), with no
per-frame normalisation and no silence rule: ``amin`` bounds the dB below at -120, so silence
(|X| = 0) gives -0.9 (to within 1 float32 ulp). Values are not clipped: for samples within +-1,
``|X| <= sum(window)``, so bins 1..127 reach at most 20*log10(2) = 6.02 dB -> 0.9147 and
DC/Nyquist 0 dB -> 0.828 (a full-scale sine gives about 0 dB at its bin, 0.828; only
square-like signals approach the bound); louder input goes beyond.
Their pipeline peak-normalised every song (``data /= max|data|``) before this step; that is the
caller's business, not done here. Their slices were 533 or 534 samples
(``linspace(0, 16000, 31)`` boundaries), which gives the same 5 frames since only 480 are used.

Numerics and speed. The whole recording is processed in chunks of ``chunk_frames`` motion
frames with no Python loop per frame: the ``[chunk, 5, 160]`` frames are gathered by fancy
indexing a ``sliding_window_view`` of the samples (slices that run off either end are built
separately with zero padding), windowed, transformed by one batched ``np.fft.rfft(..., n=256)``
and normalised with in-place whole-array operations. Computation is in float64
and only the result is rounded to float32. Measured on numpy 2.4 (pocketfft, x86-64, see
``benchmarks/bench_features.py``): the float64 FFT of these frames is *faster* than the float32
one (0.05 s against 0.07 s for 90 000 frames); a whole float32 pipeline is at most about 10%
faster (its elementwise steps are cheaper) but misses the 1e-5 accuracy target on quiet bins (max error 2e-5 for
``yalta2016``, 1.5e-4 for ``motion_dance``: the FFT's rounding error is relative to the frame's
loudest bin, and the fixed dB scale resolves bins down to -120 dB). In float64 the error against
a float64 per-slice reference is the final float32 rounding, 3e-8. Memory is bounded by the
chunk: about 22 kB per motion frame (6 MB at the default 256, whose working arrays stay in a core's
cache: 1.5x faster than chunks of 4096, which use 90 MB) plus the ``[N, 1, 129, 5]`` float32 output
(2.6 kB per frame).

Determinism. Each motion frame's result depends only on its own slice's samples: every step is
elementwise or a reduction along one frame's contiguous row, and numpy's FFT transforms each
row independently. Results are bit-identical whatever ``chunk_frames`` is and however the caller
cuts the audio into segments (starts relative to the segment), as long as the slice lies inside
the segment; ``tests/test_features.py`` checks this.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from kinectdata.core.errors import ConfigError
from kinectdata.features.config_dict import config_from_dict, config_to_dict

__all__ = ["PRESETS", "StftConfig", "stft_features"]

POWERS = ("log", "linear")
NORMALISATIONS = ("frame_minmax", "fixed_db")

FLAT_RTOL = 1e-9
"""A frame's spectrum counts as flat (so silent) when ``min >= max * (1 - FLAT_RTOL)`` on the power."""

_MEAN_SQUARE_LIMIT = 1e-8
"""Frame mean squares above this fraction of the dtype's largest value (1.8e300 in float64: |x|
around 1e150, or inf/NaN samples) are refused: beyond it ``|X|^2`` could overflow."""


@dataclass(frozen=True)
class StftConfig:
    """Parameters of :func:`stft_features`. Frozen, hashable, JSON-able via :meth:`to_dict`.

    Attributes:
        sample_rate: Hz of the samples the caller passes (not resampled here; recorded so that
            a stored config says what the bins mean: bin ``k`` is ``k * sample_rate / n_fft`` Hz).
        slice_samples: samples per motion frame's audio slice (534 = 33 ms at 16 kHz). Only
            ``(n_frames - 1) * hop_samples + frame_samples`` of them are used; the slice length
            decides the ``padded`` flag.
        frame_samples: samples per STFT frame (160 = 10 ms).
        hop_samples: samples between STFT frame starts (80 = 5 ms).
        n_frames: STFT frames per slice (5).
        n_fft: FFT length; frames are zero-padded to it; ``n_fft // 2 + 1`` bins (129).
        window: a ``scipy.signal.get_window`` name, taken periodic (``fftbins=True``).
        power: ``"log"`` (dB) or ``"linear"`` (|X|^2); ``"fixed_db"`` needs ``"log"``.
        normalisation: ``"frame_minmax"`` (each STFT frame min-max into ``out_range``) or
            ``"fixed_db"`` (magnitude dB mapped from ``db_range`` into ``out_range``).
        top_db: ``frame_minmax`` + ``log``: floor at the frame's maximum minus this many dB
            (> 0). Unused otherwise (may be None).
        silence_db: ``frame_minmax``: frames whose raw mean square is below this (dB re full
            scale) are silent; None disables the energy test (flat frames stay silent). Unused
            by ``fixed_db``.
        db_range: ``fixed_db``: the (low, high) dB mapped onto ``out_range``.
        out_range: (low, high) of the output values.
        amin: ``fixed_db``: added to the scaled magnitude before the log (bounds the dB below
            at ``20*log10(amin)``).
    """

    extractor: ClassVar[str] = "stft"

    sample_rate: int = 16000
    slice_samples: int = 534
    frame_samples: int = 160
    hop_samples: int = 80
    n_frames: int = 5
    n_fft: int = 256
    window: str = "hamming"
    power: str = "log"
    normalisation: str = "frame_minmax"
    top_db: float | None = 80.0
    silence_db: float | None = -60.0
    db_range: tuple[float, float] = (-120.0, 5.0)
    out_range: tuple[float, float] = (0.1, 0.9)
    amin: float = 1e-6

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        for name in ("sample_rate", "slice_samples", "frame_samples", "hop_samples", "n_frames", "n_fft"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 1:
                raise ConfigError(f"{name} must be a positive integer, got {value!r}")
            put(name, int(value))
        if self.used_samples > self.slice_samples:
            raise ConfigError(
                f"{self.n_frames} frames of {self.frame_samples} at hop {self.hop_samples} need "
                f"{self.used_samples} samples, more than slice_samples={self.slice_samples}"
            )
        if self.n_fft < self.frame_samples:
            raise ConfigError(f"n_fft={self.n_fft} is shorter than frame_samples={self.frame_samples}")
        if not isinstance(self.window, str):
            raise ConfigError(f"window must be a scipy.signal.get_window name, got {self.window!r}")
        if self.power not in POWERS:
            raise ConfigError(f"power must be one of {POWERS}, got {self.power!r}")
        if self.normalisation not in NORMALISATIONS:
            raise ConfigError(f"normalisation must be one of {NORMALISATIONS}, got {self.normalisation!r}")
        if self.normalisation == "fixed_db" and self.power != "log":
            raise ConfigError('normalisation="fixed_db" maps dB values: it needs power="log"')
        for name in ("top_db", "silence_db"):
            value = getattr(self, name)
            if value is not None:
                put(name, float(value))
        if (
            self.normalisation == "frame_minmax"
            and self.power == "log"
            and not (self.top_db is not None and 0 < self.top_db < math.inf)
        ):
            raise ConfigError(f"top_db must be a positive finite number of dB, got {self.top_db!r}")
        if self.silence_db is not None and math.isnan(self.silence_db):
            raise ConfigError("silence_db must be a number or None")
        for name in ("db_range", "out_range"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ConfigError(f"{name} must be (low, high) with low < high, got {getattr(self, name)!r}")
            put(name, (lo, hi))
        put("amin", float(self.amin))
        if not 0 < self.amin < math.inf:
            raise ConfigError(f"amin must be positive, got {self.amin!r}")
        # the window name is checked when the window is first built (_window): checking it here
        # would import scipy.signal whenever this module is imported

    @property
    def used_samples(self) -> int:
        """Samples of the slice the STFT frames cover: ``(n_frames - 1) * hop_samples + frame_samples`` (480)."""
        return (self.n_frames - 1) * self.hop_samples + self.frame_samples

    @property
    def n_bins(self) -> int:
        """Frequency bins of the real FFT: ``n_fft // 2 + 1`` (129)."""
        return self.n_fft // 2 + 1

    @property
    def bin_hz(self) -> float:
        """Spacing of the bins, Hz: ``sample_rate / n_fft`` (62.5)."""
        return self.sample_rate / self.n_fft

    @property
    def output_shape(self) -> tuple[int, int, int]:
        """Shape of one motion frame's features: ``(1, n_bins, n_frames)`` = (1, 129, 5)."""
        return (1, self.n_bins, self.n_frames)

    @property
    def span(self) -> tuple[int, int]:
        """Samples a frame reads, relative to its slice start: ``[0, slice_samples)``."""
        return 0, self.slice_samples

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able dict of every field (tuples as lists); :meth:`from_dict` inverts it exactly."""
        return config_to_dict(self, with_extractor=False)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StftConfig:
        """The config of a :meth:`to_dict` dict (also after a JSON round trip). Missing keys take
        their defaults; unknown keys raise ConfigError. An ``"extractor"`` key must say ``"stft"``."""
        return config_from_dict(cls, d, "an STFT")


PRESETS: dict[str, StftConfig] = {
    "yalta2016": StftConfig(),
    "motion_dance": StftConfig(
        normalisation="fixed_db",
        top_db=None,
        silence_db=None,
        db_range=(-120.0, 5.0),
        out_range=(-0.9, 0.9),
        amin=1e-6,
    ),
}
"""Named configurations: ``"yalta2016"`` (the paper, log power, per-frame 0.1..0.9) and
``"motion_dance"`` (the authors' public code, magnitude dB from [-120, 5] into [-0.9, 0.9])."""


_COSINE_WINDOWS = {"hamming": 0.54, "hann": 0.5}  # w[n] = a - (1 - a) cos(2 pi n / N), periodic


def _window(name: str, size: int) -> np.ndarray:
    """The periodic (``fftbins=True``) window ``name`` of ``size`` samples, float64, as
    ``scipy.signal.get_window`` gives it; Hamming and Hann are computed here because importing
    scipy.signal takes longer than featurising minutes of audio."""
    if name in _COSINE_WINDOWS:
        a = _COSINE_WINDOWS[name]
        return a - (1.0 - a) * np.cos(2.0 * np.pi * np.arange(size) / size)
    from scipy.signal import get_window

    try:
        return get_window(name, size, fftbins=True).astype(np.float64)
    except ValueError as exc:
        raise ConfigError(f"window must be a scipy.signal.get_window name, got {name!r} ({exc})") from exc


@dataclass(frozen=True)
class _Plan:
    """Per-config constants, computed once (see :func:`_plan`)."""

    window: np.ndarray  # [frame_samples] float64
    offsets: np.ndarray  # [n_frames] int64, STFT frame starts within the slice
    bin_scale: np.ndarray  # [n_bins] float64, fixed_db: 1/sum(window), doubled on bins 1..n_fft/2-1


@functools.lru_cache(maxsize=32)
def _plan(config: StftConfig) -> _Plan:
    window = _window(config.window, config.frame_samples)
    window.flags.writeable = False
    offsets = np.arange(config.n_frames, dtype=np.int64) * config.hop_samples
    bin_scale = np.full(config.n_bins, 2.0 / np.sum(window))
    bin_scale[0] /= 2  # DC
    if config.n_fft % 2 == 0:
        bin_scale[-1] /= 2  # Nyquist
    bin_scale.flags.writeable = False
    return _Plan(window, offsets, bin_scale)


def stft_features(
    samples: np.ndarray,
    starts: np.ndarray,
    config: StftConfig = StftConfig(),  # noqa: B008 (frozen, so a shared default is safe)
    *,
    chunk_frames: int = 256,
) -> tuple[np.ndarray, np.ndarray]:
    """Normalised short-time spectra of the audio slice of each motion frame (see the module docs).

    Args:
        samples: [S] mono audio at ``config.sample_rate`` Hz, float32 or float64 (any real
            floating dtype), full scale +-1. Must be finite; frames whose mean square exceeds
            1.8e300 (|x| around 1e150, only possible in float64) raise ConfigError.
        starts: [N] integer sample indices into ``samples`` where each motion frame's slice
            begins. May be negative or run past ``S``: the missing samples are zeros.
        config: the parameters; ``PRESETS["yalta2016"]`` (the default) or ``PRESETS["motion_dance"]``.
        chunk_frames: motion frames computed at once; bounds the working memory (about 22 kB per
            frame) and never changes the result.

    Returns:
        ``(features, padded)``: ``features`` float32 [N, 1, n_bins, n_frames] = [N, 1, 129, 5]
        (channel, frequency bin from 0 Hz up in ``config.bin_hz`` steps, STFT frame in time
        order); values in ``out_range`` for ``frame_minmax`` (silent frames exactly
        ``out_range[0]``), unclipped for ``fixed_db``. ``padded`` bool [N]: True where the
        ``slice_samples``-long slice starts before 0 or ends after ``S`` (zero-padded; True even
        when only the unused tail of the slice is outside).

    Raises:
        TypeError: ``samples`` is not floating point, or ``starts`` not integer.
        ValueError: wrong dimensions, ``chunk_frames < 1``, or non-finite/huge samples.
    """
    x = np.asarray(samples)
    if x.ndim != 1:
        raise ConfigError(f"samples must be 1-D mono, got shape {x.shape}")
    if not np.issubdtype(x.dtype, np.floating):
        raise TypeError(f"samples must be floating point in -1..1, got {x.dtype} (convert PCM first)")
    st = np.asarray(starts)
    if st.ndim != 1:
        raise ConfigError(f"starts must be 1-D, got shape {st.shape}")
    if st.size and not np.issubdtype(st.dtype, np.integer):
        raise TypeError(f"starts must be integer sample indices, got {st.dtype}")
    st = st.astype(np.int64, copy=False)
    if isinstance(chunk_frames, bool) or int(chunk_frames) != chunk_frames or chunk_frames < 1:
        raise ConfigError(f"chunk_frames must be a positive integer, got {chunk_frames!r}")
    chunk_frames = int(chunk_frames)
    if not isinstance(config, StftConfig):
        raise TypeError(f"config must be a StftConfig, got {type(config).__name__}")

    n, s = len(st), len(x)
    plan = _plan(config)
    features = np.empty((n, *config.output_shape), dtype=np.float32)
    padded = (st < 0) | (st > s - config.slice_samples)
    for c0 in range(0, n, chunk_frames):
        c1 = min(n, c0 + chunk_frames)
        result = _normalised_spectra(_gather(x, st[c0:c1], config, plan), config, plan)
        features[c0:c1, 0] = result.transpose(0, 2, 1)  # rounds to float32
    return features, padded


def _gather(x: np.ndarray, starts: np.ndarray, config: StftConfig, plan: _Plan) -> np.ndarray:
    """The raw STFT frames of the slices at ``starts``: float64 [n, n_frames, frame_samples].

    Slices whose used samples lie inside ``x`` are read through a sliding-window view (one row
    copy per frame); the others are built by clipped index arithmetic with zeros outside ``x``.
    """
    n, s, length = len(starts), len(x), config.frame_samples
    span = config.used_samples
    out = np.empty((n, config.n_frames, length), dtype=np.float64)
    inside = (starts >= 0) & (starts <= s - span)
    if s >= span:
        view = sliding_window_view(x, length)
        if inside.all():
            out[...] = view[starts[:, None] + plan.offsets]
        elif inside.any():
            rows = np.flatnonzero(inside)
            out[rows] = view[starts[rows, None] + plan.offsets]
    rows = np.flatnonzero(~inside)
    if rows.size:
        first = np.clip(starts[rows], -span, s)  # further out is all zeros anyway; no int overflow
        idx = first[:, None, None] + plan.offsets[:, None] + np.arange(length)
        valid = (idx >= 0) & (idx < s)
        if s:
            out[rows] = np.where(valid, x[np.clip(idx, 0, s - 1)], 0.0)
        else:
            out[rows] = 0.0
    return out


def _normalised_spectra(frames: np.ndarray, config: StftConfig, plan: _Plan) -> np.ndarray:
    """Window, FFT and normalise raw frames [n, n_frames, frame_samples] -> [n, n_frames, n_bins].

    Computes in the frames' dtype (float64 from :func:`_gather`; the benchmark also runs it in
    float32 to compare). Works in place on ``frames`` and on the spectrum buffers; every
    operation is elementwise or a reduction along one STFT frame's row, so each row's result
    depends on that row only.
    """
    mean_square = np.einsum("...i,...i->...", frames, frames)
    mean_square /= config.frame_samples
    if not np.all(mean_square <= _MEAN_SQUARE_LIMIT * np.finfo(frames.dtype).max):  # also catches NaN, inf
        raise ConfigError("samples must be finite, with |x| well below 1e150 (audio is expected in -1..1)")
    frames *= plan.window
    spec = np.fft.rfft(frames, n=config.n_fft, axis=-1)
    del frames  # freed here when the caller passed a temporary (stft_features does): less peak memory
    out = np.abs(spec)  # [n, n_frames, n_bins], |X|
    del spec
    lo, hi = config.out_range

    if config.normalisation == "fixed_db":
        # out_lo + (out_hi - out_lo) * (20*log10(a) - db_lo) / (db_hi - db_lo) as one affine map of log10(a).
        out *= plan.bin_scale
        out += config.amin
        np.log10(out, out=out)
        db_lo, db_hi = config.db_range
        slope = (hi - lo) / (db_hi - db_lo)
        out *= 20.0 * slope
        out += lo - db_lo * slope
        return out

    np.square(out, out=out)  # power |X|^2
    pmax = out.max(axis=-1, keepdims=True)
    pmin = out.min(axis=-1, keepdims=True)
    silent = pmin >= pmax * (1.0 - FLAT_RTOL)  # flat spectrum, including all zeros
    if config.silence_db is not None:
        silent |= mean_square[..., None] < 10.0 ** (config.silence_db / 10.0)
    # Per-row affine map lo + (v - vmin) * gain, gain 0 on silent rows (they come out exactly lo).
    if config.power == "linear":
        vmin, span = pmin, pmax - pmin
    else:
        scale = np.where(silent, 1.0, pmax)
        floor = 10.0 ** (-config.top_db / 10.0)
        out /= scale  # ratio to the frame's maximum, 1 at the maximum
        np.maximum(out, floor, out=out)
        np.log10(out, out=out)  # in [-top_db/10, 0]
        vmin = np.log10(np.maximum(pmin / scale, floor))  # == out.min(-1): division and log10 are monotone
        span = -vmin
    gain = np.divide(hi - lo, span, out=np.zeros_like(span), where=~silent)
    out -= vmin
    out *= gain
    out += lo
    return out
