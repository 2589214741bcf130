"""Nothing trains on, or is scored against, a damaged dataset or checkpoint."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import TINY_TRAINING

torch = pytest.importorskip("torch")

from kinectdata.cli import main  # noqa: E402
from kinectdata.core.errors import KinectDataError  # noqa: E402
from kinectdata.dataset.windows import WindowDataset  # noqa: E402
from kinectdata.models.run import load_checkpoint, save_checkpoint, state_digest  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402
from kinectdata.training.train import train  # noqa: E402


@pytest.fixture
def dataset(sample_dataset, tmp_path):
    copy = tmp_path / "dataset"
    shutil.copytree(sample_dataset, copy)
    return copy


def flip_first_value(shard):
    """One changed byte in a target value of the shard: its sign and exponent's, so that the value
    becomes about -2e38, as in the damaged shard of issue 15; the layout and size stay."""
    with h5py.File(shard, "r") as f:  # where the first chunk of targets lies in the file (h5py's own account)
        chunk = f["current"].id.get_chunk_info(0)
        assert f["current"].compression is None  # stored as is: a byte of the file is a byte of a value
    raw = bytearray(shard.read_bytes())
    values = np.frombuffer(bytes(raw[chunk.byte_offset : chunk.byte_offset + chunk.size]), "<f4")
    at = next(
        chunk.byte_offset + 4 * i
        for i, v in enumerate(values)
        if 0 < abs(v) < 10 and not raw[chunk.byte_offset + 4 * i + 2] & 0x80
    )
    raw[at + 3] = 0xFF  # sign 1, exponent 254 (with the next byte's top bit 0): -(1..2) x 2^127
    shard.write_bytes(bytes(raw))
    with h5py.File(shard, "r") as f:
        assert int((f["current"][()] < -1e38).sum()) == 1


def test_a_shard_with_one_changed_value_is_refused_before_training(dataset, tmp_path):
    shard = dataset / "train-00000.h5"
    flip_first_value(shard)
    with pytest.raises(KinectDataError, match="train-00000.h5: checksum differs from the manifest's"):
        train(dataset, tmp_path / "run", TrainConfig(**TINY_TRAINING))
    assert not (tmp_path / "run").exists()
    with pytest.raises(KinectDataError, match="checksum differs"):
        WindowDataset(dataset, "train", 30)
    WindowDataset(dataset, "train", 30, checksums=False)  # the layout is intact: the user may choose
    result = CliRunner().invoke(main, ["train-baseline", "--data", str(dataset), "--out", str(tmp_path / "cli")])
    assert result.exit_code == 1 and "checksum differs" in result.stderr and "Traceback" not in result.output


def test_a_truncated_or_missing_shard_is_one_clear_line(dataset, trained_run, tmp_path):
    shard = dataset / "test-00000.h5"
    shard.write_bytes(shard.read_bytes()[: shard.stat().st_size // 2])
    result = CliRunner().invoke(main, ["train-baseline", "--data", str(dataset), "--out", str(tmp_path / "r")])
    assert (
        result.exit_code == 1 and "test-00000.h5: is" in result.stderr and "bytes, the manifest says" in result.stderr
    )
    shard.unlink()
    run, _ = trained_run
    result = CliRunner().invoke(
        main, ["evaluate", "--run", str(run), "--data", str(dataset), "--out", str(tmp_path / "e")]
    )
    assert result.exit_code == 1 and "test-00000.h5: missing: manifest.json lists it" in result.stderr
    assert not (tmp_path / "e").exists()


def test_the_checkpoint_digest_covers_every_tensor_byte_and_value():
    state = {"model": {"w": torch.arange(6.0).reshape(2, 3)}, "epoch": 3, "rng": torch.get_rng_state()}
    same = {"epoch": 3, "rng": torch.get_rng_state(), "model": {"w": torch.arange(6.0).reshape(2, 3)}}
    assert state_digest(state) == state_digest(same)  # key order does not matter
    changed = {**state, "model": {"w": state["model"]["w"].clone()}}
    changed["model"]["w"][1, 2] = float(np.nextafter(np.float32(5.0), np.float32(6.0)))  # one ulp
    assert state_digest(changed) != state_digest(state)
    assert state_digest({**state, "epoch": 4}) != state_digest(state)


def test_resume_refuses_a_damaged_checkpoint_and_keeps_the_model(trained_run, sample_dataset, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(trained_run[0], run)  # a TINY_TRAINING run of sample_dataset, damaged below
    model_before = (run / "model.pt").read_bytes()
    checkpoint = run / "checkpoint.pt"
    state = load_checkpoint(checkpoint)
    weights = next(v for v in state["model"].values() if v.numel() > 100)
    needle = weights.reshape(-1)[50:54].numpy().tobytes()  # the tensor's bytes, found in the file
    raw = bytearray(checkpoint.read_bytes())
    at = raw.find(needle)
    assert at > 0
    raw[at + 1] ^= 0x10
    raw[at + 6] ^= 0x01  # two flipped bits of two weights
    checkpoint.write_bytes(bytes(raw))
    with pytest.raises(KinectDataError, match="checkpoint.pt: damaged: its content differs from the SHA-256"):
        train(sample_dataset, run, TrainConfig(**{**TINY_TRAINING, "epochs": 3}), resume=True)
    result = CliRunner().invoke(main, ["train-baseline", "--data", str(sample_dataset), "--out", str(run), "--resume"])
    errors = [line for line in result.stderr.splitlines() if not line.startswith("warning: ")]
    assert result.exit_code == 1 and len(errors) == 1 and f"{checkpoint}: damaged: its content differs" in errors[0]
    assert (run / "model.pt").read_bytes() == model_before
    save_checkpoint(tmp_path / "again.pt", {"x": torch.ones(2)})
    assert torch.equal(load_checkpoint(tmp_path / "again.pt")["x"], torch.ones(2))


def test_no_checksums_skips_only_the_hashing_in_every_reader(dataset, trained_run, tmp_path, monkeypatch):
    """With a changed value and the layout intact, each command refuses by default and goes on past
    the check with --no-checksums (up to a planted stop just after it); a truncated shard is refused
    with --no-checksums too (sizes and layout are always checked)."""
    import kinectdata.evaluation.evaluate as evaluate_module
    import kinectdata.training.sweep as sweep_module
    import kinectdata.training.train as train_module

    def planted(*args, **kwargs):
        raise KinectDataError("planted: past the check")

    monkeypatch.setattr(train_module, "check_fits", planted)
    monkeypatch.setattr(evaluate_module, "interface_mismatch", planted)
    monkeypatch.setattr(sweep_module, "model_kind", planted)
    flip_first_value(dataset / "train-00000.h5")
    run, _ = trained_run
    tiny = ["--units", "32", "--sequence", "30", "--batch-size", "8", "--epochs", "1"]
    commands = {
        "train-baseline": ["train-baseline", "--data", str(dataset), "--out", str(tmp_path / "t"), *tiny],
        "evaluate": ["evaluate", "--run", str(run), "--data", str(dataset), "--out", str(tmp_path / "e")],
        "sweep": ["sweep", "--data", str(dataset), "--out", str(tmp_path / "s"), "--model", "yalta", *tiny],
    }
    for name, command in commands.items():
        refused = CliRunner().invoke(main, command)
        assert refused.exit_code == 1 and "train-00000.h5: checksum differs" in refused.stderr, (name, refused.output)
        passed = CliRunner().invoke(main, [*command, "--no-checksums"])
        assert passed.exit_code == 1 and "planted: past the check" in passed.stderr, (name, passed.output)
    shard = dataset / "val-00000.h5"
    shard.write_bytes(shard.read_bytes()[:-100])
    for name, command in commands.items():
        result = CliRunner().invoke(main, [*command, "--no-checksums"])
        assert result.exit_code == 1 and "val-00000.h5: is" in result.stderr, (name, result.output)
    assert not any((tmp_path / d).exists() for d in ("t", "e", "s"))
