"""``--precision bfloat16``: the training step's forward pass under torch.autocast where the
device computes bfloat16 natively, the yalta model's LSTMs kept in float32, float32 with a warning
elsewhere; everything else in float32."""

from __future__ import annotations

import json

import pytest
from conftest import TINY_TRAINING

torch = pytest.importorskip("torch")

from kinectdata.core.errors import ConfigError  # noqa: E402
from kinectdata.models.yalta import YaltaConfig, YaltaNet  # noqa: E402
from kinectdata.training import train as training  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402

pytestmark = pytest.mark.usefixtures("one_thread")


def yalta_window(seed=0):
    torch.manual_seed(seed)
    net = YaltaNet(YaltaConfig(output_dim=6, units=16, input_shape=(1, 129, 5))).train()
    g = torch.Generator().manual_seed(seed + 1)
    return net, torch.rand(2, 12, 1, 129, 5, generator=g), torch.rand(2, 12, 6, generator=g) - 0.5


def test_under_bfloat16_the_yalta_convolutions_run_in_it_and_its_lstms_in_float32():
    net, audio, previous = yalta_window()
    seen = {}

    def dtype_of(name, output):
        def hook(module, inputs, out):
            seen[name] = (out if output else inputs[0]).dtype  # returns None: the output stays

        return hook

    net.convs.register_forward_hook(dtype_of("convs", output=True))
    for name in ("lstm1", "lstm2"):
        getattr(net, name).register_forward_hook(dtype_of(name, output=False))
    with torch.autocast("cpu", dtype=torch.bfloat16):
        poses, free = net(audio, previous, "teacher", free=True)
    assert seen == {"convs": torch.bfloat16, "lstm1": torch.float32, "lstm2": torch.float32}
    assert poses.dtype == free.dtype == torch.float32
    with torch.no_grad():  # the same network in float32: within bfloat16's rounding of the audio codes
        exact = net(audio, previous, "teacher")
    assert (poses - exact).abs().max() < 0.05
    assert not torch.equal(poses, exact)


def test_the_setting_is_checked_and_older_runs_trained_in_float32():
    assert TrainConfig("yalta").precision == "bfloat16"  # its convolutions are most of a step
    assert TrainConfig("yalta", paper=True).precision == TrainConfig("cdhc").precision == "float32"
    assert TrainConfig("yalta", precision="bfloat16").to_dict()["precision"] == "bfloat16"
    assert TrainConfig.from_dict({"model": "yalta"}).precision == "float32"
    with pytest.raises(ConfigError, match="precision must be float32 or bfloat16, not 'float16'"):
        TrainConfig("yalta", precision="float16")


@pytest.mark.skipif(
    not training.native_bfloat16(torch.device("cpu")), reason="hardware: this CPU has no native bfloat16"
)
def test_a_bfloat16_run_trains_and_keeps_its_weights_in_float32(sample_dataset, tmp_path):
    config = TrainConfig(**{**TINY_TRAINING, "units": 16, "epochs": 1, "feedback": "teacher", "precision": "bfloat16"})
    rows = training.train(sample_dataset, tmp_path / "bf16", config)
    exact = training.train(sample_dataset, tmp_path / "fp32", config.replace(precision="float32"))
    assert abs(rows[0]["train_loss"] - exact[0]["train_loss"]) < 0.1 * exact[0]["train_loss"]
    assert rows[0]["train_loss"] != exact[0]["train_loss"]  # the forward pass did run in bfloat16
    state = torch.load(tmp_path / "bf16" / "model.pt", weights_only=True)["model"]
    assert {v.dtype for v in state.values() if v.is_floating_point()} == {torch.float32}
    assert json.loads((tmp_path / "bf16" / "config.json").read_text())["train"]["precision"] == "bfloat16"


def test_without_native_bfloat16_it_warns_and_trains_in_float32(sample_dataset, tmp_path, monkeypatch):
    monkeypatch.setattr(training, "native_bfloat16", lambda device: False)
    config = TrainConfig(**{**TINY_TRAINING, "units": 16, "epochs": 1, "feedback": "teacher", "precision": "float32"})
    exact = training.train(sample_dataset, tmp_path / "fp32", config)
    with pytest.warns(training.TrainingWarning, match="no native bfloat16 .*: training in float32"):
        rows = training.train(sample_dataset, tmp_path / "asked", config.replace(precision="bfloat16"))
    assert rows[0]["train_loss"] == exact[0]["train_loss"]
