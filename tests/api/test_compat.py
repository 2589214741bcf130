"""Files written before the package was regrouped (tests/data/v0.1, made by commit 925c15e) still
read, and the regrouped code computes the same dataset rows from the same aligned file."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from conftest import DATA

from kinectdata.align.aligned import AlignedRecording, Provenance
from kinectdata.align.offset import OffsetChoice
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.config import BuildConfig
from kinectdata.dataset.verify import verify_dataset

OLD = DATA / "v0.1"


def test_an_aligned_file_of_v01_reads_with_typed_offset_and_provenance():
    rec = AlignedRecording.load(OLD / "synth_003.h5")
    assert isinstance(rec.offset, OffsetChoice) and isinstance(rec.provenance, Provenance)
    assert rec.offset.source in ("clap", "xcorr") and rec.offset.seconds == pytest.approx(0.4, abs=1 / 30)
    assert len(rec.provenance.motion["sha256"]) == 64 and rec.provenance.options["sample_rate"] == 16000
    assert rec.fps == 30 and rec.sample_rate == 16000 and rec.n_frames > 200


def test_a_dataset_of_v01_verifies_and_gives_windows():
    pytest.importorskip("torch")
    from kinectdata.dataset import WindowDataset

    assert verify_dataset(OLD / "dataset") == []
    windows = WindowDataset(OLD / "dataset", "train", 30, 30)
    assert len(windows) == 214 // 30 and windows[0]["audio"].shape == (30, 1, 129, 5)


def test_the_same_aligned_file_builds_the_same_rows_as_v01(tmp_path):
    source = tmp_path / "aligned"
    source.mkdir()
    shutil.copy(OLD / "synth_003.h5", source)
    config = BuildConfig.from_pipeline("yalta2016", split_ratios=(1, 0, 0), compression="gzip")
    build_dataset(source, tmp_path / "dataset", config)
    with (
        h5py.File(OLD / "dataset" / "train-00000.h5") as old,
        h5py.File(tmp_path / "dataset" / "train-00000.h5") as new,
    ):
        for name in ("input", "current", "mask", "audio_padded"):
            np.testing.assert_array_equal(new[name][()], old[name][()], err_msg=name)
        for key in ("normalisation", "features", "target_spec"):
            assert new.attrs[key] == old.attrs[key], key
