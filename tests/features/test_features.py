"""STFT features (kinectdata.features): against an independent per-slice reference, silence,
ranges, chunk and segment independence, config and registry."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal

import kinectdata.features as features_pkg
from kinectdata.features import StftConfig, extractor_names, get_extractor, register_extractor, stft_features
from kinectdata.features.stft import PRESETS

SR = 16000
SLICE = 534
LO, HI = np.float32(0.1), np.float32(0.9)


# ---------------------------------------------------------------- reference, written independently


def reference(samples, starts, config: StftConfig) -> np.ndarray:
    """Per-slice float64 reference [N, 1, n_bins, n_frames]: plain indexing, scipy.signal.stft on
    each slice, each column normalised here with the formulas of the spec."""
    x = [float(v) for v in samples]
    out = []
    for start in (int(s) for s in starts):
        seg = np.array([x[i] if 0 <= i < len(x) else 0.0 for i in range(start, start + config.slice_samples)])
        _, _, z = signal.stft(
            seg,
            fs=config.sample_rate,
            window=config.window,
            nperseg=config.frame_samples,
            noverlap=config.frame_samples - config.hop_samples,
            nfft=config.n_fft,
            detrend=False,
            return_onesided=True,
            boundary=None,
            padded=False,
            scaling="spectrum",  # X / sum(window)
        )
        z = z[:, : config.n_frames]
        assert z.shape == (config.n_bins, config.n_frames)
        cols = []
        lo, hi = config.out_range
        for j in range(config.n_frames):
            a = np.abs(z[:, j])  # |X| / sum(window)
            if config.normalisation == "fixed_db":
                a = a.copy()
                a[1 : config.n_fft // 2] *= 2  # one-sided doubling, not DC nor Nyquist
                db = 20 * np.log10(a + config.amin)
                d0, d1 = config.db_range
                cols.append(lo + (hi - lo) * (db - d0) / (d1 - d0))
                continue
            frame = seg[j * config.hop_samples : j * config.hop_samples + config.frame_samples]
            power = a**2
            with np.errstate(divide="ignore"):
                level_db = 10 * np.log10(np.mean(frame**2))
                v = 10 * np.log10(power) if config.power == "log" else power
            if config.power == "log":
                v = np.maximum(v, v.max() - config.top_db)
            flat = power.min() >= power.max() * (1 - 1e-9)
            if flat or (config.silence_db is not None and level_db < config.silence_db):
                cols.append(np.full(config.n_bins, lo))
            else:
                cols.append(lo + (hi - lo) * (v - v.min()) / (v.max() - v.min()))
        out.append(np.stack(cols, axis=1))
    return np.array(out)[:, None]


def music_like(seconds: float, seed: int = 0) -> np.ndarray:
    """float32 mono: notes with harmonics and decays, noise-burst drums, a faint noise floor."""
    rng = np.random.default_rng(seed)
    n = int(seconds * SR)
    t = np.arange(n) / SR
    x = rng.normal(0, 10 ** (-70 / 20), n)
    note = int(0.125 * SR)
    for k in range(0, n, note):
        f0 = 110 * 2 ** (rng.integers(0, 36) / 12)
        tt = t[k : k + note] - t[k]
        env = np.exp(-tt / rng.uniform(0.03, 0.3)) * rng.uniform(0.05, 0.3)
        for h in range(1, 6):
            if f0 * h < SR / 2:
                x[k : k + note] += env / h * np.sin(2 * np.pi * f0 * h * tt + rng.uniform(0, 2 * np.pi))
        if rng.random() < 0.5:  # a drum hit: decaying noise
            x[k : k + note] += rng.normal(0, 1, tt.size) * np.exp(-tt / 0.02) * rng.uniform(0.05, 0.4)
    return (0.9 * x / np.abs(x).max()).astype(np.float32)


def frame_starts(n_samples: int, fps: float = 30.0) -> np.ndarray:
    return np.round(np.arange(int(n_samples / SR * fps)) * SR / fps).astype(np.int64)


@pytest.fixture(scope="module")
def song() -> np.ndarray:
    return music_like(2.0, seed=3)


ALL_CONFIGS = {
    "yalta2016": PRESETS["yalta2016"],
    "linear": StftConfig(power="linear"),
    "motion_dance": PRESETS["motion_dance"],
}
MINMAX_CONFIGS = {k: v for k, v in ALL_CONFIGS.items() if v.normalisation == "frame_minmax"}


# ---------------------------------------------------------------- against the reference


@pytest.mark.parametrize("name", ALL_CONFIGS)
def test_matches_reference_on_music(song, name):
    config = ALL_CONFIGS[name]
    starts = frame_starts(song.size)[::3]
    feats, padded = stft_features(song, starts, config)
    ref = reference(song, starts, config)
    assert feats.dtype == np.float32 and feats.shape == (len(starts), 1, 129, 5)
    assert np.abs(feats - ref).max() < 1e-6  # float64 inside: the float32 rounding is all that differs
    assert not padded.any()


@pytest.mark.parametrize("name", ALL_CONFIGS)
def test_matches_reference_off_both_ends(song, name):
    config = ALL_CONFIGS[name]
    x = song[:4000].astype(np.float64)  # float64 input too
    s = x.size
    starts = np.array(
        [-2000, -600, -479, -300, -1, 0, 1, s - 534, s - 533, s - 480, s - 479, s - 100, s - 1, s, s + 10]
    )
    feats, padded = stft_features(x, starts, config)
    assert np.abs(feats - reference(x, starts, config)).max() < 1e-6
    expected = [True] * 5 + [False, False, False] + [True] * 7
    assert padded.tolist() == expected
    if config.normalisation == "frame_minmax":
        assert np.all(feats[[0, 1, -2, -1]] == LO)  # nothing of the audio in the used 480 samples


@pytest.mark.parametrize("freq,bin_", [(1000.0, 16), (437.5, 7), (3000.0, 48), (7500.0, 120)])
@pytest.mark.parametrize("name", ALL_CONFIGS)
def test_pure_tone_peaks_at_its_bin(name, freq, bin_):
    config = ALL_CONFIGS[name]
    assert config.bin_hz == 62.5 and freq / config.bin_hz == bin_
    x = (0.5 * np.sin(2 * np.pi * freq * np.arange(SR // 2) / SR)).astype(np.float32)
    starts = frame_starts(x.size)[:-1]
    feats, _ = stft_features(x, starts, config)
    assert np.all(np.argmax(feats[:, 0], axis=1) == bin_)
    if config.normalisation == "frame_minmax":
        assert np.all(feats[:, 0, bin_, :] == HI)
    else:  # |X| / sum(w) * 2 = the amplitude, 0.5 at a bin centre: -6.02 dB (+- the image's leakage)
        expected = -0.9 + 1.8 * (20 * np.log10(0.5) + 120) / 125
        np.testing.assert_allclose(feats[:, 0, bin_, :], expected, atol=1e-3)
    assert np.abs(feats[:4] - reference(x, starts[:4], config)).max() < 1e-6


def test_motion_dance_doubling_and_range():
    config = PRESETS["motion_dance"]
    x = np.zeros(2000, np.float32)
    feats, _ = stft_features(x, np.array([0, 500]), config)
    np.testing.assert_allclose(feats, -0.9, atol=1e-7)  # |X| = 0: the amin floor, -120 dB
    # White noise: bins 1..127 doubled (+6.02 dB), DC and Nyquist not; compare to the reference directly.
    rng = np.random.default_rng(5)
    noise = rng.uniform(-1, 1, 40000).astype(np.float32)
    starts = np.arange(0, 39000, 533)
    feats, _ = stft_features(noise, starts, config)
    assert np.abs(feats[:10] - reference(noise, starts[:10], config)).max() < 1e-6
    # Audio within +-1: |X| <= sum(window), so at most 20*log10(2) dB on bins 1..127.
    square = np.sign(np.sin(2 * np.pi * 250 * np.arange(8000) / SR)).astype(np.float32)
    for x in (noise, square, np.ones(4000, np.float32), -np.ones(4000, np.float32)):
        f, _ = stft_features(x, np.arange(0, x.size - 534, 97), config)
        assert f.min() >= np.float32(-0.9) - 1e-6 and f.max() <= -0.9 + 1.8 * (20 * np.log10(2) + 120) / 125 + 1e-6
        assert np.all(f[:, 0, [0, 128]] <= -0.9 + 1.8 * 120 / 125 + 1e-6)  # 0 dB at most at DC / Nyquist


# ---------------------------------------------------------------- silence


def _noise(n: int, dbfs: float, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).normal(0, 10 ** (dbfs / 20), n)


@pytest.mark.parametrize("name", MINMAX_CONFIGS)
def test_silent_slices_are_identical_constant_columns(name):
    config = MINMAX_CONFIGS[name]
    n = SLICE
    impulse = np.zeros(n)
    impulse[[100, 260, 420]] = [0.9, -0.7, 0.3]  # exactly one non-zero sample per STFT frame: flat spectra
    pieces = {
        "zeros": np.zeros(n),
        "noise -80 dBFS": _noise(n, -80, 1),
        "noise -65 dBFS": _noise(n, -65, 2),
        "DC 5e-4 (-66 dBFS)": np.full(n, 5e-4),
        "negative DC": np.full(n, -2e-4),
        "denormals": np.full(n, 1e-40),
        "impulses": impulse,
    }
    x = np.concatenate(list(pieces.values())).astype(np.float32)
    starts = np.arange(len(pieces)) * n
    feats, padded = stft_features(x, starts, config)
    assert not padded.any()
    assert np.all(feats == LO), {k: bool(np.all(f == LO)) for k, f in zip(pieces, feats)}
    assert np.abs(feats - reference(x, starts, config)).max() < 1e-6


@pytest.mark.parametrize("name", MINMAX_CONFIGS)
def test_quiet_but_not_silent(name):
    config = MINMAX_CONFIGS[name]
    x = _noise(SLICE, -40, 3).astype(np.float32)
    feats, _ = stft_features(x, np.array([0]), config)
    assert np.all(feats.max(axis=2) == HI) and np.all(feats.min(axis=2) == LO)
    assert np.abs(feats - reference(x, [0], config)).max() < 1e-6
    # A loud DC offset is sound under the mean-square rule (the module docs say so).
    dc, _ = stft_features(np.full(SLICE, 0.1, np.float32), np.array([0]), config)
    assert np.all(dc.max(axis=2) == HI)


@pytest.mark.parametrize("name", MINMAX_CONFIGS)
def test_silence_only_in_the_silent_stft_frame(name):
    config = MINMAX_CONFIGS[name]
    x = np.concatenate([np.zeros(160), _noise(SLICE - 160, -20, 4)]).astype(np.float32)
    feats, _ = stft_features(x, np.array([0]), config)
    cols = feats[0, 0]
    assert np.all(cols[:, 0] == LO)
    assert np.all(cols[:, 1:].max(axis=0) == HI) and np.all(cols[:, 1:].min(axis=0) == LO)
    assert np.abs(feats - reference(x, [0], config)).max() < 1e-6


@pytest.mark.parametrize("name", ALL_CONFIGS)
def test_no_nan_or_inf_on_extreme_input(name):
    config = ALL_CONFIGS[name]
    t = np.arange(8000) / SR
    cases = {
        "clipped": np.clip(4 * np.sin(2 * np.pi * 220 * t), -1, 1),
        "full-scale Nyquist": np.where(np.arange(8000) % 2 == 0, 1.0, -1.0),
        "full-scale DC": np.ones(8000),
        "huge float32": np.random.default_rng(6).normal(0, 1e37, 8000).clip(-3e38, 3e38),
        "denormal noise": np.random.default_rng(7).normal(0, 1e-41, 8000),
        "loud with denormals": np.where(np.arange(8000) < 4000, np.sin(2 * np.pi * 300 * t), 1e-42),
    }
    for label, x in cases.items():
        x = x.astype(np.float32)
        starts = np.arange(-300, x.size, 211)
        feats, _ = stft_features(x, starts, config)
        assert np.all(np.isfinite(feats)), label
        if config.normalisation == "frame_minmax":
            assert feats.min() >= LO and feats.max() <= HI, label
        if label != "huge float32":
            assert np.abs(feats[:8] - reference(x, starts[:8], config)).max() < 1e-6, label


def test_invalid_samples_raise():
    starts = np.array([0])
    for bad in (np.array([0.0, np.nan] * 300), np.array([0.0, np.inf] * 300), np.full(600, 1e200)):
        with pytest.raises(ValueError, match="finite"):
            stft_features(bad, starts)
    with pytest.raises(TypeError):
        stft_features(np.zeros(600, np.int16), starts)
    with pytest.raises(TypeError):
        stft_features(np.zeros(600), np.array([0.5]))
    with pytest.raises(ValueError):
        stft_features(np.zeros((600, 2)), starts)
    with pytest.raises(ValueError):
        stft_features(np.zeros(600), starts, chunk_frames=0)


# ---------------------------------------------------------------- ranges


@pytest.mark.parametrize("name", MINMAX_CONFIGS)
def test_range_and_exact_extremes(song, name):
    config = MINMAX_CONFIGS[name]
    x = song.copy()
    x[8000:12000] = 0  # a silent stretch
    feats, _ = stft_features(x, frame_starts(x.size), config)
    assert feats.min() >= LO and feats.max() <= HI
    cols = feats[:, 0].transpose(0, 2, 1).reshape(-1, 129)
    silent = np.all(cols == LO, axis=1)
    assert 0 < silent.sum() < len(cols)
    assert np.all(cols[~silent].max(axis=1) == HI) and np.all(cols[~silent].min(axis=1) == LO)


def test_log_spreads_values_linear_does_not(song):
    """Why log is the default: min-max of linear power leaves nearly every bin at the floor."""
    starts = frame_starts(song.size)
    log, _ = stft_features(song, starts, PRESETS["yalta2016"])
    lin, _ = stft_features(song, starts, StftConfig(power="linear"))
    assert np.median(lin) < 0.101 and np.median(log) > 0.3


# ---------------------------------------------------------------- chunk and segment independence


@pytest.mark.parametrize("name", ALL_CONFIGS)
def test_chunk_size_does_not_change_bits(song, name):
    config = ALL_CONFIGS[name]
    starts = np.concatenate([[-700, -100], frame_starts(song.size), [song.size - 200, song.size + 5]])
    results = [stft_features(song, starts, config, chunk_frames=c) for c in (1, 7, 4096)]
    for feats, padded in results[1:]:
        assert np.array_equal(feats, results[0][0]) and np.array_equal(padded, results[0][1])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("name", ALL_CONFIGS)
def test_segments_give_the_same_bits_as_the_whole(song, name, dtype):
    config = ALL_CONFIGS[name]
    x = song.astype(dtype)
    starts = frame_starts(x.size)
    whole, _ = stft_features(x, starts, config)
    # Two overlapping segments, cut at odd places (so differently aligned in memory).
    cuts = [(0, 20001), (13337, x.size)]
    for a, b in cuts:
        inside = (starts >= a) & (starts + SLICE <= b)
        part, padded = stft_features(x[a:b], starts[inside] - a, config, chunk_frames=5)
        assert inside.sum() > 10 and not padded.any()
        assert np.array_equal(part, whole[inside])
    # A slice whose unused tail (the last 54 samples) runs off the end: padded, same features.
    s = x.size
    tail, padded = stft_features(x[: s - 30], np.array([s - 30 - 500]), config)
    assert padded.tolist() == [True]
    assert np.array_equal(tail[0], stft_features(x, np.array([s - 30 - 500]), config)[0][0])


def test_non_contiguous_input(song):
    feats, _ = stft_features(song[::2], np.array([0, 1000]))
    assert np.array_equal(feats, stft_features(np.ascontiguousarray(song[::2]), np.array([0, 1000]))[0])


# ---------------------------------------------------------------- shapes, config, registry


def test_shapes_and_dtypes():
    feats, padded = stft_features(np.zeros(1000, np.float32), np.zeros(0, np.int64))
    assert feats.shape == (0, 1, 129, 5) and feats.dtype == np.float32
    assert padded.shape == (0,) and padded.dtype == bool
    feats, padded = stft_features(np.zeros(0), np.array([0, 5]))  # no audio at all
    assert np.all(feats == LO) and padded.all()
    feats, padded = stft_features(np.zeros(100), np.array([0]), PRESETS["motion_dance"])  # shorter than a frame
    assert feats.shape == (1, 1, 129, 5) and padded.all()
    assert StftConfig().output_shape == (1, 129, 5) == PRESETS["motion_dance"].output_shape
    custom = StftConfig(n_fft=512, n_frames=3, hop_samples=160, frame_samples=160)
    assert custom.output_shape == (1, 257, 3) and custom.used_samples == 480
    f, _ = stft_features(np.random.default_rng(0).normal(0, 0.1, 3000), np.array([0, 1000]), custom)
    assert f.shape == (2, 1, 257, 3)
    assert np.abs(f - reference(np.random.default_rng(0).normal(0, 0.1, 3000), [0, 1000], custom)).max() < 1e-6


@pytest.mark.parametrize("name", PRESETS)
def test_config_dict_round_trip(name):
    config = PRESETS[name]
    d = config.to_dict()
    text = json.dumps(d)
    back = StftConfig.from_dict(json.loads(text))
    assert back == config and back.to_dict() == d and hash(back) == hash(config)
    assert StftConfig.from_dict({}) == StftConfig()
    with pytest.raises(ValueError, match="unknown"):
        StftConfig.from_dict({**d, "hop": 1})


def test_config_validation():
    for kw in (
        {"power": "db"},
        {"normalisation": "global"},
        {"normalisation": "fixed_db", "power": "linear"},
        {"n_frames": 6},  # 6 frames need 560 samples > 534
        {"n_fft": 128},
        {"top_db": 0.0},
        {"top_db": None},
        {"out_range": (0.9, 0.1)},
        {"hop_samples": 0},
    ):
        with pytest.raises(ValueError):
            StftConfig(**kw)
    # a window name is checked when the window is first built (not at import, which would load scipy.signal)
    with pytest.raises(ValueError, match="no-such-window"):
        stft_features(np.zeros(1000), np.array([0]), StftConfig(window="no-such-window"))
    assert StftConfig(top_db=80) == StftConfig()  # numbers are normalised to float


def test_registry():
    assert "stft" in extractor_names()
    assert get_extractor("stft") is stft_features
    with pytest.raises(KeyError, match="stft"):
        get_extractor("no-such-extractor")
    name = "test-dummy-extractor"
    try:

        @register_extractor(name)
        def dummy(samples, starts, config=None, *, chunk_frames=1):
            return None

        assert get_extractor(name) is dummy and name in extractor_names()
        register_extractor(name, dummy)  # the same callable again: fine
        with pytest.raises(ValueError, match="already"):
            register_extractor(name, lambda *a: None)
        register_extractor(name, stft_features, replace=True)
        assert get_extractor(name) is stft_features
    finally:
        features_pkg._EXTRACTORS.pop(name, None)
    assert name not in extractor_names()


def test_windows_computed_here_equal_scipy():
    from scipy.signal import get_window

    from kinectdata.features.stft import _window

    for name in ("hamming", "hann", "blackman"):
        np.testing.assert_allclose(_window(name, 160), get_window(name, 160, fftbins=True), rtol=0, atol=1e-15)


@pytest.mark.parametrize("block", [1, 97, 534, 16000])
def test_streaming_features_equal_the_whole_audio_at_any_block_size(block):
    from kinectdata.features.streaming import StreamingFeatures

    rng = np.random.default_rng(block)
    audio = rng.normal(0, 0.2, 16000 * 2 + 123).astype(np.float32)
    starts = np.round(np.arange(61) * 16000 / 30).astype(np.int64)  # the last slices run past the end
    config = PRESETS["yalta2016"]
    expected, expected_padded = stft_features(audio, starts, config)
    got = np.full_like(expected, np.nan)
    padded = np.zeros(len(starts), bool)
    calls = []

    def sink(k0, feats, pad):
        calls.append(k0)
        got[k0 : k0 + len(feats)] = feats
        padded[k0 : k0 + len(feats)] = pad

    stream = StreamingFeatures(starts, config, sink)
    for i in range(0, audio.size, block):
        stream.push(audio[i : i + block])
        assert stream.buffer.size <= block + config.slice_samples + 16000 / 30  # bounded memory
    stream.finish()
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(padded, expected_padded)
    assert calls == sorted(calls) and (block > audio.size or len(calls) > 1)
