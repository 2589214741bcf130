"""The yalta network's side channels: the style planes bypass the convolutions and join the audio
code before LSTM4-6, in the sequence network, its streaming form and the dataset a run is built for."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.features import PRESETS, feature_config  # noqa: E402
from kinectdata.inference.export import export_torchscript  # noqa: E402
from kinectdata.models.bundled import YaltaSettings  # noqa: E402
from kinectdata.models.registry import model_kind  # noqa: E402
from kinectdata.models.yalta import StreamingYalta, YaltaConfig, YaltaNet  # noqa: E402

D = 9
SIDE = 4


def side_net(seed=0, side=SIDE) -> YaltaNet:
    torch.manual_seed(seed)
    return YaltaNet(YaltaConfig(output_dim=D, units=16, input_shape=(2 + side, 129, 5), side_channels=side)).eval()


def song(T, style_slot, seed=1):
    """[T, 2 + SIDE, 129, 5]: random spectra and pulse, the style one-hot as constant planes."""
    g = torch.Generator().manual_seed(seed)
    x = torch.zeros(T, 2 + SIDE, 129, 5)
    x[:, :2] = torch.rand(T, 2, 129, 5, generator=g)
    x[:, 2 + style_slot] = 1.0
    return x


def test_side_channels_bypass_the_convolutions():
    net = side_net()
    assert net.convs[0].in_channels == 2
    assert net.lstm1.input_size == 65 and net.lstm2.input_size == 65 + SIDE + D
    with torch.no_grad():
        codes_a, _ = net.encode(song(12, 0)[None])
        codes_b, _ = net.encode(song(12, 3)[None])
    # the audio code (the first 65 values) is the same whatever the style; the side values are the planes' means
    torch.testing.assert_close(codes_a[..., :65], codes_b[..., :65], rtol=0, atol=0)
    expected = torch.zeros(1, 12, SIDE)
    expected[..., 3] = 1.0
    torch.testing.assert_close(codes_b[..., 65:], expected)


def test_the_style_changes_the_poses():
    net = side_net()
    first = torch.zeros(1, D)
    with torch.no_grad():
        a = net(song(20, 0)[None], first, "predicted")
        b = net(song(20, 1)[None], first, "predicted")
    assert not torch.allclose(a, b)


def test_streaming_equals_the_sequence_network_with_side_channels():
    net = side_net(seed=2)
    audio, first = song(25, 2, seed=3), torch.rand(D, generator=torch.Generator().manual_seed(4))
    with torch.no_grad():
        expected = net(audio[None], first[None], "predicted")[0]
        stream = StreamingYalta(net)
        state, pose, got = stream.initial_state(), first, []
        for k in range(audio.shape[0]):
            pose, *state = stream(audio[k], pose, *state)
            got.append(pose)
    torch.testing.assert_close(torch.stack(got), expected, rtol=0, atol=2e-6)


def test_exported_stream_takes_the_side_channels(tmp_path):
    net = side_net(seed=2)
    audio, first = song(5, 1, seed=3), torch.zeros(D)
    export_torchscript(net, tmp_path / "stream.ts", metadata={})
    loaded = torch.jit.load(str(tmp_path / "stream.ts"))
    with torch.no_grad():
        expected = net(audio[None], first[None], "predicted")[0, 0]
        got = loaded(audio[0], first, *loaded.initial_state())[0]
    torch.testing.assert_close(got, expected, rtol=0, atol=2e-6)


def test_side_channels_are_validated_and_old_configs_have_none():
    with pytest.raises(ValueError, match="side_channels"):
        YaltaConfig(output_dim=D, input_shape=(4, 129, 5), side_channels=4)
    old = {k: v for k, v in YaltaConfig(output_dim=D).to_dict().items() if k != "side_channels"}
    assert YaltaConfig.from_dict(old).side_channels == 0
    with pytest.raises(ValueError, match="style_path"):
        YaltaSettings(style_path="ears")


def manifest_for(preset: str) -> dict:
    config = PRESETS[preset]
    shape = {
        "yalta2016_rhythm_style": [6, 129, 5],
        "yalta2016_rhythm": [2, 129, 5],
        "yalta2016_rhythm_clocks_style": [12, 129, 5],
        "yalta2016_rhythm_metre": [4, 129, 5],
    }[preset]
    return {"feature_shape": shape, "target_dim": D, "config": {"features": json.loads(json.dumps(config.to_dict()))}}


@pytest.mark.parametrize(
    "preset,path,side",
    [
        ("yalta2016_rhythm_style", "lstm", 4),
        ("yalta2016_rhythm_style", "convs", 0),
        ("yalta2016_rhythm", "lstm", 0),
        ("yalta2016_rhythm_clocks_style", "lstm", 10),  # the clocks' 6 planes and the style's 4
        ("yalta2016_rhythm_clocks_style", "convs", 0),
        ("yalta2016_rhythm_metre", "lstm", 2),
    ],
)
def test_a_run_routes_the_constant_planes_as_its_settings_say(preset, path, side):
    manifest = manifest_for(preset)
    assert feature_config(manifest["config"]["features"]) == PRESETS[preset]
    kind = model_kind("yalta")
    config = kind.network_config(YaltaSettings(style_path=path), manifest)
    assert config["side_channels"] == side
    net = kind.build(config)
    assert net.convs[0].in_channels == manifest["feature_shape"][0] - side
    out = net(torch.zeros(1, 3, *manifest["feature_shape"]), torch.zeros(1, D), "predicted")
    assert out.shape == (1, 3, D) and np.isfinite(out.detach().numpy()).all()
