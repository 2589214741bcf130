"""Log-mel features: the filterbank against librosa's, each frame against a per-frame computation
done another way, levels with known answers, and streaming equal to the whole audio."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import get_window

from kinectdata.features import PRESETS, MelConfig, compute_features, feature_config, mel_features
from kinectdata.features.mel import mel_filterbank
from kinectdata.features.streaming import StreamingFeatures

librosa = pytest.importorskip("librosa")
CONFIG = PRESETS["listen_to_dance"]


@pytest.mark.parametrize("sr, n_fft, n_mels, fmin, fmax", [(16000, 1024, 80, 0, 8000), (22050, 2048, 40, 30, 9000)])
def test_filterbank_is_librosa_slaney_scale_without_area_norm(sr, n_fft, n_mels, fmin, fmax):
    ours = mel_filterbank(sr, n_fft, n_mels, fmin, fmax)
    theirs = librosa.filters.mel(sr=sr, n_fft=n_fft, n_mels=n_mels, fmin=fmin, fmax=fmax, htk=False, norm=None)
    np.testing.assert_allclose(ours, theirs, atol=1e-6)


def reference_frame(audio: np.ndarray, start: int) -> np.ndarray:
    """One frame the slow way: a padded copy, a Hann window from scipy, librosa's filterbank."""
    centre = start + 267
    padded = np.concatenate([np.zeros(2048), audio.astype(np.float64), np.zeros(2048)])
    seg = padded[2048 + centre - 512 : 2048 + centre + 512]
    w = get_window("hann", 1024, fftbins=True)
    mag = np.abs(np.fft.rfft(seg * w)) * 2 / w.sum()
    bank = librosa.filters.mel(sr=16000, n_fft=1024, n_mels=80, fmin=0, fmax=8000, htk=False, norm=None)
    db = 10 * np.log10(np.maximum(bank @ mag**2, 1e-8))
    return np.clip((db + 80) / 100, 0, 1)


def test_frames_match_a_per_frame_reference_including_the_padded_ends():
    rng = np.random.default_rng(0)
    audio = (0.3 * np.sin(2 * np.pi * 440 * np.arange(24000) / 16000) + rng.normal(0, 0.05, 24000)).astype(np.float32)
    starts = np.round(np.arange(46) * 16000 / 30).astype(np.int64)  # the last windows run past the end
    feats, padded = mel_features(audio, starts, CONFIG, chunk_frames=7)
    assert feats.shape == (46, 80) and feats.dtype == np.float32
    for k in range(46):
        np.testing.assert_allclose(feats[k], reference_frame(audio, int(starts[k])), atol=2e-6)
    expected_padded = (starts - 245 < 0) | (starts + 779 > audio.size)
    np.testing.assert_array_equal(padded, expected_padded)
    assert padded[0] and not padded[1:-2].any() and padded[-1]


def test_levels_full_scale_sine_on_a_bin_and_silence_at_the_floor():
    """A full-scale sine exactly on bin b: the periodic Hann window gives scaled magnitudes 1 at b and
    1/2 at b +- 1 (0 elsewhere), so each band's energy is known from the filter weights alone."""
    bank = mel_filterbank(16000, 1024, 80, 0, 8000)
    b = 100  # 1562.5 Hz
    sine = np.sin(2 * np.pi * b * 16000 / 1024 * np.arange(16000) / 16000)
    feats, _ = compute_features(sine, np.array([4000, 8000]), CONFIG)
    energy = bank[:, b] + 0.25 * (bank[:, b - 1] + bank[:, b + 1])
    expected = np.clip((10 * np.log10(np.maximum(energy, 1e-8)) + 80) / 100, 0, 1)
    np.testing.assert_allclose(feats, np.stack([expected, expected]), atol=1e-6)
    assert 0.75 < feats.max() <= 0.8 + 1e-6  # the band centred nearest the sine: about 0 dB
    silent, _ = compute_features(np.zeros(16000), np.array([4000, 8000]), CONFIG)
    assert (silent == 0).all()


def test_config_round_trip_and_dispatch():
    d = json.loads(json.dumps(CONFIG.to_dict()))
    assert d["extractor"] == "mel" and feature_config(d) == CONFIG
    assert feature_config(PRESETS["yalta2016"].to_dict()) == PRESETS["yalta2016"]
    assert MelConfig().span == (-245, 779) and MelConfig().output_shape == (80,)
    with pytest.raises(ValueError, match="unknown MelConfig keys"):
        MelConfig.from_dict({**d, "hop": 3})
    with pytest.raises(ValueError, match="fmax"):
        MelConfig(fmax=9000)
    with pytest.raises(ValueError, match="unknown feature extractor"):
        feature_config({"extractor": "cqt"})


@pytest.mark.parametrize("block", [1, 300, 16000])
def test_streaming_mel_equals_the_whole_audio(block):
    rng = np.random.default_rng(block)
    audio = rng.normal(0, 0.2, 16000 + 77).astype(np.float32)
    starts = np.round(np.arange(31) * 16000 / 30).astype(np.int64)
    expected, expected_padded = mel_features(audio, starts, CONFIG)
    got, padded = np.full_like(expected, np.nan), np.zeros(31, bool)

    def sink(k0, feats, pad):
        got[k0 : k0 + len(feats)], padded[k0 : k0 + len(feats)] = feats, pad

    stream = StreamingFeatures(starts, CONFIG, sink)
    for i in range(0, audio.size, block):
        stream.push(audio[i : i + block])
        assert stream.buffer.size <= block + 1024 + 534
    stream.finish()
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(padded, expected_padded)
