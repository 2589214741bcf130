"""Audio loading: formats, mono downmix, band-limited resampling, clear errors."""

from __future__ import annotations

import re

import numpy as np
import pytest
import soundfile as sf

from kinectdata.align.audio import load_audio
from kinectdata.core.errors import AudioError


def _tone(freq, sr, seconds, amp):
    t = np.arange(int(sr * seconds)) / sr
    return amp * np.sin(2 * np.pi * freq * t)


def _peak_frequency(x, sr):
    w = np.hanning(x.size)
    spec = np.abs(np.fft.rfft(x * w))
    k = int(np.argmax(spec))
    a, b, c = np.log(spec[k - 1 : k + 2])
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) * sr / x.size  # parabolic interpolation


@pytest.mark.parametrize("fmt,subtype", [("WAV", "FLOAT"), ("WAV", "PCM_24"), ("FLAC", "PCM_24"), ("OGG", "VORBIS")])
def test_tone_keeps_frequency_and_level(tmp_path, fmt, subtype):
    sr = 44100
    tone = _tone(997.0, sr, 3.0, 0.5)
    path = tmp_path / f"tone.{fmt.lower()}"
    sf.write(path, np.stack([tone, tone], axis=1), sr, format=fmt, subtype=subtype)
    audio = load_audio(path)
    assert audio.sample_rate == 16000 and audio.samples.dtype == np.float32 and audio.samples.ndim == 1
    assert audio.samples.size == pytest.approx(3.0 * 16000, abs=2)
    assert audio.source["sample_rate"] == sr and audio.source["channels"] == 2
    mid = audio.samples[4000:-4000].astype(np.float64)
    assert _peak_frequency(mid, 16000) == pytest.approx(997.0, abs=0.2)
    rms_db = 20 * np.log10(np.sqrt(np.mean(mid**2)) / (0.5 / np.sqrt(2)))
    assert abs(rms_db) < (0.3 if fmt == "OGG" else 0.02)


def test_content_above_the_new_nyquist_is_removed_not_aliased(tmp_path):
    sr = 44100
    path = tmp_path / "high.wav"
    sf.write(path, _tone(12000.0, sr, 2.0, 0.5), sr, subtype="FLOAT")  # would alias to 4 kHz
    out = load_audio(path).samples[2000:-2000].astype(np.float64)
    level_db = 20 * np.log10(np.sqrt(np.mean(out**2)) / (0.5 / np.sqrt(2)) + 1e-12)
    assert level_db < -80


def test_downmix_is_the_mean_of_the_channels(tmp_path):
    sr = 16000
    left, right = _tone(440, sr, 1.0, 0.4), _tone(660, sr, 1.0, 0.2)
    sf.write(tmp_path / "st.wav", np.stack([left, right], axis=1), sr, subtype="FLOAT")
    np.testing.assert_allclose(load_audio(tmp_path / "st.wav").samples, (left + right) / 2, atol=1e-6)
    sf.write(tmp_path / "anti.wav", np.stack([left, -left], axis=1), sr, subtype="FLOAT")
    assert np.abs(load_audio(tmp_path / "anti.wav").samples).max() < 1e-6


def test_unreadable_missing_empty_and_nan_audio(tmp_path):
    bad = tmp_path / "notaudio.wav"
    bad.write_text("this is not audio")
    with pytest.raises(AudioError, match=r"notaudio\.wav: cannot read audio"):
        load_audio(bad)
    with pytest.raises(AudioError, match=r"missing\.flac: no such audio file"):
        load_audio(tmp_path / "missing.flac")
    sf.write(tmp_path / "empty.wav", np.zeros((0, 1)), 16000)
    with pytest.raises(AudioError, match=r"empty\.wav: the audio file holds no samples"):
        load_audio(tmp_path / "empty.wav")
    x = np.zeros(1000, np.float32)
    x[500] = np.nan
    sf.write(tmp_path / "nan.wav", x, 16000, subtype="FLOAT")
    with pytest.raises(AudioError, match=r"nan\.wav: non-finite sample .* at sample 500"):
        load_audio(tmp_path / "nan.wav")


def test_streamed_blocks_equal_whole_file_resampling_for_any_block_size(tmp_path):
    from kinectdata.align.audio import AudioReader, resample, to_mono

    x = np.random.default_rng(0).normal(0, 0.2, (44100 * 7 + 77, 2)).astype(np.float32)
    sf.write(tmp_path / "n.flac", x, 44100, subtype="PCM_24")
    ref = resample(to_mono(sf.read(tmp_path / "n.flac", dtype="float32")[0]), 44100, 16000)
    for seconds in (0.37, 1.0, 10.0):
        reader = AudioReader(tmp_path / "n.flac", block_seconds=seconds)
        got = np.concatenate(list(reader.blocks()))
        assert np.array_equal(got, ref) and got.size == reader.n_samples


def test_resampled_length_is_soxr_rounding_half_up():
    import soxr

    from kinectdata.align.audio import resampled_length

    for n in (1, 15, 22, 29, 36, 1001, 44100 * 3 + 13):
        for a, b in ((44100, 16000), (48000, 16000), (11025, 16000), (22050, 16000)):
            assert resampled_length(n, a, b) == soxr.resample(np.zeros(n, np.float32), a, b).size


def test_envelopes_do_not_depend_on_the_block_size():
    from kinectdata.align.envelopes import audio_envelopes

    x = np.random.default_rng(1).normal(0, 0.1, 16000 * 9 + 321).astype(np.float32)
    whole = audio_envelopes([x], 16000)
    for size in (1000, 16000, 77777):
        parts = audio_envelopes([x[s : s + size] for s in range(0, x.size, size)], 16000)
        assert np.array_equal(parts.clap_energy, whole.clap_energy)
        assert np.array_equal(parts.onset, whole.onset)
        assert parts.mean_square == pytest.approx(whole.mean_square, rel=1e-12)
    assert whole.clap_energy.size == x.size // 80 and whole.onset.size == int(np.ceil(x.size / 160))


def _music(sr: int, seconds: float) -> np.ndarray:
    """A tone in noise: compresses to about the same number of bytes per second all through."""
    rng = np.random.default_rng(5)
    return (_tone(440, sr, seconds, 0.3) + rng.normal(0, 0.05, int(sr * seconds))).astype(np.float32)


@pytest.mark.parametrize("damage", ["zeroed", "truncated"])
def test_a_flac_damaged_5_s_in_names_the_sample_where_decoding_failed(tmp_path, damage):
    """The default 10 s decoding blocks start at sample 0: the place must be found inside the block."""
    sr, x = 16000, _music(16000, 12.0)
    good = tmp_path / "good.flac"
    sf.write(good, x, sr)
    data = bytearray(good.read_bytes())
    at = len(data) * 5 // 12  # about 5 s into the audio
    data = data[:at] if damage == "truncated" else data[:at] + bytes(4000) + data[at + 4000 :]
    bad = tmp_path / "bad.flac"
    bad.write_bytes(bytes(data))
    with pytest.raises(AudioError) as caught:
        load_audio(bad)
    message = str(caught.value)
    found = re.search(r"bad\.flac: cannot decode audio from sample (\d+) \((\d+\.\d{3}) s\) on", message)
    assert found, message
    sample, seconds = int(found.group(1)), float(found.group(2))
    assert 4.5 * sr < sample <= 5.0 * sr and seconds == pytest.approx(sample / sr, abs=5e-4)
    with sf.SoundFile(bad) as f:  # everything before the named sample decodes as written
        np.testing.assert_allclose(f.read(sample, dtype="float32"), x[:sample], atol=1e-4)


@pytest.mark.parametrize("n", [0, 1, 79, 80, 100, 700])
def test_envelopes_of_audio_shorter_than_a_frame_are_empty_or_its_few_frames(n):
    """Audio shorter than one 40 ms STFT frame (640 samples at 16 kHz) crashed the framer."""
    from scipy import signal

    from kinectdata.align.envelopes import audio_envelopes

    x = np.random.default_rng(2).normal(0, 0.1, n).astype(np.float32)
    whole = audio_envelopes([x], 16000)
    parts = audio_envelopes([x[s : s + 7] for s in range(0, n, 7)], 16000)
    # independent: the high-passed signal's mean square over whole 5 ms (80-sample) frames
    expected = np.zeros(0)
    if n:
        high = signal.sosfilt(signal.butter(4, 1000.0, btype="highpass", fs=16000, output="sos"), x.astype(float))
        expected = np.square(high[: n // 80 * 80].reshape(-1, 80)).mean(axis=1)
    for env in (whole, parts):
        np.testing.assert_allclose(env.clap_energy, expected, rtol=1e-6)
        assert env.onset.size == int(np.ceil(n / 160)) and env.duration == n / 16000
