"""One model interface: a third model, defined here and registered for these tests only, trains,
evaluates, generates and exports through the same loops as the bundled ones; and nothing outside
``kinectdata/models/`` branches on a model's name or network class."""

import ast
import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

torch = pytest.importorskip("torch")
from torch import nn  # noqa: E402

import kinectdata  # noqa: E402
from kinectdata.core.errors import ConfigError, KinectDataError  # noqa: E402
from kinectdata.models.kind import ModelKind  # noqa: E402
from kinectdata.models.losses import masked_mse  # noqa: E402
from kinectdata.models.registry import (  # noqa: E402
    MODELS,
    check_fits,
    model_kind,
    register_model,
    unregister_model,
)

SONG = REPO / "sample_data" / "synth_001.flac"


@dataclass(frozen=True)
class TinySettings:
    hidden: int = field(default=8, metadata={"help": "GRU units.", "min": 1})

    def __post_init__(self) -> None:
        if self.hidden < 1:
            raise ConfigError(f"hidden must be positive, not {self.hidden}")


class TinyNet(nn.Module):
    """Per frame: the features flattened to a tanh code; a GRU over [code, previous pose]; a linear pose."""

    def __init__(self, config: dict):
        super().__init__()
        self.config = config
        self.code = nn.Linear(int(np.prod(config["feature_shape"])), config["hidden"])
        self.gru = nn.GRU(config["hidden"] + config["output_dim"], config["hidden"], batch_first=True)
        self.out = nn.Linear(config["hidden"], config["output_dim"])

    def forward(self, audio: torch.Tensor, previous: torch.Tensor, state: torch.Tensor | None = None):
        """audio [B, L, *F], previous [B, L, D], GRU state [1, B, H] -> ([B, L, D] poses, new state)."""
        hidden, state = self.gru(torch.cat([torch.tanh(self.code(audio.flatten(2))), previous], -1), state)
        return self.out(hidden), state


class TinyStream(nn.Module):
    """One unbatched frame: (features [*F], previous [D], h [1, 1, H]) -> (pose [D], h)."""

    def __init__(self, net: TinyNet):
        super().__init__()
        self.net = net
        self.hidden = int(net.config["hidden"])

    @torch.jit.export
    def initial_state(self) -> tuple[torch.Tensor]:
        return (torch.zeros(1, 1, self.hidden),)

    def forward(self, features: torch.Tensor, previous: torch.Tensor, h: torch.Tensor):
        pose, h = self.net(features[None, None], previous[None, None], h)
        return pose[0, 0], h


class TinyKind(ModelKind):
    name = "tiny_gru"
    description = "a tiny GRU (tests)"
    settings_type = TinySettings
    network_type = TinyNet
    training_defaults = {"sequence": 30, "batch_size": 8, "epochs": 1, "lr": 3e-3, "noise_eta": 0.0}
    streams = True
    engines = {"torch": ("float32",)}
    exports = ("torchscript",)
    run_exports = {"tiny.ts": "torchscript"}
    state_names = ("h",)

    def check_dataset(self, manifest):
        if manifest["normalisation"]["method"] == "none":
            raise ConfigError("the tiny_gru model wants normalised targets")

    def network_config(self, settings, manifest):
        return {"feature_shape": manifest["feature_shape"], "output_dim": manifest["target_dim"], **vars(settings)}

    def build(self, config):
        return TinyNet(config)

    def predict(self, net, audio, previous, settings, context=0):
        return net(audio, previous)[0][:, context:]  # teacher forcing; a recurrent net steps its context

    def loss(self, net, pred, pose, mask, settings):
        return masked_mse(pred, pose, mask)

    def init_output(self, net, start_pose):
        with torch.no_grad():
            net.out.bias.copy_(torch.tensor(start_pose))

    def free_run(self, net, audio, first_pose, reset_every=None):
        x = torch.from_numpy(np.ascontiguousarray(audio[1:], np.float32))[None]
        pose, state, poses = torch.as_tensor(first_pose, dtype=torch.float32)[None, None], None, []
        with torch.no_grad():
            for t in range(x.shape[1]):
                pose, state = net(x[:, t : t + 1], pose, state)
                poses.append(pose[0, 0].numpy())
        return np.stack(poses)

    def stream(self, net, precision="float32"):
        return TinyStream(net.eval())

    def describe(self, settings):
        return f"tiny GRU, {settings.hidden} units"


class WholeKind(TinyKind):
    """The same network run free over the whole song: a model that does not stream."""

    name = "tiny_whole"
    streams = False
    engines = {}
    exports = ()
    run_exports = {}


@pytest.fixture(scope="module")
def tiny():
    kinds = register_model(TinyKind()), register_model(WholeKind())
    yield kinds
    for kind in kinds:
        unregister_model(kind.name)


@pytest.fixture(scope="module")
def tiny_run(tiny, sample_dataset, tmp_path_factory):
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    run = tmp_path_factory.mktemp("tiny") / "run"
    history = train(sample_dataset, run, TrainConfig.for_model("tiny_gru", hidden=6))
    return run, history


def test_a_registered_model_trains_with_its_own_settings_and_writes_its_files(tiny_run):
    from kinectdata.models.run import load_model

    run, history = tiny_run
    assert len(history) == 1 and np.isfinite(history[0]["train_loss"]) and np.isfinite(history[0]["val_smape"])
    config = json.loads((run / "config.json").read_text())
    assert config["train"]["model"] == "tiny_gru" and config["train"]["hidden"] == 6
    assert config["train"]["sequence"] == 30 and "units" not in config["train"]  # its defaults, not yalta's
    assert config["model"]["hidden"] == 6
    net, _ = load_model(run)
    assert isinstance(net, TinyNet)
    assert (run / "tiny.ts").is_file() and not (run / "stream.ts").exists()
    scripted = torch.jit.load(str(run / "tiny.ts"), _extra_files=(extra := {"kinectdata.json": ""}))
    meta = json.loads(extra["kinectdata.json"])
    assert meta["model"] == "tiny_gru" and meta["outputs"] == ["pose", "h_out"]
    frame, pose = torch.rand(1, 129, 5), torch.tensor(meta["start_pose"], dtype=torch.float32)
    expected, _ = TinyStream(net)(frame, pose, *TinyStream(net).initial_state())
    got, _ = scripted(frame, pose, *scripted.initial_state())
    torch.testing.assert_close(got, expected)


def test_it_evaluates_and_generates_and_a_model_that_does_not_stream_too(tiny_run, sample_dataset, tmp_path):
    from kinectdata.evaluation.evaluate import evaluate
    from kinectdata.inference.export import export_run
    from kinectdata.inference.generate import generate

    run, _ = tiny_run
    results = evaluate(run, sample_dataset, "test", out=tmp_path / "e", silence_seconds=2.0, timing_frames=20)
    assert list(results["smape"]) == ["without_reset"] and 0 < results["smape"]["without_reset"]["smape_normalised"]
    assert list(results["forward_time"]) == ["torch float32"]
    motion, timing = generate(run, SONG, tmp_path / "dance.csv")
    assert motion.n_frames == timing["frames"] and (tmp_path / "dance.csv").is_file()
    with pytest.raises(KinectDataError, match="runs on torch with float32 weights only"):
        generate(run, SONG, engine="torch", precision="float16")
    with pytest.raises(KinectDataError, match="the tiny_gru model has no onnx export"):
        export_run(run, tmp_path / "x.onnx")

    whole = tmp_path / "whole"  # the same weights under the model that runs free over the whole song
    shutil.copytree(run, whole)
    config = json.loads((whole / "config.json").read_text())
    config["train"]["model"] = "tiny_whole"
    (whole / "config.json").write_text(json.dumps(config))
    again, _ = generate(whole, SONG)
    np.testing.assert_allclose(again.positions, motion.positions, atol=1e-5, equal_nan=True)
    results = evaluate(whole, sample_dataset, "test", out=tmp_path / "w", silence_seconds=2.0)
    assert results["forward_time"] == {} and "silence_test" in results


def test_settings_and_datasets_are_checked_by_the_model(tiny, sample_dataset):
    from kinectdata.models.run import read_manifest
    from kinectdata.training.config import TrainConfig

    config = TrainConfig("tiny_gru", hidden=5, epochs=2)
    assert (config.hidden, config.sequence, config.epochs) == (5, 30, 2)
    assert TrainConfig.from_dict(config.to_dict()) == config
    with pytest.raises(ConfigError, match="the tiny_gru model has no setting units"):
        TrainConfig.for_model("tiny_gru", units=3)
    with pytest.raises(ConfigError, match="hidden must be positive"):
        TrainConfig("tiny_gru", hidden=0)
    manifest = read_manifest(sample_dataset)
    manifest["normalisation"] = {**manifest["normalisation"], "method": "none"}
    with pytest.raises(ConfigError, match=r"ds: the tiny_gru model wants normalised targets \(use --model yalta"):
        check_fits(model_kind("tiny_gru"), manifest, "ds")
    with pytest.raises(ConfigError, match="already registered"):
        register_model(WholeKind())


def test_the_registry_lists_and_forgets_a_model():
    class Gone(TinyKind):
        name = "gone"

    register_model(Gone())
    try:
        assert "gone" in MODELS
    finally:
        unregister_model("gone")
    assert "gone" not in MODELS
    with pytest.raises(ConfigError, match="unknown model 'gone'; known: yalta, cdhc"):
        model_kind("gone")

    class Incomplete:
        name = "incomplete"

    with pytest.raises(ConfigError, match="is not a model kind: it has no description, settings_type"):
        register_model(Incomplete())


NETWORK_NAMES = {"YaltaNet", "CdhcNet", "StreamingYalta", "StreamingCdhc", "FrameCdhc", "YaltaKind", "CdhcKind"}
NETWORK_MODULES = {"kinectdata.models.yalta", "kinectdata.models.cdhc", "kinectdata.models.bundled"}
MODEL_DATA = {Path("dataset/pipelines.py")}  # PIPELINES: which model each pipeline's datasets train


def test_nothing_outside_the_models_branches_on_a_model():
    """No model's name as a string, no model's network class or module, outside kinectdata/models/
    (the pipelines' table names the model of each pipeline: data, the one mapping)."""
    package = Path(kinectdata.__file__).parent
    names = set(MODELS)
    found = []
    for path in sorted(package.rglob("*.py")):
        where = path.relative_to(package)
        if where.parts[0] == "models":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and node.value in names and where not in MODEL_DATA:
                found.append(f"{where}:{node.lineno}: {node.value!r}")
            elif isinstance(node, ast.Name | ast.Attribute | ast.alias):
                name = (
                    node.id
                    if isinstance(node, ast.Name)
                    else node.attr
                    if isinstance(node, ast.Attribute)
                    else node.name
                )
                if name in NETWORK_NAMES:
                    found.append(f"{where}:{getattr(node, 'lineno', '?')}: {name}")
            elif isinstance(node, ast.ImportFrom) and node.module in NETWORK_MODULES:
                found.append(f"{where}:{node.lineno}: from {node.module}")
    assert not found, "\n".join(found)


def test_recordings_are_run_free_in_bounded_batches_of_similar_length():
    from kinectdata.models.kind import run_batches

    assert run_batches([5, 100, 7, 90], max_frames=300, max_batch=32) == [[0, 2, 3], [1]]
    assert run_batches([10] * 5, max_batch=2) == [[0, 1], [2, 3], [4]]
    assert run_batches([50_000, 10]) == [[1], [0]]  # one recording longer than the cap runs alone
    assert run_batches([]) == []


class OlderKind(TinyKind):
    """A kind written before ``predict`` took the window's context."""

    name = "tiny_older"

    def predict(self, net, audio, previous, settings):
        return net(audio, previous)[0]


def test_a_kind_written_before_predict_took_the_context_still_trains_on_the_frames_after_it(sample_dataset, tmp_path):
    from kinectdata.training import train as training
    from kinectdata.training.config import TrainConfig

    seen = []  # the shapes the loss is given
    register_model(OlderKind())
    try:
        kind = training.model_kind("tiny_older")
        original = kind.loss
        kind.loss = lambda net, pred, pose, mask, settings: (
            seen.append((pred.shape, pose.shape)) or original(net, pred, pose, mask, settings)
        )
        history = training.train(sample_dataset, tmp_path / "run", TrainConfig.for_model("tiny_older", context=5))
    finally:
        unregister_model("tiny_older")
    assert np.isfinite(history[0]["train_loss"])
    pred_shape, pose_shape = seen[0]
    assert pred_shape == pose_shape and pred_shape[1] == 30  # the window's 30 counted frames, its 5 of context cut
