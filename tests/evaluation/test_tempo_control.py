"""The tempo control (kinectdata.evaluation.tempo_control): a dance made for a song played faster or
slower, warped back by the tempo, repeats like the dance at x1.00 when the dancer keeps time with
the music and does not when it keeps its own tempo; checked on dances whose periods are set by
hand, and end to end through SoX on songs whose beat a model-like function hears."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from helpers import envelope_beat_s, pulsed_tone, skip_unless_installed
from scipy.stats import binomtest

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.tempo_control import (
    TempoControl,
    TempoPair,
    TempoSong,
    repetition_curve,
    tempo_control,
    tempo_pair,
)

FPS = 30.0
RATE = 16000


def dance(period_s: float, seconds: float, joints: int = 4) -> np.ndarray:
    """[T, J, 3] joints bobbing at ``period_s`` (with a second harmonic), each its own phase and size."""
    t = np.arange(int(seconds * FPS)) / FPS
    out = np.zeros((t.size, joints, 3))
    for j in range(joints):
        phase = 2 * np.pi * (t / period_s + j / joints)
        out[:, j, 1] = (1 + j) * 0.05 * np.sin(phase) + 0.02 * np.sin(2 * phase + j)
        out[:, j, 0] = 0.1 * j
    return out


def test_the_curve_is_the_joint_heights_autocorrelation_over_its_lags():
    curve = repetition_curve(dance(1.0, 30.0), FPS)
    lags = np.arange(len(curve)) / FPS + 0.3
    assert len(curve) == round((4.5 - 0.3) * FPS) + 1
    assert lags[np.argmax(curve)] == pytest.approx(1.0, abs=1 / FPS)  # the period's peak
    with pytest.raises(KinectDataError, match="too few for the tempo control's lags"):
        repetition_curve(dance(1.0, 0.4), FPS)


@pytest.mark.parametrize("rate", [0.85, 1.18])
def test_a_dancer_who_keeps_time_follows_and_one_who_keeps_its_own_does_not(rate):
    at_one = dance(1.3, 40.0)
    kept_time = tempo_pair("song", rate, at_one, dance(1.3 / rate, 40.0 / rate), FPS)
    own_tempo = tempo_pair("song", rate, at_one, dance(1.3, 40.0 / rate), FPS)
    assert kept_time.follows and kept_time.warped > 0.95 > kept_time.unwarped
    assert not own_tempo.follows and own_tempo.unwarped > 0.95 > own_tempo.warped


def test_the_count_its_chance_and_the_verdict():
    pairs = tuple(TempoPair(f"s{i}", 1.18, 0.9 if i < 12 else 0.1, 0.5) for i in range(14))
    control = TempoControl(pairs, (0.85, 1.18), "sox")
    assert control.followed == 12 and control.keeps_time
    assert control.p_value == pytest.approx(binomtest(12, 14, 0.5, alternative="greater").pvalue)
    assert "keeps time with the song at other tempi: yes (12 of 14 pairs follow" in control.verdict()
    # which program stretched the songs is said: SoX and librosa's fallback move the pairs differently
    assert control.verdict().endswith("the songs stretched by sox)")
    assert TempoControl(pairs, (0.85, 1.18), "librosa").verdict().endswith("the songs stretched by librosa)")
    eleven = TempoControl(pairs[:11] + pairs[12:] + (TempoPair("x", 0.85, 0.1, 0.5),), (0.85, 1.18), "sox")
    assert eleven.followed == 11 and not eleven.keeps_time
    assert control.to_dict()["pairs"][0] == {"song": "s0", "rate": 1.18, "warped": 0.9, "unwarped": 0.5,
                                             "follows": True}  # fmt: skip


def beat_song(bpm: float, seconds: float) -> np.ndarray:
    return pulsed_tone(bpm, seconds, RATE, tone_hz=660.0)


def heard_beat_s(samples: np.ndarray) -> float:
    """The beat of the music (s): where its loudness envelope's autocorrelation peaks in 0.3-1.2 s."""
    return envelope_beat_s(samples, RATE, (0.3, 1.2))


def features_of(samples: np.ndarray, beats_per_bar: int | None = None) -> np.ndarray:
    """Per motion frame, the beat the music has (a stand-in for a model's audio features)."""
    frames = int(len(samples) / RATE * FPS)
    return np.full((frames, 1), heard_beat_s(samples))


features_of.sample_rate = RATE  # type: ignore[attr-defined]


def listener(jobs):
    return [dance(2 * f[0, 0], len(f) / FPS)[1:] for f, _ in jobs]  # a step every two beats


def deaf(jobs):
    return [dance(1.1, len(f) / FPS)[1:] for f, _ in jobs]


def test_end_to_end_through_sox_a_listener_follows_every_pair_and_a_deaf_dancer_none():
    skip_unless_installed(None if shutil.which("sox") else "no sox on the PATH", "SoX")
    songs = [TempoSong(f"song at {bpm} BPM", beat_song(bpm, 30.0), np.zeros(3), 4) for bpm in (96, 120)]
    heard = tempo_control(songs, listener, features_of, FPS, stretcher="sox")
    assert heard.stretcher == "sox" and heard.rates == (0.85, 1.18)
    assert [(p.song, p.rate) for p in heard.pairs] == [(s.name, r) for s in songs for r in (0.85, 1.18)]
    assert heard.followed == 4
    ignored = tempo_control(songs, deaf, features_of, FPS, stretcher="sox")
    assert ignored.followed == 0 and not ignored.keeps_time
