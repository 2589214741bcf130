"""The CDHC encoder-decoder of Lee, Kim, Lee (2018): sizes, causality, receptive field, loss,
incremental generation, and that it learns."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.special import expit, logit

torch = pytest.importorskip("torch")

from kinectdata.core.errors import KinectDataError  # noqa: E402
from kinectdata.core.jointsets import load_joint_set  # noqa: E402
from kinectdata.models.cdhc import (  # noqa: E402
    OPENPOSE_MPI_LIMBS,
    CdhcConfig,
    CdhcNet,
    FrameCdhc,
    StreamingCdhc,
    cdhc_loss,
    generate,
    generate_many,
    init_output_bias,
)

D = 44  # 15 joints x (x, y) + 14 limb lengths
F = 12  # audio features in the small tests


def sharpened(net: CdhcNet) -> CdhcNet:
    """The net with every 1x1 conv's weights x3 and the highway gates mostly carrying (bias -2).

    At the default initialisation an input frame changes the outputs by only ~1e-5 (each highway
    block halves what it carries); sharpened, by ~1e-2, so that comparing outputs can fail.
    """
    with torch.no_grad():
        for module in net.modules():
            if isinstance(module, torch.nn.Linear):
                module.weight.mul_(3.0)
            if hasattr(module, "gate_norm"):
                module.gate_norm.bias.fill_(-2.0)
    return net


def make_net(channels=8, seed=0, dtype=torch.float32, sharpen=True, **config) -> CdhcNet:
    torch.manual_seed(seed)
    config = {"output_dim": D, "input_dim": F, "channels": channels, "decoder_channels": channels, **config}
    net = CdhcNet(CdhcConfig(**config))
    return (sharpened(net) if sharpen else net).to(dtype).eval()


pytestmark = pytest.mark.usefixtures("one_thread")  # tests/conftest.py


def sequences(T, batch=2, seed=1, dtype=torch.float32, features=F):
    g = torch.Generator().manual_seed(seed)
    return torch.rand(batch, T, features, generator=g, dtype=dtype), torch.rand(batch, T, D, generator=g, dtype=dtype)


def openpose_limbs_from_joint_set() -> list[tuple[int, int]]:
    js = load_joint_set("openpose_mpi")
    return [(j, p) for j, p in enumerate(js.parents) if p >= 0]


def test_default_layout_is_openpose_mpi():
    assert list(OPENPOSE_MPI_LIMBS) == openpose_limbs_from_joint_set()
    config = CdhcConfig(output_dim=D, input_dim=80)
    assert (config.coordinates, config.joint_dims, len(config.limbs)) == (30, 2, 14)


def test_config_is_validated_and_round_trips():
    bad = [
        {"channels": 0},
        {"dropout": 1.0},
        {"encoder_dilations": (1, 0)},
        {"coordinates": 29},  # not a multiple of joint_dims
        {"output_dim": 43},  # 30 + 14 do not fit
        {"limbs": ((0, 15),)},  # only 15 joints
        {"limbs": ((3, 3),)},
    ]
    for change in bad:
        with pytest.raises(KinectDataError, match="CDHC config"):
            CdhcConfig(**{"output_dim": D, "input_dim": 80, **change})
    config = CdhcConfig(output_dim=8, input_dim=5, coordinates=6, joint_dims=3, limbs=((1, 0),), dropout=0.1)
    assert CdhcConfig.from_dict(json.loads(json.dumps(config.to_dict()))) == config


def test_full_size_layers_and_parameter_count():
    net = CdhcNet(CdhcConfig(output_dim=D, input_dim=80))

    def conv(cin, cout, k=1):
        return k * cin * cout + cout

    def highway(c, k=3):
        return conv(c, 2 * c, k) + 2 * 2 * c  # the conv and two layer norms (gain and bias over c)

    encoder = conv(80, 256) + 2 * conv(256, 256) + 10 * highway(256)
    skeleton = conv(D, 256) + 2 * conv(256, 256) + 10 * highway(256)
    fusion = conv(512, 256) + conv(256, 128)
    decoder = 6 * highway(128) + 3 * conv(128, 128) + conv(128, D)
    expected = encoder + skeleton + fusion + decoder
    assert expected == 9_004_332  # the count stated in CdhcNet's docstring
    assert sum(p.numel() for p in net.parameters()) == expected
    for encoder in (net.audio_encoder, net.skeleton_encoder):
        assert [b.conv.dilation[0] for b in encoder.blocks] == [1, 3, 9, 27, 1, 3, 9, 27, 3, 3]
        assert {(b.conv.kernel_size[0], b.conv.out_channels) for b in encoder.blocks} == {(3, 512)}
    assert [b.conv.dilation[0] for b in net.decoder.blocks] == [1, 3, 9, 27, 3, 3]


def test_output_shape_and_range():
    net = make_net()
    audio, previous = sequences(25, batch=3)
    with torch.no_grad():
        out = net(audio, previous)
        loud = net(100 * audio, -50 * previous)
    assert out.shape == (3, 25, D)
    assert ((out > 0) & (out < 1)).all()
    assert ((loud >= 0) & (loud <= 1)).all()
    with pytest.raises(KinectDataError, match=r"audio must be \[B, T >= 1, 12\]"):
        net(audio[..., :5], previous)
    with pytest.raises(KinectDataError, match=r"not \[3, 0, 12\]"):
        net(audio[:, :0], previous[:, :0])
    with pytest.raises(KinectDataError, match="previous poses"):
        net(audio, previous[:, :10])


@pytest.mark.parametrize("changed", ["audio", "previous", "both"])
def test_outputs_do_not_look_ahead(changed):
    net = make_net()
    audio, previous = sequences(30)
    noise_audio, noise_previous = sequences(30, seed=7)
    t = 12

    def changed_from(start):
        a, p = audio.clone(), previous.clone()
        if changed in ("audio", "both"):
            a[:, start:] = noise_audio[:, start:]
        if changed in ("previous", "both"):
            p[:, start:] = noise_previous[:, start:]
        return a, p

    with torch.no_grad():
        base = net(audio, previous)
        later = net(*changed_from(t + 1))
        now = net(*changed_from(t))
    assert torch.allclose(later[:, : t + 1], base[:, : t + 1], rtol=0, atol=1e-6)
    assert (later[:, t + 1 :] - base[:, t + 1 :]).abs().amax() > 1e-3
    assert torch.allclose(now[:, :t], base[:, :t], rtol=0, atol=1e-6)
    assert (now[:, t] - base[:, t]).abs().amax() > 1e-3


@pytest.mark.parametrize("changed", ["audio", "previous"])
def test_receptive_field_boundary(changed):
    """Output t depends on frames t - R + 1 .. t of either input and not on frame t - R."""
    net = make_net(channels=4, dtype=torch.float64)
    R = net.receptive_field
    assert R == 1 + 2 * (1 + 3 + 9 + 27 + 1 + 3 + 9 + 27 + 3 + 3) + 2 * (1 + 3 + 9 + 27 + 3 + 3) == 265
    T = R + 4
    t = T - 1
    audio, previous = sequences(T, batch=1, dtype=torch.float64)

    def output_t_after_changing(frame):
        a, p = audio.clone(), previous.clone()
        x = a if changed == "audio" else p
        x[:, frame] = 1.0 - x[:, frame] + 0.5
        with torch.no_grad():
            return net(a, p)[0, t]

    with torch.no_grad():
        base = net(audio, previous)[0, t]
    assert (output_t_after_changing(t - R + 1) - base).abs().amax() > 1e-12
    assert (output_t_after_changing(t - R) - base).abs().amax() < 1e-14


def numpy_loss(pred, target, mask, limb_weight):
    """The loss computed joint by joint from the openpose_mpi hierarchy (float64)."""
    js = load_joint_set("openpose_mpi")
    diff = np.abs(pred - np.where(mask, target, 0.0))
    l1 = diff[mask].mean()
    errors = []
    for b in range(pred.shape[0]):
        for t in range(pred.shape[1]):
            limb = 0
            for j, parent in enumerate(js.parents):
                if parent < 0:
                    continue
                xy = slice(2 * j, 2 * j + 2), slice(2 * parent, 2 * parent + 2)
                valid = mask[b, t, xy[0]].all() and mask[b, t, xy[1]].all() and mask[b, t, 30 + limb]
                if valid:
                    length = np.hypot(*(pred[b, t, xy[0]] - pred[b, t, xy[1]]))
                    errors.append(abs(length - target[b, t, 30 + limb]))
                limb += 1
    limb_loss = float(np.mean(errors))
    return l1 + limb_weight * limb_loss, l1, limb_loss


def test_loss_against_numpy():
    rng = np.random.default_rng(4)
    pred = rng.uniform(0, 1, (2, 3, D))
    target = rng.uniform(0, 1, (2, 3, D))
    mask = rng.uniform(size=(2, 3, D)) > 0.15
    target[~mask] = np.nan  # invalid values must not reach the loss or its gradient
    config = CdhcConfig(output_dim=D, input_dim=F)
    p = torch.tensor(pred, requires_grad=True)
    total, parts = cdhc_loss(p, torch.tensor(target), torch.tensor(mask), config, limb_weight=0.5)
    expected_total, expected_l1, expected_limb = numpy_loss(pred, target, mask, 0.5)
    total.backward()
    assert parts["l1"].item() == pytest.approx(expected_l1, abs=1e-12)
    assert parts["limb"].item() == pytest.approx(expected_limb, abs=1e-12)
    assert total.item() == pytest.approx(expected_total, abs=1e-12)
    assert torch.isfinite(p.grad).all() and (p.grad[torch.tensor(~mask)] == 0).all()

    nothing = torch.zeros(2, 3, D, dtype=torch.bool)
    total, parts = cdhc_loss(p, torch.tensor(target), nothing, config)
    assert total.item() == parts["l1"].item() == parts["limb"].item() == 0.0


def test_loss_follows_the_configured_layout():
    """Two 3-D joints, one limb, one extra component: limb length |joint 1 - joint 0| at component 6."""
    config = CdhcConfig(output_dim=8, input_dim=F, coordinates=6, joint_dims=3, limbs=((1, 0),))
    pred = np.array([[0.1, 0.2, 0.3, 0.4, 0.6, 0.3, 0.9, 0.5], [0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.0, 0.5]])
    target = np.array([[0.1, 0.2, 0.3, 0.4, 0.6, 0.3, 0.2, 0.7], [0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.3, 0.5]])
    total, parts = cdhc_loss(torch.tensor(pred), torch.tensor(target), None, config, limb_weight=2.0)
    lengths = np.linalg.norm(pred[:, 3:6] - pred[:, 0:3], axis=1)  # 0.5 and 0.0
    assert parts["l1"].item() == pytest.approx(np.abs(pred - target).mean(), abs=1e-12)
    assert parts["limb"].item() == pytest.approx(np.mean(np.abs(lengths - target[:, 6])), abs=1e-12)
    assert parts["limb"].item() == pytest.approx((0.3 + 0.3) / 2, abs=1e-12)
    assert total.item() == pytest.approx(parts["l1"].item() + 2 * parts["limb"].item(), abs=1e-12)


def test_streaming_equals_forward():
    net = make_net()
    audio, previous = sequences(40, batch=2)
    stream = StreamingCdhc(net)
    audio_caches, pose_caches = stream.initial_state(batch=2)
    with torch.no_grad():
        expected = net(audio, previous)
        steps = []
        for t in range(40):
            pose, audio_caches, pose_caches = stream(audio[:, t], previous[:, t], audio_caches, pose_caches)
            steps.append(pose)
    assert torch.allclose(torch.stack(steps, dim=1), expected, rtol=0, atol=1e-5)


def teacher_forced(net, audio, first_pose, generated):
    previous = np.concatenate([first_pose[None], generated[:-1]])
    with torch.no_grad():
        return net(torch.as_tensor(audio)[None], torch.as_tensor(previous)[None])[0].numpy()


def test_generation_feeds_back_its_own_output():
    net = make_net(dropout=0.3).train()  # generation must switch dropout off and restore the mode
    rng = np.random.default_rng(2)
    audio = rng.uniform(0, 1, (60, F)).astype(np.float32)
    first = rng.uniform(0, 1, D).astype(np.float32)
    poses = generate(net, audio, first)
    assert net.training
    net.eval()
    assert poses.shape == (60, D) and poses.dtype == np.float32
    np.testing.assert_allclose(poses, teacher_forced(net, audio, first, poses), rtol=0, atol=1e-5)
    np.testing.assert_array_equal(generate(net, torch.from_numpy(audio), first), poses)
    other_start = generate(net, audio, 1.0 - first)
    assert np.abs(other_start[0] - poses[0]).max() > 1e-3
    with pytest.raises(KinectDataError, match="first_pose"):
        generate(net, audio, first[:10])
    with pytest.raises(KinectDataError, match="audio must be"):
        generate(net, audio[:0], first)


def test_songs_generated_together_equal_each_song_alone():
    """Shorter songs are padded in the batch: each song's poses are still its own free run (the
    teacher-forced network on them, computed in parallel, gives them back)."""
    net = make_net()
    rng = np.random.default_rng(5)
    audios = [rng.uniform(0, 1, (n, F)).astype(np.float32) for n in (37, 60, 5)]
    firsts = [rng.uniform(0, 1, D).astype(np.float32) for _ in audios]
    together = generate_many(net, audios, firsts)
    assert [g.shape for g in together] == [(37, D), (60, D), (5, D)]
    for audio, first, poses in zip(audios, firsts, together):
        np.testing.assert_allclose(poses, teacher_forced(net, audio, first, poses), rtol=0, atol=1e-5)
        np.testing.assert_allclose(poses, generate(net, audio, first), rtol=0, atol=1e-5)
    with pytest.raises(KinectDataError, match="2 songs but 1 first poses"):
        generate_many(net, audios[:2], firsts[:1])


def test_a_music_only_net_hears_its_start_silence_before_every_song_in_every_form():
    """``start_silence``: generation and the stream both give the poses the network makes for the
    song preceded by that many frames of zero features (here one pass over the two together), not
    those of the song alone; only a music-only network takes it."""
    net = make_net(inputs="music", start_silence=20)
    rng = np.random.default_rng(7)
    audio, first = rng.uniform(0, 1, (30, F)).astype(np.float32), rng.uniform(0, 1, D).astype(np.float32)
    with torch.no_grad():
        after_silence = torch.as_tensor(np.concatenate([np.zeros((20, F), np.float32), audio]))[None]
        expected = net(after_silence, torch.zeros(1, 50, D))[0, 20:].numpy()
        alone = net(torch.as_tensor(audio)[None], torch.zeros(1, 30, D))[0].numpy()
        stream = FrameCdhc(net)
        state, stepped = stream.initial_state(), []
        for frame in torch.as_tensor(audio):
            pose, *state = stream(frame, torch.as_tensor(first), *state)
            stepped.append(pose.numpy())
    np.testing.assert_allclose(generate(net, audio, first), expected, rtol=0, atol=1e-5)
    np.testing.assert_allclose(np.stack(stepped), expected, rtol=0, atol=1e-5)
    assert np.abs(alone - expected).max() > 1e-3  # what the silence changed
    with pytest.raises(KinectDataError, match=r"start_silence must be at least 0 \(0 unless inputs is 'music'\)"):
        CdhcConfig(output_dim=D, input_dim=F, start_silence=5)


def test_full_size_generates_beyond_its_receptive_field():
    """The paper's size, 600 frames (20 s at 30 fps, over twice its 265-frame receptive field):
    every frame is the teacher-forced network's on the fed-back poses. (Its speed:
    benchmarks/bench_listen.py.)"""
    torch.manual_seed(0)
    net = sharpened(CdhcNet(CdhcConfig(output_dim=D, input_dim=80))).eval()
    assert 2 * net.receptive_field < 600
    rng = np.random.default_rng(3)
    audio = rng.uniform(0, 1, (600, 80)).astype(np.float32)
    first = rng.uniform(0, 1, D).astype(np.float32)
    poses = generate(net, audio, first)
    assert poses.shape == (600, D)
    np.testing.assert_allclose(poses, teacher_forced(net, audio, first, poses), rtol=0, atol=1e-5)


def test_output_bias_starts_at_the_mean_pose():
    net = make_net()
    mean = np.linspace(0.0, 1.0, D)  # the ends are clipped to 0.01 and 0.99
    init_output_bias(net, mean)
    np.testing.assert_allclose(net.decoder.output.bias.detach().numpy(), logit(np.clip(mean, 0.01, 0.99)), atol=1e-6)
    with torch.no_grad():
        net.decoder.output.weight.zero_()
        out = net(*sequences(5))
    np.testing.assert_allclose(out.numpy(), np.broadcast_to(np.clip(mean, 0.01, 0.99), out.shape), atol=1e-6)
    with pytest.raises(KinectDataError, match=r"components \[3\]"):
        init_output_bias(net, np.where(np.arange(D) == 3, np.nan, 0.5))


def synthetic_dance(rng, batch, T, weights):
    """Audio iid per frame (so the previous pose tells nothing) and poses that are a function of it."""
    audio = rng.uniform(0, 1, (batch, T, weights.shape[0]))
    xy = expit(audio @ weights).reshape(batch, T, 15, 2)
    lengths = np.stack([np.linalg.norm(xy[:, :, j] - xy[:, :, p], axis=-1) for j, p in OPENPOSE_MPI_LIMBS], -1)
    return audio.astype(np.float32), np.concatenate([xy.reshape(batch, T, 30), lengths], -1).astype(np.float32)


def test_training_learns_poses_from_the_audio():
    """The held-out loss falls well below a constant pose's (the per-component median, L1's best
    constant). A shallow net (two highway blocks per encoder, dilations 1 and 3, one in the decoder):
    at full depth, with its 265-frame receptive field, the net memorises the 16 short training
    sequences before it generalises."""
    rng = np.random.default_rng(5)
    weights = rng.normal(0, 1.5, (6, 30))
    audio, poses = synthetic_dance(rng, 16, 32, weights)
    test_audio, test_poses = synthetic_dance(rng, 8, 32, weights)
    config = {"input_dim": 6, "dropout": 0.0, "encoder_dilations": (1, 3), "decoder_dilations": (1,)}
    net = make_net(channels=64, sharpen=False, **config)
    mean_pose = poses.reshape(-1, D).mean(axis=0)
    init_output_bias(net, mean_pose)
    cfg = net.config

    def shifted(p):  # previous poses: the mean pose, then the true poses one frame late
        return torch.cat([torch.from_numpy(mean_pose).expand(len(p), 1, D), p[:, :-1]], dim=1)

    def test_loss():
        with torch.no_grad():
            target = torch.from_numpy(test_poses)
            return float(cdhc_loss(net(torch.from_numpy(test_audio), shifted(target)), target, None, cfg)[0])

    median = torch.from_numpy(np.broadcast_to(np.median(poses.reshape(-1, D), axis=0), test_poses.shape).copy())
    constant = float(cdhc_loss(median, torch.from_numpy(test_poses), None, cfg)[0])
    before = test_loss()
    optimiser = torch.optim.Adam(net.parameters(), lr=3e-3)
    x, y = torch.from_numpy(audio), torch.from_numpy(poses)
    net.train()
    for _ in range(200):
        optimiser.zero_grad()
        loss, _ = cdhc_loss(net(x, shifted(y)), y, None, cfg)
        loss.backward()
        optimiser.step()
    net.eval()
    after = test_loss()
    assert after < 0.5 * min(before, constant), (before, constant, after)
