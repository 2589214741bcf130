"""A training window's context (``skip``): the cdhc network computes only what the counted frames
read, and a music-only network's skeleton codes come from one short pass. Both are checked
against the network stepped frame by frame (:class:`StreamingCdhc`, per-frame caches: the work
done another way), and the gradients against the whole window's."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from test_cdhc import sharpened  # noqa: E402

from kinectdata.core.errors import KinectDataError  # noqa: E402
from kinectdata.models.cdhc import CdhcConfig, CdhcNet, StreamingCdhc, history  # noqa: E402

D, F = 14, 7  # 4 joints x 3 + 2 limb lengths; features


pytestmark = pytest.mark.usefixtures("one_thread")  # tests/conftest.py


def make_net(inputs="music", output="linear", seed=0, dropout=0.0) -> CdhcNet:
    """A small net whose every input frame changes its outputs visibly (weights x3, gates carrying)."""
    torch.manual_seed(seed)
    config = CdhcConfig(
        output_dim=D,
        input_dim=F,
        channels=8,
        decoder_channels=6,
        dropout=dropout,
        coordinates=12,
        joint_dims=3,
        limbs=((1, 0), (2, 1)),
        output=output,
        inputs=inputs,
        leak=0.1 if output == "residual" else 0.0,
    )
    net = sharpened(CdhcNet(config))
    if output == "residual":
        with torch.no_grad():
            net.anchor.normal_()
    return net.eval()


def window(T, seed=1, batch=2):
    g = torch.Generator().manual_seed(seed)
    return torch.rand(batch, T, F, generator=g), torch.rand(batch, T, D, generator=g)


def stepped(net: CdhcNet, audio, previous):
    """The teacher-forced poses [B, T, D] one frame at a time."""
    stream = StreamingCdhc(net)
    audio_caches, pose_caches = [[torch.zeros_like(c) for c in caches] for caches in stream.initial_state(len(audio))]
    out = []
    with torch.no_grad():
        for t in range(audio.shape[1]):
            pose, audio_caches, pose_caches = stream(audio[:, t], previous[:, t], audio_caches, pose_caches)
            out.append(pose)
    return torch.stack(out, dim=1)


@pytest.mark.parametrize("inputs, output", [("music", "linear"), ("music-and-poses", "residual")])
@pytest.mark.parametrize("skip", [0, 3, 40, 91, 92, 120, 199])
def test_the_frames_after_the_context_are_the_stepped_networks(inputs, output, skip):
    net = make_net(inputs, output)
    # the decoder reads 92 frames back (2 x (1+3+9+27+3+3)), the encoders 172: skips on either side
    assert history(net.decoder.blocks) == 92 and history(net.audio_encoder.blocks) == 172
    audio, previous = window(200)
    every = stepped(net, audio, previous)
    with torch.no_grad():
        got = net(audio, previous, skip=skip)
    assert got.shape == (2, 200 - skip, D)
    # float32 sums taken in another order by the batched and the stepped convolutions, block after
    # block: on an Intel Xeon with AVX-512 FP16 the residual outputs differ by up to 1.8e-5 (under 1e-5
    # on the AMD EPYC machines before); a wrong frame differs by 1e-2 (the last assert)
    assert torch.allclose(got, every[:, skip:], rtol=0, atol=5e-5)
    assert (every[:, 1:] - every[:, :-1]).abs().max() > 1e-2  # the frames differ: the comparison can fail


def test_the_free_run_of_a_fed_back_network_is_cut_after_the_context_too():
    net = make_net("music-and-poses", "residual")
    audio, previous = window(150)
    with torch.no_grad():
        whole, whole_free = net(audio, previous, free=True)
        poses, free = net(audio, previous, free=True, skip=100)
    assert torch.allclose(poses, whole[:, 100:], rtol=0, atol=1e-5)
    assert torch.equal(free, whole_free[:, 100:])


@pytest.mark.parametrize("inputs", ["music", "music-and-poses"])
def test_the_gradients_are_the_whole_windows(inputs):
    """Only the work no counted frame reads is left out: every weight gets the gradient it gets
    from the whole window's outputs cut after the context."""
    net = make_net(inputs).train()
    audio, previous = window(230)
    target = torch.rand(2, 230 - 150, D, generator=torch.Generator().manual_seed(5))

    def gradients(poses):
        net.zero_grad()
        (poses - target).abs().mean().backward()
        return {name: p.grad.clone() for name, p in net.named_parameters()}

    whole = gradients(net(audio, previous)[:, 150:])
    cut = gradients(net(audio, previous, skip=150))
    for name, grad in whole.items():
        assert torch.allclose(cut[name], grad, rtol=1e-4, atol=1e-6), name
    assert whole["skeleton_encoder.blocks.9.conv.weight"].abs().max() > 0  # the short pass is trained too
    assert whole["audio_encoder.convs.0.weight"].abs().max() > 0


def test_a_music_only_networks_skeleton_codes_are_the_encoders_on_zeros():
    net = make_net("music")
    _, previous = window(260, batch=3)
    with torch.no_grad():
        expected, _ = net.skeleton_encoder(torch.zeros(3, 260, D))  # every window, every frame
        for first in (0, 50, 171, 172, 200):
            assert torch.equal(net._skeleton_codes(previous, first), expected[:, first:]) or torch.allclose(
                net._skeleton_codes(previous, first), expected[:, first:], rtol=0, atol=1e-6
            )
    assert (expected[0, 1:172] - expected[0, :171]).abs().max() > 1e-3  # they change while the padding is in view


def test_with_dropout_in_training_each_window_gets_its_own_skeleton_codes():
    net = make_net("music", dropout=0.5).train()
    _, previous = window(60)
    codes = net._skeleton_codes(previous, 0)
    assert not torch.equal(codes[0], codes[1])  # dropout drew each window's own masks


def test_a_context_as_long_as_the_window_is_refused():
    net = make_net()
    audio, previous = window(50)
    with pytest.raises(KinectDataError, match="skip must be in 0..49"):
        net(audio, previous, skip=50)
