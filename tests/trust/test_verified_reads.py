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


def test_a_shard_with_one_changed_value_is_refused_before_training(dataset, tmp_path):
    shard = dataset / "train-00000.h5"
    with h5py.File(shard, "r") as f:  # where the first target value lies in the file (h5py's own account)
        chunk = f["current"].id.get_chunk_info(0)
        assert f["current"].compression is None  # stored as is: a byte of the file is a byte of a value
        offset = chunk.byte_offset
    raw = bytearray(shard.read_bytes())
    raw[offset + 3] ^= 0xFF  # one value's sign and exponent: about -1e38 from a small number
    shard.write_bytes(bytes(raw))
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


def test_resume_refuses_a_damaged_checkpoint_and_keeps_the_model(sample_dataset, tmp_path):
    run = tmp_path / "run"
    train(sample_dataset, run, TrainConfig(**TINY_TRAINING))
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
    assert (run / "model.pt").read_bytes() == model_before
    save_checkpoint(tmp_path / "again.pt", {"x": torch.ones(2)})
    assert torch.equal(load_checkpoint(tmp_path / "again.pt")["x"], torch.ones(2))
