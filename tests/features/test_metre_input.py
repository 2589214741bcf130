"""The song's metre as a network input (kinectdata.features.metre_input): one value per bar length,
on the frames where music sounds; stacked under the presets' spectra and pulse."""

from __future__ import annotations

import numpy as np
import pytest

from kinectdata.core.errors import ConfigError
from kinectdata.features import PRESETS, compute_features, feature_config, needs_metre
from kinectdata.features.metre_input import MetreInputConfig, metre_input_features
from kinectdata.features.silence import silence_features, silent_frames

RATE = 16000
FPS = 30.0


def frames(seconds: float) -> np.ndarray:
    return np.round(np.arange(int(seconds * FPS)) * RATE / FPS).astype(np.int64)


def test_each_frame_says_the_metre_where_music_sounds():
    music = np.random.default_rng(0).normal(0, 0.1, 4 * RATE).astype(np.float32)
    music[RATE : 2 * RATE] = 0.0  # a second of digital silence
    starts = frames(4.0)
    config = MetreInputConfig()
    waltz, padded = metre_input_features(music, starts, config, beats_per_bar=3)
    assert waltz.shape == (len(starts), 2) and waltz.dtype == np.float32
    own_slice = [np.any(np.abs(music[s : s + 534]) > 0) for s in starts]
    assert np.array_equal(waltz[:, 0], np.array(own_slice, np.float32)) and not waltz[:, 1].any()
    assert not waltz[30:59].any() and waltz[59, 0] == 1  # frames 30-58 lie in the silence, 59 reaches past it
    assert waltz[10].tolist() == [1.0, 0.0]
    four, _ = metre_input_features(music, starts, config, beats_per_bar=4)
    assert four[10].tolist() == [0.0, 1.0]
    assert metre_input_features(music, starts, config)[0][10].tolist() == [0.0, 1.0]  # none given: 4
    six, _ = metre_input_features(music, starts, config, beats_per_bar=6)
    assert not six.any()  # a metre not among the values
    assert padded.tolist() == [s + 534 > music.size for s in starts]


def test_planes_under_an_image_input_and_the_presets():
    music = np.random.default_rng(1).normal(0, 0.1, 2 * RATE).astype(np.float32)
    planes, _ = metre_input_features(music, frames(1.0), MetreInputConfig(planes=(129, 5)), beats_per_bar=3)
    assert planes.shape == (30, 2, 129, 5) and (planes[:, 0] == 1).all() and (planes[:, 1] == 0).all()
    for name, shape in (("yalta2016_rhythm_metre", (4, 129, 5)), ("listen_to_dance_rhythm_bars_metre", (155,))):
        config = PRESETS[name]
        assert config.output_shape == shape and needs_metre(config)
        assert feature_config(config.to_dict()) == config
        made, _ = compute_features(music, frames(1.0), config, beats_per_bar=3)
        without, _ = compute_features(music, frames(1.0), PRESETS[name.removesuffix("_metre")], beats_per_bar=3)
        assert np.array_equal(made[:, : without.shape[1]], without)  # the parts before it unchanged
        # digital silence still looks like silence: the metre gives zeros there
        quiet = silence_features(config, FPS)
        assert silent_frames(compute_features(np.zeros(RATE, np.float32), frames(0.5), config, beats_per_bar=3)[0],
                             quiet).all()  # fmt: skip


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"values": ()}, "bar lengths of at least 1 beat"),
        ({"values": (3, 3)}, "values must differ"),
        ({"planes": (129,)}, "planes must be"),
    ],
)
def test_bad_settings_are_refused(settings, message):
    with pytest.raises(ConfigError, match=message):
        MetreInputConfig(**settings)
