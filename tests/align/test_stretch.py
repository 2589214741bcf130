"""A song played faster or slower with its pitch kept (kinectdata.align.stretch): through SoX (which
.ci/run installs) and through librosa, the beat comes back ``rate`` times as fast, the song ``1 /
rate`` as long and its tone at the same pitch, each checked against numbers worked out by hand."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from helpers import envelope_beat_s, pulsed_tone, skip_unless_installed

from kinectdata.align.stretch import available_stretcher, stretch_audio
from kinectdata.core.errors import AudioError, ConfigError

RATE = 16000


def pulses(bpm: float, seconds: float) -> np.ndarray:
    return pulsed_tone(bpm, seconds, RATE)


def beat_interval_s(x: np.ndarray) -> float:
    return envelope_beat_s(x, RATE, (0.2, 1.5))


def dominant_hz(x: np.ndarray) -> float:
    spectrum = np.abs(np.fft.rfft(x.astype(np.float64)))
    return float(np.fft.rfftfreq(x.size, 1 / RATE)[np.argmax(spectrum)])


@pytest.mark.parametrize("stretcher", ["sox", "librosa"])
@pytest.mark.parametrize("rate", [0.85, 1.18])
def test_the_beat_comes_back_rate_times_as_fast_at_the_same_pitch(stretcher, rate):
    if stretcher == "sox":
        skip_unless_installed(None if shutil.which("sox") else "no sox on the PATH", "SoX")
    else:
        pytest.importorskip("librosa")
    song = pulses(120.0, 12.0)
    made = stretch_audio(song, rate, RATE, stretcher)
    assert made.dtype == np.float32 and made.size == round(song.size / rate)
    # 0.5 s between beats at 120 BPM, 0.5 / rate after (the phase vocoder's swells come 2 % early or late;
    # the tempo unchanged would be 15-18 % off)
    assert beat_interval_s(song) == pytest.approx(0.5, abs=0.006)
    assert beat_interval_s(made) == pytest.approx(0.5 / rate, rel=0.03)
    assert dominant_hz(made) == pytest.approx(880.0, abs=3.0)  # the pitch kept


def test_rate_one_returns_a_copy_and_bad_rates_are_refused():
    song = pulses(100.0, 2.0)
    same = stretch_audio(song, 1.0, RATE, "sox")  # no program runs at x1
    assert np.array_equal(same, song) and same is not song
    with pytest.raises(ConfigError, match="tempo factor must be 0.25-4"):
        stretch_audio(song, 5.0, RATE)
    with pytest.raises(ConfigError, match="stretcher must be one of sox, librosa"):
        stretch_audio(song, 1.1, RATE, "rubberband")


def test_without_sox_or_librosa_it_says_what_to_install(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_librosa(name, *args, **kwargs):
        if name == "librosa":
            raise ImportError("no librosa here")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(shutil, "which", lambda name: None)
    monkeypatch.setattr(builtins, "__import__", no_librosa)
    assert available_stretcher() is None
    with pytest.raises(AudioError, match=r"needs SoX \(apt-get install sox\) or librosa"):
        stretch_audio(pulses(100.0, 1.0), 1.2, RATE)
