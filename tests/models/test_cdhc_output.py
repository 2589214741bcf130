"""The CDHC network's output layer: a sigmoid for targets in 0..1 (the paper's), a linear one for
normalised targets of any dataset, and which datasets the cdhc model takes."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.special import expit

torch = pytest.importorskip("torch")

from kinectdata.core.errors import ConfigError, KinectDataError  # noqa: E402
from kinectdata.models.cdhc import CdhcConfig, CdhcNet, init_output_bias  # noqa: E402
from kinectdata.models.registry import model_kind  # noqa: E402
from kinectdata.targets.specs import load_target_spec  # noqa: E402

D, F = 8, 6  # 2 joints in 3-D and 2 limbs; 6 audio features


@pytest.fixture(autouse=True)
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def small(output: str, seed: int = 0) -> CdhcNet:
    torch.manual_seed(seed)
    config = CdhcConfig(
        output_dim=D,
        input_dim=F,
        channels=8,
        decoder_channels=8,
        coordinates=6,
        joint_dims=3,
        limbs=((1, 0),) * 2,
        output=output,
    )
    return CdhcNet(config).eval()


def inputs(T: int = 12, scale: float = 1.0):
    g = torch.Generator().manual_seed(1)
    return scale * torch.rand(2, T, F, generator=g), scale * torch.rand(2, T, D, generator=g)


def test_the_output_is_sigmoid_or_linear_and_old_configs_are_sigmoid():
    with pytest.raises(KinectDataError, match="CDHC config: output must be one of sigmoid, linear, not 'tanh'"):
        CdhcConfig(output_dim=44, input_dim=80, output="tanh")
    config = CdhcConfig(output_dim=8, input_dim=5, coordinates=6, joint_dims=3, limbs=((1, 0), (1, 0)), output="linear")
    assert CdhcConfig.from_dict(json.loads(json.dumps(config.to_dict()))) == config
    old = config.to_dict()
    del old["output"]  # a run written before the option
    assert CdhcConfig.from_dict(old).output == "sigmoid"
    assert CdhcConfig(output_dim=44, input_dim=80).output == "sigmoid"


def test_a_linear_output_starts_at_a_mean_pose_outside_0_1():
    mean = np.array([-0.5, 1.7, 0.3, -0.9, 0.9, 2.0, 0.0, 0.1])
    net = small("linear")
    init_output_bias(net, mean)
    np.testing.assert_allclose(net.decoder.output.bias.detach().numpy(), mean, atol=1e-7)  # no logit
    with torch.no_grad():
        start = net(*inputs()).numpy()
    # at initialisation the last layer's input is small: the output is near its bias, unsquashed
    assert np.abs(start - mean).max() < 0.5
    assert (start[..., 0] < 0).all() and (start[..., 5] > 1).all()
    with torch.no_grad():
        net.decoder.output.weight.zero_()
        exact = net(*inputs()).numpy()
    np.testing.assert_allclose(exact, np.broadcast_to(mean, exact.shape), atol=1e-6)
    # a sigmoid net given the same mean pose starts at it clipped into 0.01..0.99
    squashed = small("sigmoid")
    init_output_bias(squashed, mean)
    with torch.no_grad():
        squashed.decoder.output.weight.zero_()
        out = squashed(*inputs()).numpy()
    np.testing.assert_allclose(out, np.broadcast_to(np.clip(mean, 0.01, 0.99), out.shape), atol=1e-6)


def test_the_linear_output_is_the_sigmoid_outputs_logit():
    """The same weights, with and without the squashing: sigmoid(linear) == sigmoid output."""
    linear, sigmoid = small("linear", seed=3), small("sigmoid", seed=3)
    sigmoid.load_state_dict(linear.state_dict())
    with torch.no_grad():
        for module in linear.modules():  # large weights: outputs far outside 0..1
            if isinstance(module, torch.nn.Linear):
                module.weight.mul_(4.0)
        sigmoid.load_state_dict(linear.state_dict())
        a, b = linear(*inputs(scale=20.0)).numpy(), sigmoid(*inputs(scale=20.0)).numpy()
    assert a.min() < 0 or a.max() > 1
    np.testing.assert_allclose(expit(a.astype(np.float64)), b, atol=1e-6)


def manifest(target: str, method: str, root_centre: bool = False) -> dict:
    spec = load_target_spec(target)
    return {
        "feature_shape": [F],
        "target_dim": spec.dim,
        "normalisation": {"method": method},
        "config": {"target": spec.to_dict(), "root_centre": root_centre},
    }


@pytest.mark.parametrize("root_centre", [False, True])
def test_cdhc_takes_normalised_3d_positions_even_root_centred(root_centre):
    kind = model_kind("cdhc")
    settings = kind.settings_type(channels=8, decoder_channels=8)
    for method in ("maxabs", "minmax"):
        found = manifest("kinect_v2_positions", method, root_centre)  # 25 joints in 3-D, no limbs
        kind.check_dataset(found)
        config = kind.network_config(settings, found)
        assert config["output"] == "linear" and config["joint_dims"] == 3 and config["coordinates"] == 75
        assert config["limbs"] == []
        net = kind.build(config)
        assert net.config.output == "linear"


def test_cdhc_refuses_unnormalised_targets_unless_scaled_per_recording():
    kind = model_kind("cdhc")
    with pytest.raises(ConfigError) as caught:
        kind.check_dataset(manifest("kinect_v2_positions", "none"))
    message = str(caught.value)
    # it names what is needed and what this dataset has: position scale and normalisation
    assert "position_scale recording_minmax" in message and "maxabs" in message
    assert "this dataset's are none and none" in message
    paper = manifest("listen_to_dance", "none")  # the paper's: per-video min-max into 0..1
    kind.check_dataset(paper)
    config = kind.network_config(kind.settings_type(channels=8, decoder_channels=8), paper)
    assert config["output"] == "sigmoid"
    assert kind.build(config).config.output == "sigmoid"
    # its limbs are measured between its coordinates: root-centring is still refused
    with pytest.raises(ConfigError, match="without --root-centre"):
        kind.check_dataset(manifest("listen_to_dance", "none", root_centre=True))
