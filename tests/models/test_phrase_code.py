"""The phrase code (kinectdata.models.latent) and the cdhc network that takes it: the KL against
torch.distributions, the free nats, one code per phrase, and the same drawn codes on every
generation path (a whole song, a batch of songs, the one-frame stream, the teacher-forced pass)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from test_cdhc import D, F, make_net  # noqa: E402

from kinectdata.core.errors import KinectDataError  # noqa: E402
from kinectdata.models.cdhc import CdhcConfig, CdhcNet, FrameCdhc, generate, generate_many  # noqa: E402
from kinectdata.models.latent import PhraseCode, kl_term  # noqa: E402

pytestmark = pytest.mark.usefixtures("one_thread")  # tests/conftest.py


def test_kl_per_dimension_is_torch_distributions_kl_to_the_standard_normal():
    torch.manual_seed(0)
    code = PhraseCode(dims=3, phrase=4, pose_dim=5, out_channels=6)
    with torch.no_grad():
        for p in code.encoder.parameters():
            p.mul_(4.0)  # a posterior well away from N(0, I)
        poses = torch.randn(2, 10, 5)
        _, kl = code.posterior(poses)
        padded = torch.cat([poses, poses[:, -1:].expand(2, 2, 5)], dim=1)  # 10 frames: 3 phrases of 4
        mean, log_var = code.encoder(padded.reshape(2, 3, 20)).chunk(2, dim=-1)
    q = torch.distributions.Normal(mean, (0.5 * log_var).exp())
    p = torch.distributions.Normal(torch.zeros_like(mean), torch.ones_like(mean))
    assert kl.shape == (2, 3, 3)
    torch.testing.assert_close(kl, torch.distributions.kl_divergence(q, p), rtol=1e-5, atol=1e-6)
    assert float(kl.min()) > 0.1


def test_free_nats_forgive_each_dimension_its_share_averaged_over_the_phrases():
    kl = torch.tensor([[[0.2, 1.0], [0.4, 3.0]], [[0.0, 2.0], [0.2, 0.0]]])  # [B 2, phrases 2, dims 2]
    means = np.array([0.2, 1.5])  # per dimension over the 4 phrases
    assert float(kl_term(kl)) == pytest.approx(means.sum())
    assert float(kl_term(kl, free_nats=0.5)) == pytest.approx(np.clip(means - 0.5, 0, None).sum())
    with pytest.raises(KinectDataError, match="free_nats"):
        kl_term(kl, -1.0)


def test_one_code_per_phrase_the_posterior_mean_in_evaluation_and_a_draw_in_training():
    torch.manual_seed(1)
    code = PhraseCode(dims=2, phrase=5, pose_dim=3, out_channels=4).eval()
    poses = torch.randn(1, 12, 3)
    z, _ = code.posterior(poses)
    assert z.shape == (1, 12, 2)
    for start, end in ((0, 5), (5, 10), (10, 12)):
        assert torch.equal(z[0, start:end], z[0, start : start + 1].expand(end - start, 2))
    assert not torch.equal(z[0, 0], z[0, 5])
    torch.testing.assert_close(code.posterior(poses)[0], z)  # the mean: the same every time
    code.train()
    assert not torch.allclose(code.posterior(poses)[0], z)


def test_drawn_codes_are_the_table_rows_counted_in_phrases_from_the_draw():
    code = PhraseCode(dims=2, phrase=3, pose_dim=1, out_channels=1, draws=4)
    z = code.drawn(batch=2, frames=14, draw=torch.tensor([0, 3]))
    for b, draw in enumerate((0, 3)):
        for t in range(14):
            assert torch.equal(z[b, t], code.draws[(draw + t // 3) % 4])
            assert torch.equal(code.at_frame(torch.tensor([float(draw * 3 + t)]))[0], z[b, t])
    # the table is saved with the weights and the same in every network: generation is reproducible
    assert torch.equal(PhraseCode(2, 3, 1, 1, draws=4).draws, code.draws)
    assert "draws" in code.state_dict()


@pytest.mark.parametrize("inputs", ["music", "music-and-poses"])
def test_every_generation_path_takes_the_same_drawn_codes(inputs):
    extra = {"inputs": inputs, "output": "linear"} | ({"start_silence": 7} if inputs == "music" else {})
    net = make_net(latent_dims=3, phrase_frames=5, latent_draws=6, **extra)
    rng = np.random.default_rng(3)
    audio, first = rng.uniform(0, 1, (33, F)).astype(np.float32), rng.uniform(0, 1, D).astype(np.float32)
    dance = generate(net, audio, first, draw=2)
    assert np.abs(dance - generate(net, audio, first, draw=0)).max() > 1e-3  # another draw, another dance
    together = generate_many(net, [audio, audio[:20]], [first, first], [2, 4])
    np.testing.assert_allclose(together[0], dance, rtol=0, atol=1e-5)
    np.testing.assert_allclose(together[1], generate(net, audio[:20], first, draw=4), rtol=0, atol=1e-5)
    stream = FrameCdhc(net, draw=2)
    state, stepped, previous = stream.initial_state(), [], torch.as_tensor(first)
    with torch.no_grad():
        for frame in torch.as_tensor(audio):
            pose, *state = stream(frame, previous, *state)
            stepped.append(pose.numpy())
            previous = pose if inputs != "music" else previous
    np.testing.assert_allclose(np.stack(stepped), dance, rtol=0, atol=1e-5)
    # the teacher-forced pass on the generated poses, with the table's codes counted from the
    # first frame it is given (the start silence's first frame for a music-only network)
    silence = 7 if inputs == "music" else 0
    heard = np.concatenate([np.zeros((silence, F), np.float32), audio])
    previous = np.concatenate([np.zeros((silence, D), np.float32), first[None], dance[:-1]])
    with torch.no_grad():
        forced = net(torch.as_tensor(heard)[None], torch.as_tensor(previous)[None], draw=2)[0, silence:]
    np.testing.assert_allclose(forced.numpy(), dance, rtol=0, atol=1e-5)
    with pytest.raises(KinectDataError, match="2 songs but 1 draws"):
        generate_many(net, [audio, audio], [first, first], [1])


def test_training_infers_the_code_from_the_true_poses_and_keeps_its_kl_for_the_loss():
    net = make_net(latent_dims=4, phrase_frames=10, inputs="music", output="linear").train()
    audio, previous = torch.rand(2, 35, F), torch.rand(2, 35, D)
    poses = net(audio, previous, skip=5, posterior=True)
    assert poses.shape == (2, 30, D) and net.latent_kl.shape == (2, 4, 4)
    (poses.square().mean() + kl_term(net.latent_kl)).backward()
    encoder = net.phrase_code.encoder[0].weight.grad
    assert encoder is not None and float(encoder.abs().sum()) > 0
    net.eval()
    with torch.no_grad():  # the poses tell the figure: other true poses, another dance to the same music
        a = net(audio, previous, posterior=True)
        b = net(audio, torch.rand(2, 35, D), posterior=True)
    assert float((a - b).abs().max()) > 1e-3


def test_a_phrase_code_is_validated_and_saved_in_the_config():
    with pytest.raises(KinectDataError, match="latent_dims must be at least 0"):
        CdhcConfig(output_dim=D, input_dim=F, latent_dims=-1)
    with pytest.raises(KinectDataError, match="phrase_frames and latent_draws positive"):
        CdhcConfig(output_dim=D, input_dim=F, latent_dims=2, phrase_frames=0)
    config = CdhcConfig(output_dim=D, input_dim=F, latent_dims=2, phrase_frames=45)
    assert CdhcConfig.from_dict(config.to_dict()) == config
    assert CdhcNet(CdhcConfig(output_dim=D, input_dim=F)).phrase_code is None
    assert "phrase_frames" not in CdhcConfig(output_dim=D, input_dim=F).to_dict()  # no code, no entries


@pytest.mark.parametrize("inputs", ["music", "music-and-poses"])
def test_the_yalta_model_takes_the_same_drawn_codes_free_streamed_scripted_and_in_onnx(inputs, tmp_path):
    """The yalta model's phrase code joins LSTM4-6's input: a free run from a draw equals its
    stream from that draw, eager, scripted (the run's stream.ts) and exported to ONNX."""
    from kinectdata.inference.engines import make_engine, onnxruntime_available
    from kinectdata.models.registry import model_kind
    from kinectdata.models.yalta import PhrasedStreamingYalta, YaltaConfig, YaltaNet, free_run, free_runs

    torch.manual_seed(0)
    net = YaltaNet(YaltaConfig(output_dim=6, units=8, inputs=inputs, latent_dims=3, phrase_frames=5, latent_draws=7))
    net.eval()
    rng = np.random.default_rng(1)
    audio, first = rng.uniform(0, 1, (24, 1, 129, 5)).astype(np.float32), rng.uniform(0, 1, 6).astype(np.float32)
    dance = free_run(net, audio, first, draw=2)
    assert np.abs(dance - free_run(net, audio, first, draw=0)).max() > 1e-3
    together = free_runs(net, [audio, audio[:12]], [first, first], draws=[2, 0])
    np.testing.assert_allclose(together[0], dance, rtol=0, atol=1e-5)
    np.testing.assert_allclose(together[1], free_run(net, audio[:12], first), rtol=0, atol=1e-5)
    stream = PhrasedStreamingYalta(net, draw=2)
    for module in (stream, torch.jit.script(stream)):
        state, previous, stepped = module.initial_state(), torch.as_tensor(first), []
        with torch.no_grad():
            for frame in torch.as_tensor(audio[1:]):
                previous, *state = module(frame, previous, *state)
                stepped.append(previous.numpy())
        np.testing.assert_allclose(np.stack(stepped), dance, rtol=0, atol=1e-5)
    kind = model_kind("yalta")
    assert kind.stream_state_names(net.config.to_dict())[-1] == "phrase_frame"
    if onnxruntime_available():
        engine, pose, stepped = make_engine(net, "onnxruntime", kind=kind, draw=2), first, []
        for frame in audio[1:]:
            pose = engine.step(frame, pose)
            stepped.append(pose)
        np.testing.assert_allclose(np.stack(stepped), dance, rtol=0, atol=1e-4)


def test_yalta_training_infers_the_code_under_either_feedback():
    from kinectdata.models.registry import model_kind
    from kinectdata.models.yalta import YaltaConfig, YaltaNet

    kind = model_kind("yalta")
    net = YaltaNet(YaltaConfig(output_dim=6, units=8, latent_dims=2, phrase_frames=4)).train()
    audio, previous = torch.rand(2, 10, 1, 129, 5), torch.rand(2, 10, 6)
    for feedback in ("teacher", "predicted"):
        settings = kind.settings_type(feedback=feedback, latent_dims=2, free_nats=0.0, latent_weight=0.5)
        net.latent_kl = None
        pred = kind.predict(net, audio, previous, settings, context=2)
        assert pred.shape == (2, 8, 6) and net.latent_kl.shape == (2, 3, 2)
        plain = kind.loss(net, pred, previous[:, 2:], torch.ones(2, 8, 6, dtype=torch.bool), settings)
        expected = ((pred - previous[:, 2:]) ** 2).mean() + 0.5 * net.latent_kl.mean(dim=(0, 1)).sum()
        torch.testing.assert_close(plain, expected)
