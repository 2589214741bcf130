"""The music's pulse, one vector per motion frame: what a network needs to keep time with a song
that its spectral features do not show (``rhythm`` extractor).

Why: the spectra of the two published pipelines show what sounds at each instant; the beat is in
how that changes over seconds. A network can learn to hear it from thousands of songs, not from the
few dozen of a dance corpus (on the 33 training songs of Dance with Melody an audio encoder trained
to tell the beat's phase learned the training songs by heart and told the phase of new songs no
better than chance), and the STFT features of Yalta et al. normalise every frame to its own
range, which hides most onsets (their level rises correlate 0.3-0.5 with librosa's onset strength
on that corpus's songs; dB-scaled features 0.7-0.8). So the pulse is computed, causally:

1. **Onsets**: a log-mel spectrum every ``hop_samples`` (5 ms at 16 kHz; a window of
   ``frame_samples`` ending there, so nothing from the future), its rises summed over the bands
   (spectral flux, as librosa's ``onset_strength`` with ``lag=1``), minus its mean over the
   previous ``detrend_s``, half-wave rectified: o[n] >= 0.
2. **Pulse at each tempo**: for ``n_tempi`` tempi spaced evenly in log tempo over ``tempo_range_bpm``,
   a Fourier tempogram over the past ``window_s`` only (Grosche and Mueller 2011, "Extracting
   predominant local pulse information from music recordings", with a one-sided window):
   ``T_k(n) = sum_{m = 0}^{L - 1} o[n - m] w[m] exp(i omega_k m)``, ``w[m] = decay ** m``. If the
   onsets repeat at tempo k, the terms add up, and ``arg T_k(n) = omega_k (time since the last
   pulse)``: the phase within the beat now.
3. **Per tempo, three values**: the pulse's salience ``s_k = |T_k| / sum_m o[n - m] w[m]`` (0..1:
   1 for onsets exactly periodic at tempo k), and ``s_k cos(arg T_k)``, ``s_k sin(arg T_k)``.
   Silence gives zeros.
4. **The predominant pulse at metrical levels** (``levels``, optional): the beat is the tempo of
   ``beat_range_bpm`` with the greatest salience times a log-normal tempo prior (centred on 120
   BPM, one octave wide: the prior of librosa's tempo estimate), as Grosche and Mueller's
   predominant local pulse picks one tempo per instant. With ``harmonic_weight`` h > 0 a tempo's
   salience is first added h times the salience at twice its tempo (``s_k + h s_{2k}``, 0 where twice
   it lies above ``tempo_range_bpm``): a Fourier tempogram peaks at the beat's multiples too (the
   eighth notes): on the 36 training and validation songs of Dance with Melody the pick without it
   was at librosa's beat in 45 % of the frames and at twice it in 38 %; with h = 1, at it in 69 %,
   at twice it in none, at half of it in 14 % (``python -m benchmarks.bench_pulse``). Picked afresh
   at every frame, the beat flickers between neighbouring tempi whose scores are near a tie (on
   those songs, after the first 12 s, it moves to another tempo 71 times a minute), and the levels'
   clocks, read at the new tempo's phase, jump with it (the beat's clock turns more than 0.5 rad off
   its median turn in 4.0 % of the frames); with ``beat_hold`` b > 0 the beat of the frame before is
   kept unless another tempo's score is more than 1 + b times its own (b = 0.3: 11 moves a minute,
   1.4 % of the frames, at librosa's beat in 72 % of the frames instead of 70 %). For each
   level m (1 the beat, 2 two beats, 3 and 4 a bar of 3 or 4 beats...) the pulse of the tempo
   nearest the beat's tempo / m gives ``s* cos(arg T)``, ``s* sin(arg T)``, s* the beat's salience:
   a clock at the song's own beat and bar whatever its tempo, which a network can read without
   finding the right tempo among all of them itself (a convolutional decoder reading the tempi
   kept one tempo's phase, the same period for every song: each tempo's phase turns at that tempo
   whenever there are onsets, a clock whatever the music; ``tempo_phases`` false leaves them out).
   ``bar_levels`` are counted in bars of the song's metre (``beats_per_bar``, given by the caller: a
   dataset build takes the recordings manifest's, else estimates it from the music): a bar is 3
   beats in a waltz and 4 in a cha-cha, so one output is the bar whatever the metre (with fixed
   levels of 3 and 4 beats, a network that learned waltzes at the 3-beat level danced cha-chas at 3
   beats too: docs/notebook/2026-11-real-dance.md). A level's tempo below ``tempo_range_bpm`` takes the lowest tempo.
   A level above 1 has the phase of the onsets' own periodicity at its tempo: it tells the bar where
   the downbeats sound different (louder, or across more of the spectrum); where they do not, it
   restarts at every beat. With ``unit_levels`` each level's clock is ``cos``, ``sin`` of its phase at
   length 1 (0 in silence) instead of s* times them.
5. **Counted levels** (``counted_levels``): where it restarts at every beat, a bar level's phase
   hardly turns (on the 36 training and validation songs of Dance with Melody the bar's clock turned
   0.43 times a bar, median, within 5 % of once a bar in 2 of 36 songs; two bars' 0.00 times;
   ``python -m benchmarks.bench_pulse``), and a network that is the same at every instant cannot
   make a bar out of a clock that repeats every beat: its output repeats with its input. Counted,
   each level above the beat takes the beat's phase summed over the frames since the first (the
   turn of each frame at the frame's beat tempo, never backwards) and divided by the level's beats:
   a clock that turns once a bar at the song's tempo whatever the downbeats sound like (on the same
   songs 1.00 times a bar, median, within 5 % in 24 of 36; 6 waltzes at half, their beat picked at
   half librosa's). Where the bar starts is unknown (the count starts at the first frame), so it is
   a clock at the bar's rate, not the downbeat's. The counted levels and a held beat are the
   outputs that depend on every earlier frame, not only on the frame's own samples: the frames must
   be given in time order, each less than half a beat after the one before (consecutive motion
   frames), and a stream carries the count and the held beat from call to call (:class:`PulseCount`).

Output per motion frame: ``[3 * n_tempi + 2 * L]`` values in -1..1, L the levels and bar levels
(tempo by tempo: salience, cosine, sine; then level by level: cosine, sine; with ``tempo_phases``
false ``[n_tempi + 2 * L]``: the saliences, then the levels; with ``saliences`` false ``[2 * L]``:
the levels alone), or with ``columns`` = c, ``[1, 3 * n_tempi, c]`` (``[1, n_tempi, c]`` without the
tempo phases): those values at c instants spread over the frame's slice like the STFT features'
sub-frames (43 tempi give 129 rows, the STFT's bins: the two stack as channels of one [2, 129, 5]
input), or with ``planes`` = (rows, columns) ``[values, rows, columns]``, each value a constant
plane (the clocks stacked after spectra). A frame reads the ``window_s`` before its slice: history,
so ``padded`` flags only frames whose own slice runs off the audio. Each frame's onsets are taken on
a grid of hops through its last instant (the window of the last value ends exactly there), so its
values depend on its own span of samples only, not on where the audio passed in begins: streaming
gives what the whole file gives, up to float rounding. Frames whose instants lie at different phases
of the hop (3 at 30 fps and 16 kHz: 534 + round(k 533.3) modulo 80) need one onset envelope each.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.features.config_dict import checked_planes, config_from_dict, config_to_dict

__all__ = ["DEFAULT_BEATS_PER_BAR", "PulseCount", "RhythmConfig", "predominant_beat", "rhythm_features"]

DEFAULT_BEATS_PER_BAR = 4
"""The metre a song's bar levels take when nothing says otherwise: most dance music is in 4."""

_RESIDUE = 1e-9
"""A window's onset sum at most this share of the recursion's whole sum is the recursion's rounding
residue, not onsets: its pulse is 0 (:func:`_windowed_sums`)."""

DIRECT_SUMS_UPTO = 16
"""A call that needs the pulse at this many instants or fewer (a live frame's one to five) sums each
window directly; more share one recursion over the audio (:func:`_windowed_sums`)."""


@dataclass(frozen=True)
class RhythmConfig:
    """Parameters of :func:`rhythm_features` (module docstring). Frozen, JSON-able via :meth:`to_dict`.

    Attributes:
        sample_rate: Hz. slice_samples: samples per motion frame's slice.
        hop_samples: samples between onset values (80: 200 per second at 16 kHz).
        frame_samples: the onset spectra's window, ending at each hop (512: 32 ms).
        n_mels: bands of the onset spectra; fmax: their top, Hz.
        detrend_s: seconds of onsets averaged and subtracted before rectifying.
        window_s: seconds of past onsets each pulse looks at. decay_s: the window's time constant
            (``w = exp(-t / decay_s)``).
        n_tempi, tempo_range_bpm: the tempi looked at (log-spaced, inclusive).
        levels: metrical levels of the predominant pulse output after the tempi (module
            docstring, step 4), as multiples of the beat's period; () for none.
        bar_levels: more levels, after ``levels``, as multiples of the bar's period in the song's
            metre (``beats_per_bar`` of :func:`rhythm_features`): (1, 2) gives a bar and two bars,
            3 and 6 beats in a waltz, 4 and 8 in a song in 4; () for none.
        beat_range_bpm: the tempi the beat is looked for among (within ``tempo_range_bpm``; None:
            all of them).
        harmonic_weight: the share of the salience at twice a tempo added to its own when the beat
            is picked (module docstring, step 4); 0: none.
        beat_hold: the beat picked at a frame is kept at the next unless another tempo's score
            exceeds its score by more than this share (module docstring, step 4); 0: picked afresh at
            every frame. Needs levels or bar levels.
        tempo_phases: each tempo's ``s cos``, ``s sin`` after its salience (step 3); False: the
            saliences alone, so that the only clocks in the output are the levels' (a network given a
            fixed tempo's phase can keep time at that tempo whatever it hears).
        saliences: each tempo's values (its salience, and its phases with ``tempo_phases``) before the
            levels; False: the levels' clocks alone, ``[2 L]`` (the tempi still pick the beat). Needs
            levels or bar levels, and no ``tempo_phases``.
        counted_levels: the levels above the beat from the beat's counted phase (module
            docstring, step 5) instead of the tempogram's phase at their tempi.
        unit_levels: the levels' clocks at unit amplitude, ``cos``, ``sin`` of their phase wherever
            the window holds onsets (0 in silence), instead of scaled by the beat's salience (0.07-0.5
            in most songs of Dance with Melody, so a song whose onsets are less regular is heard with
            a fainter clock).
        columns: 0 for a vector per frame (at the slice's end); c > 0 for a [1, 3 n_tempi, c]
            (without the tempo phases [1, n_tempi, c]) plane of values at c instants of the slice
            (``column_hop`` samples apart, the last ``column_end`` samples after the slice start, at
            most ``slice_samples``: the STFT features' sub-frames end at 160, 240, ..., 480). A
            value is taken at the last hop of the frame's grid at or before its instant (exactly at
            it when ``column_hop`` is a multiple of ``hop_samples``).
        planes: None for the vector layout; (rows, columns) to give each of its values as a constant
            plane, ``[values_per_instant, rows, columns]`` (only with ``columns`` 0): the levels'
            clocks beside spectra, for a model that takes them past its convolutions (the yalta
            model's side channels) as it takes the style input's planes.
    """

    extractor: ClassVar[str] = "rhythm"

    sample_rate: int = 16000
    slice_samples: int = 534
    hop_samples: int = 80
    frame_samples: int = 512
    n_mels: int = 40
    fmax: float = 8000.0
    detrend_s: float = 0.4
    window_s: float = 6.0
    decay_s: float = 2.0
    n_tempi: int = 43
    tempo_range_bpm: tuple[float, float] = (40.0, 240.0)
    levels: tuple[int, ...] = ()
    bar_levels: tuple[int, ...] = ()
    beat_range_bpm: tuple[float, float] | None = None
    harmonic_weight: float = 0.0
    beat_hold: float = 0.0
    tempo_phases: bool = True
    saliences: bool = True
    counted_levels: bool = False
    unit_levels: bool = False
    columns: int = 0
    column_hop: int = 80
    column_end: int = 480
    planes: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        for name in ("sample_rate", "slice_samples", "hop_samples", "frame_samples", "n_mels", "n_tempi"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 1:
                raise ConfigError(f"rhythm features: {name} must be a positive integer, got {value!r}")
            object.__setattr__(self, name, int(value))
        for name in ("columns", "column_hop", "column_end"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 0:
                raise ConfigError(f"rhythm features: {name} must be a whole number at least 0, got {value!r}")
            object.__setattr__(self, name, int(value))
        lo, hi = (float(v) for v in self.tempo_range_bpm)
        if not 0 < lo < hi:
            raise ConfigError(
                f"rhythm features: tempo_range_bpm must be (low, high) with 0 < low < high, got {lo}, {hi}"
            )
        object.__setattr__(self, "tempo_range_bpm", (lo, hi))
        for name in ("levels", "bar_levels"):
            levels = tuple(getattr(self, name))
            if any(isinstance(m, bool) or int(m) != m or m < 1 for m in levels):
                raise ConfigError(f"rhythm features: {name} must be whole numbers at least 1, got {levels!r}")
            object.__setattr__(self, name, tuple(int(m) for m in levels))
        if self.beat_range_bpm is not None:
            beat_lo, beat_hi = (float(v) for v in self.beat_range_bpm)
            if not lo <= beat_lo < beat_hi <= hi:
                raise ConfigError(
                    f"rhythm features: beat_range_bpm ({beat_lo:g}, {beat_hi:g}) must be a range within "
                    f"tempo_range_bpm ({lo:g}, {hi:g})"
                )
            object.__setattr__(self, "beat_range_bpm", (beat_lo, beat_hi))
        if not float(self.harmonic_weight) >= 0:
            raise ConfigError(f"rhythm features: harmonic_weight must be at least 0, got {self.harmonic_weight!r}")
        object.__setattr__(self, "harmonic_weight", float(self.harmonic_weight))
        try:
            hold = float("nan") if isinstance(self.beat_hold, bool) else float(self.beat_hold)
        except (TypeError, ValueError):
            hold = float("nan")
        if not 0 <= hold < float("inf"):
            raise ConfigError(f"rhythm features: beat_hold must be a finite number at least 0, got {self.beat_hold!r}")
        object.__setattr__(self, "beat_hold", hold)
        if self.beat_hold and not (self.levels or self.bar_levels):
            raise ConfigError("rhythm features: beat_hold holds the levels' beat: give levels or bar_levels")
        for name in ("tempo_phases", "saliences", "counted_levels", "unit_levels"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"rhythm features: {name} must be true or false, got {getattr(self, name)!r}")
        if not self.saliences and (self.tempo_phases or not (self.levels or self.bar_levels)):
            raise ConfigError("rhythm features: without the saliences the output is the levels' clocks: give levels or "
                              "bar_levels, and no tempo_phases")  # fmt: skip
        if self.counted_levels and not (self.levels or self.bar_levels):
            raise ConfigError("rhythm features: counted_levels counts the levels: give levels or bar_levels")
        if self.unit_levels and not (self.levels or self.bar_levels):
            raise ConfigError("rhythm features: unit_levels sets the levels' amplitude: give levels or bar_levels")
        if (self.levels or self.bar_levels) and self.columns:
            raise ConfigError("rhythm features: levels are for the vector layout (columns 0)")
        if self.planes is not None:
            object.__setattr__(self, "planes", checked_planes(self.planes, "rhythm features"))
            if self.columns:
                raise ConfigError("rhythm features: planes are for the vector layout (columns 0)")
        for name in ("detrend_s", "window_s", "decay_s", "fmax"):
            if not float(getattr(self, name)) > 0:
                raise ConfigError(f"rhythm features: {name} must be positive, got {getattr(self, name)!r}")
        if self.window_s < 60.0 / lo:
            raise ConfigError(f"rhythm features: window_s ({self.window_s:g} s) must hold one beat of {lo:g} BPM")
        if self.columns and self.column_end - (self.columns - 1) * self.column_hop < 0:
            raise ConfigError("rhythm features: the columns must lie at or after the slice start")
        if self.columns and self.column_end > self.slice_samples:
            raise ConfigError(
                f"rhythm features: the columns must lie within the slice: column_end ({self.column_end}) is after "
                f"its end ({self.slice_samples})"
            )

    @property
    def values_per_instant(self) -> int:
        """``3 n_tempi + 2 L`` (``n_tempi + 2 L`` without the tempo phases, ``2 L`` without the
        saliences), L the levels and bar levels: the values taken at each instant of a frame."""
        tempi = ((3 if self.tempo_phases else 1) * self.n_tempi) if self.saliences else 0
        return tempi + 2 * (len(self.levels) + len(self.bar_levels))

    @property
    def needs_metre(self) -> bool:
        """True when the output depends on the song's beats per bar (``bar_levels``)."""
        return bool(self.bar_levels)

    def new_state(self, live: bool = False) -> PulseCount | None:
        """A fresh count for a stream of calls (:class:`PulseCount`), or None without counted levels
        or a held beat; ``live``: a stream of a frame or two per call, which keeps the onset spectra
        it computed (:class:`OnsetSpectra`: the same output, a fraction of the work)."""
        if live:
            return PulseCount(spectra=OnsetSpectra())
        return PulseCount() if self.follows_earlier_frames else None

    @property
    def follows_earlier_frames(self) -> bool:
        """True when a frame's values depend on the frames before it (counted levels, a held beat):
        frames must then come in time order, and a stream carries a :class:`PulseCount`."""
        return self.counted_levels or self.beat_hold > 0

    def beat_multiples(self, beats_per_bar: int) -> tuple[int, ...]:
        """Every output level in beats: ``levels``, then ``bar_levels`` x ``beats_per_bar``."""
        return self.levels + tuple(m * beats_per_bar for m in self.bar_levels)

    @property
    def output_shape(self) -> tuple[int, ...]:
        """``(values_per_instant,)``, ``(1, values_per_instant, columns)`` or with ``planes``
        ``(values_per_instant, *planes)``."""
        rows = self.values_per_instant
        if self.planes:
            return (rows, *self.planes)
        return (1, rows, self.columns) if self.columns else (rows,)

    @property
    def tempi_bpm(self) -> np.ndarray:
        """[n_tempi] the tempi looked at, beats per minute."""
        return np.geomspace(*self.tempo_range_bpm, self.n_tempi)

    @property
    def history(self) -> int:
        """Samples before an instant that its pulse depends on: the window, the detrending and one
        onset spectrum (and the hop before it, for the flux)."""
        hops = int(np.ceil(self.window_s * self.sample_rate / self.hop_samples)) + self._detrend_hops + 1
        return hops * self.hop_samples + self.frame_samples

    @property
    def _detrend_hops(self) -> int:
        return max(1, int(round(self.detrend_s * self.sample_rate / self.hop_samples)))

    @property
    def instants(self) -> np.ndarray:
        """Sample offsets from a slice's start at which a frame's values are taken."""
        if not self.columns:
            return np.array([self.slice_samples], np.int64)
        return self.column_end - self.column_hop * np.arange(self.columns - 1, -1, -1, dtype=np.int64)

    @property
    def span(self) -> tuple[int, int]:
        """Samples a frame reads, relative to its slice start: ``[-history, slice_samples)``."""
        return -self.history, self.slice_samples

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able dict of every field, with ``"extractor": "rhythm"``; without ``bar_levels``
        when there are none, ``counted_levels`` and ``unit_levels`` when false, ``beat_hold`` when 0,
        ``planes`` when None and ``saliences`` when true, as before they existed (so a dataset built
        then keeps its build key, and its runs their features)."""
        d = config_to_dict(self)
        for name in _ADDED_LATER:
            if getattr(self, name) == _DEFAULTS[name]:
                del d[name]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> RhythmConfig:
        """The config of a :meth:`to_dict` dict; unknown keys raise ConfigError."""
        return config_from_dict(cls, d, "a rhythm")


_ADDED_LATER = ("bar_levels", "beat_hold", "counted_levels", "saliences", "unit_levels", "planes")
"""Fields added after datasets were built: a config's dict leaves each out at its default."""
_DEFAULTS = {f.name: f.default for f in fields(RhythmConfig)}


@functools.lru_cache(maxsize=8)
def _mel_bank(config: RhythmConfig) -> np.ndarray:
    from kinectdata.features.mel import mel_filterbank

    return mel_filterbank(config.sample_rate, config.frame_samples, config.n_mels, 0.0, config.fmax)


@functools.lru_cache(maxsize=8)
def _poles(config: RhythmConfig) -> tuple[np.ndarray, int]:
    """([n_tempi + 1] complex poles ``decay * exp(i omega_k)``, the last one real (omega 0: the
    window's weighted sum of onsets), L the window in hops)."""
    rate = config.sample_rate / config.hop_samples
    omega = 2 * np.pi * (config.tempi_bpm / 60.0) / rate
    decay = np.exp(-1.0 / (config.decay_s * rate))
    return decay * np.exp(1j * np.append(omega, 0.0)), int(np.ceil(config.window_s * rate))


def _windowed_sums(onsets: np.ndarray, config: RhythmConfig) -> np.ndarray:
    """[H, n_tempi + 1] complex: at each hop n, ``sum_{m < L} onsets[n - m] pole ** m`` for each pole
    of :func:`_poles` (the pulse at each tempo, then the weighted onset sum). One first-order
    recursion per pole, ``y[n] = pole y[n - 1] + o[n]``, then ``y[n] - pole ** L y[n - L]`` keeps
    exactly the window: O(H) per tempo. That difference leaves rounding residue (about 1e-16 of y)
    where the window holds no onset, and a salience of residue over residue: rows whose weighted
    onset sum is not clearly above it (:data:`_RESIDUE` of y) are exactly 0."""
    from scipy.signal import lfilter

    poles, length = _poles(config)
    out = np.empty((onsets.size, poles.size), np.complex128)
    for k, pole in enumerate(poles):
        y = lfilter([1.0], [1.0, -pole], onsets.astype(np.complex128))
        out[:, k] = y
        out[length:, k] -= pole**length * y[:-length]
    out[out[:, -1].real <= _RESIDUE * y.real] = 0.0  # y: the recursion of the last, real pole (the onset sum)
    return out


@functools.lru_cache(maxsize=8)
def _window_weights(config: RhythmConfig) -> tuple[np.ndarray, np.ndarray]:
    """The real and imaginary parts [L, n_tempi + 1] of ``pole ** (L - 1 - i)`` for each pole of
    :func:`_poles`: a window of L onsets in time order times these is its pulse at every tempo."""
    poles, length = _poles(config)
    weights = poles[None, :] ** np.arange(length - 1, -1, -1)[:, None]
    return np.ascontiguousarray(weights.real), np.ascontiguousarray(weights.imag)


def _windowed_sums_at(onsets: np.ndarray, hops: np.ndarray, config: RhythmConfig) -> np.ndarray:
    """[*hops.shape, n_tempi + 1] complex: :func:`_windowed_sums` at ``hops`` only, each window's
    onsets times the poles' powers (two real matrix products), for the few instants of a live frame
    (O(L) per hop and tempo, where the recursion costs O(H) per tempo for any number of hops). The
    same rows are 0 (those whose onset sum is not clearly above the recursion's residue), so the
    two agree to float rounding. ``hops`` >= L - 1: every window lies in ``onsets``."""
    from scipy.signal import lfilter

    poles, length = _poles(config)
    real, imag = _window_weights(config)
    windows = np.lib.stride_tricks.sliding_window_view(onsets, length)[hops.ravel() - length + 1]
    out = (windows @ real + 1j * (windows @ imag)).reshape(*hops.shape, poles.size)
    onset_sum = lfilter([1.0], [1.0, -poles[-1].real], onsets)[hops]  # the recursion's scale, for its residue
    out[out[..., -1].real <= _RESIDUE * onset_sum] = 0.0
    return out


def onset_envelope(
    samples: np.ndarray,
    config: RhythmConfig,
    spectra: OnsetSpectra | None = None,
    at: int = 0,
    real: tuple[int, int] | None = None,
) -> np.ndarray:
    """o [H] >= 0: the detrended, rectified log-mel flux at hops ``n * hop_samples`` (n = 0..H-1) of
    ``samples`` [S] (value n from the window ending at sample ``n * hop_samples``; zeros before the
    first sample), H = S // hop_samples + 1. ``spectra``: the spectra a stream of calls computed,
    reused and added to, ``samples[0]`` being the stream's sample ``at``, its samples ``real[0]`` to
    ``real[1]`` the stream's own audio (the rest zeros put in; before the stream's first sample,
    its own silence)."""
    x = np.asarray(samples, np.float32)
    hops = x.size // config.hop_samples + 1
    padded = np.concatenate([np.zeros(config.frame_samples, np.float32), x])
    ends = np.arange(hops) * config.hop_samples + config.frame_samples  # window [end - frame, end) of padded
    windows = np.lib.stride_tricks.sliding_window_view(padded, config.frame_samples)
    window = np.hanning(config.frame_samples + 1)[:-1]

    def log_mel(windows: np.ndarray) -> np.ndarray:
        power = np.abs(np.fft.rfft(windows.astype(np.float64) * window, axis=1)) ** 2
        return 10 * np.log10(np.maximum(power @ _mel_bank(config).T, 1e-10))

    if spectra is None:
        db = log_mel(windows[ends - config.frame_samples])
    else:
        lo, hi = real if real is not None else (at, at + x.size)
        end = at + ends - config.frame_samples  # where each window ends in the stream
        reusable = ((end - config.frame_samples >= lo) & (end <= hi)) | (end <= 0)
        windows_of = lambda rows: windows[ends[rows] - config.frame_samples]  # noqa: E731
        db = spectra.spectra(windows_of, end, reusable, config.hop_samples, log_mel)
    flux = np.zeros(hops)
    flux[1:] = np.maximum(np.diff(db, axis=0), 0.0).sum(axis=1)
    k = config._detrend_hops
    cumulative = np.concatenate([[0.0], np.cumsum(flux)])
    first = np.maximum(np.arange(hops) - k + 1, 0)
    local_mean = (cumulative[np.arange(hops) + 1] - cumulative[first]) / (np.arange(hops) + 1 - first)
    return np.maximum(flux - local_mean, 0.0)


def _pulse_values(
    x: np.ndarray,
    starts: np.ndarray,
    phase: int,
    config: RhythmConfig,
    spectra: OnsetSpectra | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tempi's values [F, c, V] (no levels: :func:`_level_values` adds them) of frames ``starts``
    whose last instants lie at ``phase`` modulo the hop, with every tempo's salience and phase [F, c, K]."""
    hop = config.hop_samples
    need = int(starts.min()) - config.history
    first = need - (need - phase) % hop  # at or before what the frames need, on their grid
    last = int(starts.max()) + config.slice_samples
    lo, hi = max(first, 0), min(max(last, 0), x.size)
    piece = np.zeros(last - first, np.float32)
    if hi > lo:
        piece[lo - first : hi - first] = x[lo:hi]
    origin = 0 if spectra is None else spectra.origin
    # the stream's own audio in the piece: the buffer's samples, and its silence before its first sample
    real = (origin + lo if origin + lo > 0 else -(1 << 62), origin + hi)
    envelope = onset_envelope(piece, config, spectra, origin + first, real)
    at = (starts[:, None] + config.instants[None, :] - first) // hop  # [F, c]: the hop at or before each instant
    if at.size <= DIRECT_SUMS_UPTO:
        sums = _windowed_sums_at(envelope, at, config)
    else:
        sums = _windowed_sums(envelope, config)[at]  # hop j at sample first + j * hop
    pulse, total = sums[..., :-1], sums[..., -1].real  # [F, c, tempi], [F, c]
    salience = np.where(total[..., None] > 0, np.abs(pulse) / np.maximum(total[..., None], 1e-30), 0.0)
    angle = np.angle(pulse)
    if not config.saliences:
        values = np.zeros((*salience.shape[:2], 0))
    elif config.tempo_phases:
        values = np.stack([salience, salience * np.cos(angle), salience * np.sin(angle)], axis=-1)  # [F, c, K, 3]
        values = values.reshape(*values.shape[:2], -1)
    else:
        values = salience
    return values, salience, angle


@functools.lru_cache(maxsize=16)
def _level_tempi(config: RhythmConfig, beats_per_bar: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(the beat candidates' tempo indices [B], their log prior [B], [B, L] the index of the tempo
    nearest each candidate's tempo / m for each level m in beats (:meth:`RhythmConfig.beat_multiples`),
    [B] the index of the tempo nearest twice each candidate's, -1 where twice it lies above the grid
    by more than half a step)."""
    tempi = config.tempi_bpm
    log_tempi = np.log(tempi)
    lo, hi = config.beat_range_bpm or config.tempo_range_bpm
    candidates = np.flatnonzero((tempi >= lo * (1 - 1e-9)) & (tempi <= hi * (1 + 1e-9)))
    log_prior = -0.5 * np.log2(tempi[candidates] / 120.0) ** 2
    multiples = np.asarray(config.beat_multiples(beats_per_bar), np.float64)
    wanted = tempi[candidates][:, None] / multiples[None, :]
    nearest = np.abs(log_tempi[None, None, :] - np.log(wanted)[..., None]).argmin(axis=-1)
    doubled = np.log(2 * tempi[candidates])
    double = np.abs(log_tempi[None, :] - doubled[:, None]).argmin(axis=-1)
    half_step = 0.5 * (log_tempi[-1] - log_tempi[0]) / max(config.n_tempi - 1, 1)
    double[doubled > log_tempi[-1] + half_step] = -1
    return candidates, log_prior, nearest, double


def _beat_candidate(salience: np.ndarray, config: RhythmConfig, count: PulseCount | None = None) -> np.ndarray:
    """[...] the beat's index into :func:`_level_tempi`'s candidates (see :func:`predominant_beat`);
    with ``config.beat_hold``, ``salience`` is [F, K] of consecutive frames and ``count`` (advanced
    here; None: a fresh one) holds the beat from the frame before."""
    candidates, log_prior, _, double = _level_tempi(config)
    support = salience[..., candidates]
    if config.harmonic_weight > 0:
        support = support + config.harmonic_weight * np.where(double >= 0, salience[..., double], 0.0)
    score = support * np.exp(log_prior)
    best = score.argmax(axis=-1)
    if config.beat_hold == 0 or best.size == 0:
        return best
    if best.ndim != 1:
        shape = tuple(salience.shape)
        raise ConfigError(f"rhythm features: a held beat is picked over consecutive frames [F, n_tempi], not {shape}")
    count = PulseCount() if count is None else count
    held = int(best[0]) if count.beat is None else count.beat
    keep = 1.0 + config.beat_hold
    for frame, (top, row) in enumerate(zip(best, score)):  # sequential: each frame holds the one before's
        if row[top] > keep * row[held]:
            held = int(top)
        best[frame] = held
    count.beat = held
    return best


def predominant_beat(salience: np.ndarray, config: RhythmConfig) -> np.ndarray:
    """The beat's tempo index (into ``config.tempi_bpm``) [...] from the saliences [..., n_tempi] of
    every tempo: among ``beat_range_bpm``, the greatest salience (plus ``harmonic_weight`` x the
    salience at twice the tempo) times the log-normal prior (module docstring, step 4); with
    ``beat_hold``, of consecutive frames [F, n_tempi], each frame's beat held from the one before."""
    return _level_tempi(config)[0][_beat_candidate(salience, config)]


def _level_values(
    salience: np.ndarray, angle: np.ndarray, best: np.ndarray, config: RhythmConfig, beats_per_bar: int
) -> np.ndarray:
    """[F, 2 L] the predominant pulse's phasor at each metrical level (module docstring, step 4)
    from the saliences and phases [F, K] of every tempo and the beat [F] (:func:`_beat_candidate`)."""
    candidates, _, nearest, _ = _level_tempi(config, beats_per_bar)
    amplitude = _clock_amplitude(np.take_along_axis(salience, candidates[best][:, None], axis=-1), config)
    phase = np.take_along_axis(angle, nearest[best], axis=-1)  # [F, levels]: at the tempo of each level
    out = np.stack([amplitude * np.cos(phase), amplitude * np.sin(phase)], axis=-1)  # [F, levels, 2]
    return out.reshape(out.shape[0], -1)


def _clock_amplitude(beat_salience: np.ndarray, config: RhythmConfig) -> np.ndarray:
    """The levels' amplitude from the beat's salience [...]: itself, or 1 where it is above 0 with
    ``config.unit_levels``."""
    return (beat_salience > 0).astype(beat_salience.dtype) if config.unit_levels else beat_salience


@dataclass
class PulseCount:
    """Where the counted levels' count stands after the frames given so far (module docstring, step 5):
    a stream of calls to :func:`rhythm_features` that passes one on counts across them as one call
    over every frame would.

    Attributes:
        angles: [n_tempi] every tempo's phase at the last frame, radians (None before the first frame).
        phase: the beat's phase summed since the first frame, radians.
        beat: the beat held at the last frame (``beat_hold``), an index into the beat's candidate
            tempi (None before the first frame).
        spectra: the onset spectra already computed (:class:`OnsetSpectra`), for a stream of calls a
            frame or two apart (live), whose pieces of audio overlap by seconds; None: none kept.
    """

    angles: np.ndarray | None = None
    phase: float = 0.0
    beat: int | None = None
    spectra: OnsetSpectra | None = None


class OnsetSpectra:
    """The log-mel spectra of onset windows a stream of calls has computed, by where each window ends
    in the stream (``origin``: the stream's sample index of the ``samples`` passed in, which
    :class:`~kinectdata.features.streaming.StreamingFeatures` sets before each call). Only windows
    that lie wholly in the stream's audio are kept and reused, so the output is what it would be
    without them. A pulse frame reads seconds of onsets; one frame later all but a few are the same.
    Kept per hop grid (each phase of the hop; the ``phases`` used last), at least the ``keep`` most
    recent hops of each; a call that reads more than ``keep`` hops keeps nothing."""

    def __init__(self, keep: int = 4096, phases: int = 8):
        self.origin = 0
        self.keep, self.phases = keep, phases
        self.grids: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}  # phase: (first hop, rows, known)

    def spectra(self, windows_of, ends: np.ndarray, reusable: np.ndarray, hop: int, compute) -> np.ndarray:
        """[H, n_mels] the spectra of H windows ending at stream samples ``ends`` [H] (``hop``
        apart): ``windows_of(rows)`` gives the windows [M, frame] of ``rows`` [M] (only those computed
        are read); ``reusable`` [H]: the windows wholly in the stream's audio; ``compute``
        ([M, frame] -> [M, n_mels]) called once for the others and those not kept yet."""
        if ends.size == 0 or ends.size > self.keep:
            return compute(windows_of(np.arange(ends.size)))
        phase, number = int(ends[0] % hop), ends // hop
        grid = self.grids.pop(phase, None)  # put back last: the phases are kept in the order used
        first, rows, known = grid if grid is not None else (int(number[0]), None, None)
        at = number - first
        old = np.zeros(ends.size, bool) if known is None or at[0] < 0 else known[np.minimum(at, known.size - 1)]
        old &= reusable & (at < (0 if known is None else known.size))
        fresh = np.flatnonzero(~old)
        computed = compute(windows_of(fresh)) if fresh.size else None
        width = computed.shape[1] if computed is not None else rows.shape[1]
        first, rows, known = self._moved_on(first, rows, known, int(number[0]), int(number[-1]), width)
        at = number - first
        out = np.empty((ends.size, width))
        out[old] = rows[at[old]]
        if computed is not None:
            out[fresh] = computed
            keep = reusable[fresh]
            rows[at[fresh[keep]]], known[at[fresh[keep]]] = computed[keep], True
        self.grids[phase] = (first, rows, known)
        while len(self.grids) > self.phases:
            del self.grids[next(iter(self.grids))]
        return out

    def _moved_on(self, first: int, rows, known, lo: int, hi: int, width: int):
        """A grid of ``2 keep`` hops that holds hops ``lo``..``hi``: the one given, its rows moved
        down (the oldest let go) when ``hi`` runs past its end, or a new one."""
        size = 2 * self.keep
        if rows is None or rows.shape[1] != width or lo < first:
            return lo, np.zeros((size, width)), np.zeros(size, bool)
        if hi >= first + size:
            shift = hi - self.keep + 1 - first
            if shift < size:
                rows[: size - shift], known[: size - shift] = rows[shift:].copy(), known[shift:].copy()
            known[max(size - shift, 0) :] = False
            first += shift
        return first, rows, known


def _counted_levels(
    salience: np.ndarray, angle: np.ndarray, best: np.ndarray, config: RhythmConfig, beats_per_bar: int,
    count: PulseCount,
) -> np.ndarray:  # fmt: skip
    """[F, L, 2] every level's phasor from the beat's counted phase, from the saliences and phases
    [F, K] of consecutive frames and their beat [F] (:func:`_beat_candidate`); advances ``count``."""
    candidates, _, _, _ = _level_tempi(config, beats_per_bar)
    beat = candidates[best]  # [F] the beat's tempo index per frame
    rows = np.arange(beat.size)
    now = angle[rows, beat]
    before = np.concatenate([angle[:1] if count.angles is None else count.angles[None], angle[:-1]])[rows, beat]
    turn = np.maximum(np.angle(np.exp(1j * (now - before))), 0.0)  # at the frame's own tempo; never back
    start = float(now[0]) if count.angles is None else count.phase
    phase = start + np.cumsum(turn)
    count.angles, count.phase = angle[-1].copy(), float(phase[-1])
    strength = _clock_amplitude(salience[rows, beat][:, None], config)  # [F, 1]
    multiples = np.asarray(config.beat_multiples(beats_per_bar), np.float64)
    counted = phase[:, None] / multiples[None, :]  # [F, L]
    return np.stack([strength * np.cos(counted), strength * np.sin(counted)], axis=-1)


def rhythm_features(
    samples: np.ndarray,
    starts: np.ndarray,
    config: RhythmConfig,
    *,
    chunk_frames: int = 1024,
    beats_per_bar: int | None = None,
    state: PulseCount | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame pulse features of mono audio (module docstring).

    Args:
        samples: [S] mono float audio.
        starts: [N] int64 slice starts (may run off either end of the audio: samples there are zeros).
        config: the :class:`RhythmConfig`.
        chunk_frames: frames computed at once (bounds the memory).
        beats_per_bar: the song's metre, for ``config.bar_levels`` (None: :data:`DEFAULT_BEATS_PER_BAR`).
        state: with ``config.counted_levels``, the count so far of a stream of calls (advanced here;
            None: counted from this call's first frame); its ``spectra``, when kept, are reused.

    Returns:
        ``(features float32 [N, *config.output_shape], padded bool [N])``; padded where a frame's own
        slice runs off the audio.
    """
    metre = DEFAULT_BEATS_PER_BAR if beats_per_bar is None else int(beats_per_bar)
    if metre < 1:
        raise ConfigError(f"rhythm features: beats_per_bar must be at least 1, got {beats_per_bar!r}")
    if config.follows_earlier_frames and state is None:
        state = PulseCount()
    x = np.asarray(samples, np.float32)
    starts = np.asarray(starts, np.int64)
    n = starts.size
    out = np.zeros((n, *config.output_shape), np.float32)
    padded = (starts < 0) | (starts + config.slice_samples > x.size)
    if n == 0:
        return out, padded
    hop, last_instant = config.hop_samples, int(config.instants[-1])
    for c0 in range(0, n, chunk_frames):
        block = starts[c0 : c0 + chunk_frames]
        # Each frame's onsets are taken on a hop grid through its last instant, so that its values
        # depend on its own samples only, not on where the audio passed in begins (streamed audio
        # arrives in a buffer that starts anywhere): one onset envelope per phase of that grid.
        phase = (block + last_instant) % hop
        n_levels = len(config.beat_multiples(metre))
        values = np.empty((block.size, config.instants.size, config.values_per_instant - 2 * n_levels))
        salience = np.empty((block.size, config.instants.size, config.n_tempi))
        angle = np.empty_like(salience)
        for p in np.unique(phase):
            rows = np.flatnonzero(phase == p)
            values[rows], salience[rows], angle[rows] = _pulse_values(
                x, block[rows], int(p), config, None if state is None else state.spectra
            )
        if n_levels:  # levels have the vector layout: one instant per frame
            best = _beat_candidate(salience[:, 0], config, state)  # in time order, for a held beat
            levels = _level_values(salience[:, 0], angle[:, 0], best, config, metre).reshape(block.size, n_levels, 2)
            if config.counted_levels:  # above the beat (the beat keeps its own phase)
                above = np.asarray(config.beat_multiples(metre)) > 1
                levels[:, above] = _counted_levels(salience[:, 0], angle[:, 0], best, config, metre, state)[:, above]
            values = np.concatenate([values, levels.reshape(block.size, 1, -1)], axis=-1)
        if config.columns:
            out[c0 : c0 + block.size, 0] = np.transpose(values, (0, 2, 1))
        elif config.planes:
            out[c0 : c0 + block.size] = values[:, 0, :, None, None]
        else:
            out[c0 : c0 + block.size] = values[:, 0]
    return out, padded
