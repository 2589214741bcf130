"""A song played to the network at its style's tempo and its dance warped back
(kinectdata.inference.style_tempo): the warp, the factor heard in real audio, the band's checks."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TINY_TRAINING
from helpers import metre_music

from kinectdata.align.stretch import stretch_audio
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.features import PRESETS
from kinectdata.features.music_style import MusicStyleClassifier
from kinectdata.features.stack import StackConfig
from kinectdata.features.style_input import StyleInputConfig
from kinectdata.inference.style_tempo import (
    AS_IT_IS,
    check_band,
    run_style_tempo,
    style_tempo_factor,
    style_tempo_line,
    warp_back,
)
from kinectdata.training.config import TrainConfig

RATE = 16000


def bobbing(period_s: float, seconds: float, fps: float = 30.0) -> np.ndarray:
    """[T, 2, 3] two joints bobbing at ``period_s``."""
    t = np.arange(int(seconds * fps)) / fps
    out = np.zeros((t.size, 2, 3))
    out[:, 0, 1] = 0.1 * np.sin(2 * np.pi * t / period_s)
    out[:, 1, 1] = 0.05 * np.cos(2 * np.pi * t / period_s)
    return out


def test_warp_back_puts_a_dance_on_the_original_clock():
    # a dance made at x1.18 moves 1.18 times as fast; warped back it is the x1.00 dance (linear
    # interpolation of a smooth curve: errors of a millimetre or two on swings of 20 cm)
    at_one, fast = bobbing(1.2, 20.0), bobbing(1.2 / 1.18, 20.0 / 1.18)
    back = warp_back(fast, 1.18)
    assert back.shape[1:] == at_one.shape[1:] and abs(len(back) - len(at_one)) <= 2
    n = min(len(back), len(at_one))
    assert np.max(np.abs(back[:n] - at_one[:n])) < 2e-3
    frame = warp_back(np.arange(10.0).reshape(10, 1, 1), 0.5)[:, 0, 0]  # frame k comes from frame 2 k
    assert np.allclose(frame, [0, 2, 4, 6, 8])
    # [T, D] values too, to as many frames as asked: past the last frame it is held
    held = warp_back(np.arange(4.0)[:, None] * [1.0, -1.0], 2.0, frames=9)
    assert np.allclose(held[:, 0], [0, 0.5, 1, 1.5, 2, 2.5, 3, 3, 3]) and np.allclose(held[:, 1], -held[:, 0])
    with pytest.raises(KinectDataError, match=r"\[T, \.\.\.\] with T >= 2"):
        warp_back(np.zeros((1, 2, 3)), 1.1)


def _features(tempo_bpm: float) -> StackConfig:
    """The cdhc model's style preset with a one-style classifier whose usual tempo is ``tempo_bpm``."""
    classifier = MusicStyleClassifier(("rumba",), ((0.0,) * 5,), (0.0,) * 5, (1.0,) * 5, tempi=(tempo_bpm,))
    parts = PRESETS["listen_to_dance_rhythm_bars_style"].parts
    return StackConfig((*parts[:-1], StyleInputConfig(classifier=classifier)))


def test_the_factor_is_heard_in_the_music_and_brings_it_to_the_bands_edge():
    pytest.importorskip("librosa")
    song, _ = metre_music(126.0, 4, bars=12, seed=0, rate=RATE)
    factor, style = style_tempo_factor(song, _features(100.0), 0.08)
    # 126 beats a minute played at 108, the band's edge above 100 (librosa's tempo within 3 %)
    assert style == "rumba" and 126.0 * factor == pytest.approx(108.0, rel=0.03)
    assert style_tempo_factor(song, _features(120.0), 0.08) == (1.0, "rumba")  # within the band: as it is
    assert style_tempo_factor(song[: 2 * RATE], _features(100.0), 0.08) == (1.0, None)  # too few beats to tell
    faster = stretch_audio(song, factor, RATE)
    assert faster.dtype == np.float32 and len(faster) == pytest.approx(len(song) / factor, abs=2)


def test_the_band_is_checked_and_kept_by_the_run():
    check_band(0.08, _features(100.0))
    with pytest.raises(ConfigError, match="must hear the song's style"):
        check_band(0.08, PRESETS["listen_to_dance_rhythm_bars"])
    with pytest.raises(ConfigError, match="share of the tempo"):
        check_band(1.5, _features(100.0))
    assert run_style_tempo({"train": {"style_tempo": 0.08}}) == 0.08 and run_style_tempo({"train": {}}) is None
    assert run_style_tempo({"train": {"style_tempo": 0.0}}) is None  # 0: off, as train takes it
    assert style_tempo_line(None) == AS_IT_IS and "8 %" in style_tempo_line(0.08)
    assert TrainConfig("cdhc").style_tempo == 0.08 and TrainConfig("cdhc", style_tempo=0).style_tempo is None
    assert TrainConfig("yalta").style_tempo is None and TrainConfig("cdhc", paper=True).style_tempo is None
    with pytest.raises(ConfigError, match="style_tempo must be a share"):
        TrainConfig(**{**TINY_TRAINING, "style_tempo": 2.0})


def test_a_run_whose_features_hear_no_style_keeps_no_band_and_says_why(sample_dataset, tmp_path):
    pytest.importorskip("torch")
    import json

    from kinectdata.training.train import TrainingWarning, train

    with pytest.warns(TrainingWarning, match="every song will be danced at its own tempo.*hear no dance style"):
        train(sample_dataset, tmp_path / "r", TrainConfig(**{**TINY_TRAINING, "epochs": 1, "style_tempo": 0.08}))
    assert json.loads((tmp_path / "r" / "config.json").read_text())["train"]["style_tempo"] is None


class _Echoes:
    """A stub network kind whose free run echoes its features' first value into every component."""

    name = "echoes"

    def __init__(self, dim: int):
        self.dim, self.lengths = dim, []

    def free_run(self, net, audio, first_pose, reset_every=None):
        self.lengths.append(len(audio))
        return np.repeat(np.asarray(audio)[1:, :1, 0, 0], self.dim, axis=1).astype(np.float32)

    def free_runs(self, net, audios, first_poses, reset_every=None):
        return [self.free_run(net, a, p, reset_every) for a, p in zip(audios, first_poses)]


def test_a_kind_told_a_song_is_played_dances_the_played_features_on_the_songs_clock():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "training"))
    from test_facing import SPEC, manifest

    from kinectdata.inference.turning import TurnedKind, with_turning

    dataset = {"target": SPEC.to_dict(), "normalisation": manifest()["normalisation"], "root_centre": True,
               "fps": 30.0, "features": {}}  # fmt: skip
    kind = _Echoes(SPEC.dim)
    drawn = with_turning(kind, {"train": {"style_tempo": 0.08}, "dataset": dataset})
    assert isinstance(drawn, TurnedKind)  # nothing drawn, faced or smoothed: the style tempo alone
    song = np.ones((90, 1, 129, 5), np.float32)  # 3 s of features (not silence)
    played = np.ones((75, 1, 129, 5), np.float32) * np.linspace(0.1, 0.9, 75)[:, None, None, None]
    first = np.zeros(SPEC.dim, np.float32)
    drawn.know_played(song, played, 1.2)
    run = drawn.free_run(None, song, first)
    # by hand: the played dance (frames 1..74 after the first pose), frame k of the song at k / 1.2
    dance = np.concatenate([[0.0], np.linspace(0.1, 0.9, 75)[1:]])
    expected = np.interp(np.minimum(np.arange(90) / 1.2, 74), np.arange(75), dance)[1:]
    assert kind.lengths == [75] and run.shape == (89, SPEC.dim)
    np.testing.assert_allclose(run, np.repeat(expected[:, None], SPEC.dim, axis=1), atol=1e-5)
    # the song's opening (a control cuts a song to another's length) is the song's music: danced from
    # the played frames that cover its 60 frames (frame 59 of the song is played frame 49.2), the
    # same dance as the whole song's first frames, as a causal network makes it
    (opening,) = drawn.free_runs(None, [song[:60]], [first])
    assert kind.lengths[-1] == 52 and opening.shape == (59, SPEC.dim)
    np.testing.assert_allclose(opening, run[:59], atol=1e-6)
    (other,) = drawn.free_runs(None, [2 * song[:60]], [first])  # a song it was not told of: as it is
    assert kind.lengths[-1] == 60 and np.allclose(other, 2.0, atol=1e-5)
