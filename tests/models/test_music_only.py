"""``--inputs music``: both models' decoders given the music only (zeros where the previous pose
went), so a pose is a function of the music so far; the yalta network's sequence, streaming and
half-precision forms agree on it, and the setting reaches each model's network config."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from kinectdata.core.errors import ConfigError  # noqa: E402
from kinectdata.models.registry import model_kind  # noqa: E402
from kinectdata.models.yalta import StreamingYalta, YaltaConfig, YaltaNet  # noqa: E402

D = 6


def nets(seed: int = 0) -> tuple[YaltaNet, YaltaNet]:
    """A music-only net and the paper's with the same weights."""
    torch.manual_seed(seed)
    music = YaltaNet(YaltaConfig(output_dim=D, units=8, inputs="music")).eval()
    paper = YaltaNet(YaltaConfig(output_dim=D, units=8)).eval()
    paper.load_state_dict(music.state_dict())
    return music, paper


def batch(T: int = 7):
    g = torch.Generator().manual_seed(2)
    return 0.1 + 0.8 * torch.rand(2, T, 1, 129, 5, generator=g), torch.rand(2, T, D, generator=g)


def test_a_music_only_yalta_net_is_the_papers_given_zero_poses_in_every_form():
    music, paper = nets()
    audio, previous = batch()
    with torch.no_grad():
        expected = paper(audio, torch.zeros_like(previous), "teacher")
        torch.testing.assert_close(music(audio, previous, "teacher"), expected, rtol=0, atol=1e-6)
        torch.testing.assert_close(music(audio, previous[:, 0] * 4.0, "predicted"), expected, rtol=0, atol=1e-6)
        assert (paper(audio, previous, "teacher") - expected).abs().max() > 1e-4  # the paper's net uses them
        poses, free = music(audio, previous, "teacher", free=True)
        assert free is poses
    for precision, atol in (("float32", 2e-6), ("float16", 2e-3)):
        stream = StreamingYalta(music, precision)
        state = stream.initial_state()
        made = []
        with torch.no_grad():
            for t in range(audio.shape[1]):
                pose, *state = stream(audio[0, t], previous[0, t] * -2.0, *state)
                made.append(pose)
        torch.testing.assert_close(torch.stack(made), expected[0], rtol=0, atol=atol)


def test_the_inputs_setting_reaches_both_models_network_configs():
    manifest = {
        "feature_shape": [1, 129, 5],
        "target_dim": D,
        "normalisation": {"method": "maxabs"},
        "config": {"target": {}},
    }
    yalta = model_kind("yalta")
    assert yalta.network_config(yalta.settings_type(inputs="music"), manifest)["inputs"] == "music"
    assert yalta.network_config(yalta.settings_type(), manifest)["inputs"] == "music-and-poses"
    assert YaltaConfig.from_dict({"output_dim": D}).inputs == "music-and-poses"  # runs written before
    for kind in (yalta, model_kind("cdhc")):
        with pytest.raises(ConfigError, match="inputs must be one of music-and-poses, music, not 'poses'"):
            kind.settings_type(inputs="poses")
        assert kind.paper["inputs"] == "music-and-poses"
