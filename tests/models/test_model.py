"""The Yalta et al. (2016) network: Table 1's shapes, both feedbacks, the streaming form, export."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.inference.export import export_onnx, export_torchscript  # noqa: E402
from kinectdata.models.yalta import StreamingYalta, YaltaConfig, YaltaNet  # noqa: E402

D = 65
INPUTS = ["features", "previous", "h1", "c1", "h2", "c2"]  # the exported stream's inputs (docs/training.md)


def make_net(units=24, activation="elu", seed=0) -> YaltaNet:
    torch.manual_seed(seed)
    net = YaltaNet(YaltaConfig(output_dim=D, units=units, activation=activation))
    with torch.no_grad():  # batch norm statistics away from identity, so folding them is tested
        for m in net.convs:
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.uniform_(-0.5, 0.5)
                m.running_var.uniform_(0.5, 2.0)
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
    return net.eval()


def features(T, batch=None, seed=1):
    g = torch.Generator().manual_seed(seed)
    shape = (T, 1, 129, 5) if batch is None else (batch, T, 1, 129, 5)
    return 0.1 + 0.8 * torch.rand(shape, generator=g)


def test_convolutions_follow_table_1():
    net = make_net()
    x = torch.zeros(2, 1, 129, 5)
    sizes = []
    for m in net.convs:
        x = m(x)
        if isinstance(m, torch.nn.Conv2d):
            sizes.append((m.kernel_size, x.shape[1:]))
    assert sizes == [
        ((33, 2), (16, 97, 4)),
        ((33, 2), (32, 65, 3)),
        ((33, 2), (64, 33, 2)),
        ((33, 2), (65, 1, 1)),
    ]
    assert sum(isinstance(m, torch.nn.BatchNorm2d) for m in net.convs) == 4
    assert (net.lstm1.input_size, net.lstm1.num_layers) == (65, 3)
    assert (net.lstm2.input_size, net.lstm2.num_layers) == (65 + D, 3)
    assert (net.fc1[0].out_features, net.fc2.out_features) == (65, D)


@pytest.mark.parametrize("activation,kind", [("tanh", "Tanh"), ("relu", "ReLU"), ("elu", "ELU")])
def test_activation_choice(activation, kind):
    net = make_net(activation=activation)
    names = {type(m).__name__ for m in net.modules()}
    assert kind in names and not ({"Tanh", "ReLU", "ELU"} - {kind}) & names


def test_config_is_validated():
    with pytest.raises(ValueError, match="activation"):
        YaltaConfig(output_dim=D, activation="sigmoid")
    with pytest.raises(ValueError, match="129x5"):
        YaltaConfig(output_dim=D, input_shape=(1, 257, 5))
    with pytest.raises(ValueError, match="positive"):
        YaltaConfig(output_dim=0)
    c = YaltaConfig(output_dim=7, units=9, activation="tanh")
    assert YaltaConfig.from_dict(c.to_dict()) == c


def test_predicted_feedback_feeds_back_the_previous_output():
    """Free-running equals teacher forcing whose 'true' previous poses are the model's own outputs."""
    net = make_net()
    audio = features(12, batch=2)
    first = torch.rand(2, D, generator=torch.Generator().manual_seed(3))
    with torch.no_grad():
        free = net(audio, first, "predicted")
        previous = torch.cat([first[:, None], free[:, :-1]], dim=1)
        teacher = net(audio, previous, "teacher")
    assert free.shape == (2, 12, D)
    torch.testing.assert_close(teacher, free, rtol=0, atol=1e-6)


@pytest.mark.parametrize("reset_every", [None, 7])
def test_recordings_run_free_together_equal_each_run_alone(reset_every):
    """free_runs pads the shorter recordings: each one's poses are still those the sequence
    network gives it alone (with its own first pose and the resets at the same frames)."""
    from kinectdata.models.yalta import free_run, free_runs

    net = make_net()
    audios = [features(n, seed=n).numpy() for n in (16, 9, 2)]
    firsts = [np.random.default_rng(n).uniform(-0.9, 0.9, D).astype(np.float32) for n in range(3)]
    together = free_runs(net, audios, firsts, reset_every)
    assert [g.shape for g in together] == [(15, D), (8, D), (1, D)]
    for audio, first, poses in zip(audios, firsts, together):
        pieces, previous = [], torch.from_numpy(first)[None]
        x = torch.from_numpy(audio[1:])[None]
        step = reset_every or x.shape[1]
        with torch.no_grad():  # the network's own predicted-feedback forward, piece by piece
            for s in range(0, x.shape[1], step):
                out = net(x[:, s : s + step], previous, "predicted")
                pieces.append(out[0].numpy())
                previous = out[:, -1]
        np.testing.assert_allclose(poses, np.concatenate(pieces), rtol=0, atol=1e-5)
        np.testing.assert_allclose(poses, free_run(net, audio, first, reset_every), rtol=0, atol=1e-6)


def test_outside_training_each_distinct_frame_is_convolved_once():
    """A song of one repeated frame (silence) and the zero padding of a shorter song: the codes
    are those every frame convolved gives (the path training takes), from far fewer frames."""
    net = make_net()
    audio = features(12, batch=3)
    audio[1] = audio[1, 0]  # one frame throughout
    audio[2, 5:] = 0  # padding
    seen = []
    net.convs[0].register_forward_hook(lambda module, inputs, output: seen.append(inputs[0].shape[0]))
    with torch.no_grad():
        codes, _ = net.encode(audio)
    with torch.enable_grad():
        every_frame, _ = net.encode(audio)
    torch.testing.assert_close(codes, every_frame.detach(), rtol=0, atol=1e-6)
    assert seen == [12 + 1 + 5 + 1, 36]
    seen.clear()
    with torch.no_grad():  # a dtype numpy has not: every frame, as before
        half, _ = net.to(torch.bfloat16).encode(audio.to(torch.bfloat16))
    assert seen == [36] and half.dtype == torch.bfloat16


def test_outputs_are_causal_in_the_audio():
    net = make_net()
    audio = features(10, batch=1)
    later = audio.clone()
    later[:, 6:] = features(4, batch=1, seed=9)
    first = torch.zeros(1, D)
    with torch.no_grad():
        a, b = net(audio, first), net(later, first)
    assert torch.equal(a[:, :6], b[:, :6]) and not torch.allclose(a[:, 6:], b[:, 6:])


def test_unknown_feedback_is_refused():
    with pytest.raises(ValueError, match="feedback"):
        make_net()(features(3, batch=1), torch.zeros(1, D), "oracle")


def stream_run(stream, audio, first):
    state = stream.initial_state()
    pose, out = first, []
    with torch.no_grad():
        for k in range(audio.shape[0]):
            pose, *state = stream(audio[k], pose, *state)
            out.append(pose)
    return torch.stack(out)


@pytest.mark.parametrize("activation", ["tanh", "relu", "elu"])
def test_streaming_network_equals_the_sequence_network(activation):
    """The hand-written cells and folded batch norm against torch's LSTM and BatchNorm2d."""
    net = make_net(activation=activation)
    audio = features(40)
    first = torch.rand(D, generator=torch.Generator().manual_seed(4))
    with torch.no_grad():
        expected = net(audio[None], first[None], "predicted")[0]
    got = stream_run(StreamingYalta(net), audio, first)
    torch.testing.assert_close(got, expected, rtol=0, atol=2e-6)


def test_torchscript_export_gives_the_same_outputs(tmp_path):
    net = make_net()
    audio = features(30)
    first = torch.rand(D, generator=torch.Generator().manual_seed(5))
    export_torchscript(net, tmp_path / "stream.ts", metadata={"fps": 30})
    extra = {"kinectdata.json": ""}
    loaded = torch.jit.load(str(tmp_path / "stream.ts"), _extra_files=extra)
    assert json.loads(extra["kinectdata.json"]) == {"fps": 30}
    with torch.no_grad():
        expected = net(audio[None], first[None])[0]
    torch.testing.assert_close(stream_run(loaded, audio, first), expected, rtol=0, atol=2e-6)


def test_onnx_export_runs_the_same_in_onnx_runtime(tmp_path):
    ort = pytest.importorskip("onnxruntime")
    pytest.importorskip("onnxscript")
    net = make_net()
    export_onnx(net, tmp_path / "stream.onnx", metadata={"fps": 30})
    session = ort.InferenceSession(str(tmp_path / "stream.onnx"), providers=["CPUExecutionProvider"])
    assert [i.name for i in session.get_inputs()] == INPUTS
    assert json.loads(session.get_modelmeta().custom_metadata_map["kinectdata"]) == {"fps": 30}
    audio = features(30)
    first = torch.rand(D, generator=torch.Generator().manual_seed(6))
    state = [s.numpy() for s in StreamingYalta(net).initial_state()]
    pose, got = first.numpy(), []
    for k in range(30):
        pose, *state = session.run(None, dict(zip(INPUTS, [audio[k].numpy(), pose, *state])))
        got.append(pose)
    with torch.no_grad():
        expected = net(audio[None], first[None])[0].numpy()
    np.testing.assert_allclose(np.array(got), expected, rtol=0, atol=2e-6)
    assert not list(tmp_path.glob("*.partial")) and not list(tmp_path.glob("*.data"))


def test_half_precision_weights_stay_close():
    net = make_net(units=64)
    audio = features(100)
    first = torch.zeros(D)
    full = stream_run(StreamingYalta(net, "float32"), audio, first)
    half = stream_run(StreamingYalta(net, "float16"), audio, first)
    assert half.dtype == torch.float32
    error = float((half - full).abs().max())
    assert 0 < error < 2e-3
    with pytest.raises(ValueError, match="precision"):  # a ConfigError, also a ValueError
        StreamingYalta(net, "int8")


def test_state_handed_to_another_engine_continues_the_stream():
    """Two engines, the second given the first's state and last pose half-way, equal one stream;
    reset() starts a stream afresh."""
    from kinectdata.inference.engines import TorchEngine

    net = make_net()
    audio, first = features(20).numpy(), np.zeros(D, np.float32)
    whole, pose = TorchEngine(net), first
    expected = []
    for k in range(20):
        pose = whole.step(audio[k], pose)
        expected.append(pose)
    a, b, pose, got = TorchEngine(net), TorchEngine(net), first, []
    for k in range(10):
        pose = a.step(audio[k], pose)
        got.append(pose)
    b.state = [s.clone() for s in a.state]
    for k in range(10, 20):
        pose = b.step(audio[k], pose)
        got.append(pose)
    np.testing.assert_array_equal(np.array(got), np.array(expected))
    whole.reset()
    np.testing.assert_array_equal(whole.step(audio[0], first), expected[0])
    with torch.no_grad():
        sequence = net(torch.from_numpy(audio)[None], torch.from_numpy(first)[None])[0]
    np.testing.assert_allclose(np.array(expected), sequence.numpy(), atol=2e-6)


def test_onnx_runtime_engine_equals_the_torch_engine_and_resets():
    from kinectdata.inference.engines import OnnxRuntimeEngine, TorchEngine, onnxruntime_available

    if not onnxruntime_available():
        pytest.skip("onnxruntime and onnxscript not installed")
    net = make_net()
    audio, first = features(15).numpy(), np.zeros(D, np.float32)
    engines = [TorchEngine(net), OnnxRuntimeEngine(net)]
    for _ in range(2):  # the second pass after reset() must repeat the first
        poses = [first, first]
        for k in range(15):
            poses = [e.step(audio[k], p) for e, p in zip(engines, poses)]
            np.testing.assert_allclose(poses[1], poses[0], atol=2e-6)
        for e in engines:
            e.reset()


def test_weights_are_buffers_that_move_with_the_module():
    stream = StreamingYalta(make_net())
    assert "lstm1.cells.0.weight" in stream.state_dict() and "fc2.bias" in stream.state_dict()
    moved = StreamingYalta(make_net()).to(torch.float64)
    x, first = features(3).double(), torch.zeros(D, dtype=torch.float64)
    state = moved.initial_state()
    assert state[0].dtype == torch.float64
    pose, *state = moved(x[0], first, *state)
    expected = stream_run(stream, features(3), torch.zeros(D))[0]
    assert pose.dtype == torch.float64
    np.testing.assert_allclose(pose.numpy(), expected.numpy(), atol=1e-6)
