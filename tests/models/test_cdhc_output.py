"""The CDHC network's output layer: a sigmoid for targets in 0..1 (the paper's), a linear one for
normalised targets of any dataset or, by default on those, the change from the previous pose (a
residual output), and which datasets the cdhc model takes."""

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


pytestmark = pytest.mark.usefixtures("one_thread")  # tests/conftest.py


def small(output: str, seed: int = 0, leak: float = 0.0, inputs: str = "music-and-poses") -> CdhcNet:
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
        leak=leak,
        inputs=inputs,
    )
    return CdhcNet(config).eval()


def batch(T: int = 12, scale: float = 1.0):
    g = torch.Generator().manual_seed(1)
    return scale * torch.rand(2, T, F, generator=g), scale * torch.rand(2, T, D, generator=g)


def test_the_output_is_sigmoid_linear_or_residual_and_old_configs_are_sigmoid():
    with pytest.raises(
        KinectDataError, match="CDHC config: output must be one of sigmoid, linear, residual, not 'tanh'"
    ):
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
        start = net(*batch()).numpy()
    # at initialisation the last layer's input is small: the output is near its bias, unsquashed
    assert np.abs(start - mean).max() < 0.5
    assert (start[..., 0] < 0).all() and (start[..., 5] > 1).all()
    with torch.no_grad():
        net.decoder.output.weight.zero_()
        exact = net(*batch()).numpy()
    np.testing.assert_allclose(exact, np.broadcast_to(mean, exact.shape), atol=1e-6)
    # a sigmoid net given the same mean pose starts at it clipped into 0.01..0.99
    squashed = small("sigmoid")
    init_output_bias(squashed, mean)
    with torch.no_grad():
        squashed.decoder.output.weight.zero_()
        out = squashed(*batch()).numpy()
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
        a, b = linear(*batch(scale=20.0)).numpy(), sigmoid(*batch(scale=20.0)).numpy()
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
    settings = kind.settings_type(channels=8, decoder_channels=8, inputs="music-and-poses")
    for method in ("maxabs", "minmax"):
        found = manifest("kinect_v2_positions", method, root_centre)  # 25 joints in 3-D, no limbs
        kind.check_dataset(found)
        config = kind.network_config(settings, found)
        assert config["output"] == "residual" and config["joint_dims"] == 3 and config["coordinates"] == 75
        assert config["limbs"] == []
        assert kind.build(config).config.output == "residual"
        paper = kind.network_config(kind.settings_type(channels=8, decoder_channels=8, predicts="pose"), found)
        assert kind.build(paper).config.output == "linear"


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


def test_a_residual_output_adds_the_linear_output_to_the_previous_pose():
    """The same weights: residual(audio, previous) == linear(audio, previous) + previous, and at
    initialisation (bias 0, last weights 0) the pose stays where it was."""
    linear, residual = small("linear", seed=4), small("residual", seed=4)
    residual.load_state_dict({**linear.state_dict(), "anchor": residual.anchor})
    audio, previous = batch()
    with torch.no_grad():
        np.testing.assert_allclose(
            residual(audio, previous).numpy(), (linear(audio, previous) + previous).numpy(), atol=1e-6
        )
        init_output_bias(residual, np.full(D, 0.7))
        assert not residual.decoder.output.bias.any()
        residual.decoder.output.weight.zero_()
        np.testing.assert_allclose(residual(audio, previous).numpy(), previous.numpy(), atol=1e-7)


def test_a_residual_net_runs_free_as_a_loop_feeding_back_its_sums():
    """generate() from a first pose equals a loop over the full-sequence forward, each step fed the
    poses made so far (an independent computation: O(T^2) teacher-forced passes), and the training
    forward's free run equals generate()."""
    from kinectdata.models.cdhc import generate

    net = small("residual", seed=5)
    audio = batch(T=9)[0][0]
    first = torch.linspace(-0.5, 0.5, D)
    made = generate(net, audio, first)
    poses = [first]
    with torch.no_grad():
        for t in range(len(audio)):
            previous = torch.stack(poses)[None]  # poses of frames -1 .. t-1
            poses.append(net(audio[None, : t + 1], previous)[0, t])
    np.testing.assert_allclose(made, torch.stack(poses[1:]).numpy(), atol=1e-5)
    with torch.no_grad():
        _, free = net(audio[None], torch.cat([first[None], torch.zeros(len(audio) - 1, D)])[None], free=True)
    np.testing.assert_allclose(free[0].numpy(), made, atol=1e-5)


def test_a_leaky_residual_output_takes_back_a_share_of_the_distance_from_the_mean_pose():
    """pose = previous + change - leak * (previous - anchor), the anchor being the mean pose given
    to init_output_bias; a network whose change is 0 decays to the mean pose geometrically."""
    from kinectdata.models.cdhc import generate

    linear, leaky = small("linear", seed=6), small("residual", seed=6, leak=0.25)
    mean = np.linspace(-0.4, 0.4, D)
    init_output_bias(leaky, mean)
    state = {k: v for k, v in leaky.state_dict().items() if k != "anchor"}
    linear.load_state_dict(state)
    np.testing.assert_allclose(leaky.anchor.numpy(), mean, atol=1e-7)
    audio, previous = batch()
    with torch.no_grad():
        expected = linear(audio, previous) + previous - 0.25 * (previous - torch.as_tensor(mean, dtype=torch.float32))
        np.testing.assert_allclose(leaky(audio, previous).numpy(), expected.numpy(), atol=1e-6)
        leaky.decoder.output.weight.zero_()
    first = np.full(D, 0.8, dtype=np.float32)
    made = generate(leaky, audio[0], first)
    steps = np.arange(1, len(made) + 1)[:, None]
    np.testing.assert_allclose(made, mean + (first - mean) * 0.75**steps, atol=1e-5)
    with pytest.raises(KinectDataError, match="leak must be in 0..1"):
        CdhcConfig(output_dim=D, input_dim=F, output="residual", leak=1.5)


def test_a_music_only_net_makes_the_same_poses_whatever_poses_it_is_given():
    """inputs 'music': the skeleton encoder sees zeros, so the poses are those of the paper's net
    (same weights) given all-zero previous poses, whatever previous poses come in; its free run in
    training is that same pass, and generate() (which feeds back its outputs) makes them too."""
    from kinectdata.models.cdhc import FrameCdhc, generate

    music, paper = small("linear", seed=7, inputs="music"), small("linear", seed=7)
    paper.load_state_dict(music.state_dict())
    audio, previous = batch()
    with torch.no_grad():
        expected = paper(audio, torch.zeros_like(previous))
        np.testing.assert_allclose(music(audio, previous).numpy(), expected.numpy(), atol=1e-6)
        np.testing.assert_allclose(music(audio, previous * -3.0).numpy(), expected.numpy(), atol=1e-6)
        assert (paper(audio, previous) - expected).abs().max() > 1e-3  # the paper's net does use them
        poses, free = music(audio, previous, free=True)
        assert free is poses
    np.testing.assert_allclose(generate(music, audio[0], previous[0, 0]), expected[0].numpy(), atol=1e-5)
    stream = FrameCdhc(music)  # frame by frame with caches, fed poses it ignores
    state, made = stream.initial_state(), []
    with torch.no_grad():
        for t in range(audio.shape[1]):
            pose, *state = stream(audio[0, t], previous[0, t] + 1.0, *state)
            made.append(pose)
    np.testing.assert_allclose(torch.stack(made).numpy(), expected[0].numpy(), atol=1e-5)
    with pytest.raises(KinectDataError, match="inputs must be one of music-and-poses, music, not 'poses'"):
        CdhcConfig(output_dim=D, input_dim=F, inputs="poses")
    with pytest.raises(KinectDataError, match="inputs 'music' has none"):
        CdhcConfig(output_dim=D, input_dim=F, output="residual", inputs="music")


def test_the_music_only_setting_gives_a_linear_output():
    kind = model_kind("cdhc")
    given = manifest("listen_to_dance", "maxabs")
    assert kind.network_config(kind.settings_type(inputs="music"), given)["output"] == "linear"
    assert kind.network_config(kind.settings_type(inputs="music"), given)["leak"] == 0.0
    assert kind.network_config(kind.settings_type(), given)["inputs"] == "music"  # the default on real dance
