"""Balanced training windows (``--balance``): each group of windows gets the same share of an epoch."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.core.errors import ConfigError, KinectDataError  # noqa: E402
from kinectdata.dataset.windows import WindowDataset  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402
from kinectdata.training.distributed import PaddedWindows, WindowSampler, World  # noqa: E402

# (name, frames, style, beats per bar): three long waltzes and two short cha-chas
RECORDINGS = [("W_1", 1000, "waltz", 3), ("W_2", 900, "waltz", 3), ("W_3", 1100, "waltz", 3)]
RECORDINGS += [("C_1", 400, "cha-cha", 4), ("C_2", 300, "cha-cha", None)]


def _windows(tmp_path, length=100, stride=50, made=RECORDINGS) -> WindowDataset:
    """A dataset folder holding only a manifest (windows are listed from it; no shard is read)."""
    start, recordings, inputs = 0, [], []
    for name, frames, style, bar in made:
        recordings.append({"name": name, "split": "train", "shard": "train-00000.h5", "start": start, "frames": frames})
        inputs.append({"name": name, "style": style, "beats_per_bar": bar})
        start += frames
    (tmp_path / "manifest.json").write_text(json.dumps({"recordings": recordings, "inputs": inputs}))
    return WindowDataset(tmp_path, "train", length, stride, verify=False)


def _expected_count(frames, length=100, stride=50):
    return len(range(1, frames - length, stride))


def test_each_group_gets_the_same_share(tmp_path):
    windows = _windows(tmp_path)
    groups = windows.groups("style")
    assert Counter(groups) == {
        "waltz": sum(_expected_count(f) for _, f, s, _ in RECORDINGS if s == "waltz"),
        "cha-cha": sum(_expected_count(f) for _, f, s, _ in RECORDINGS if s == "cha-cha"),
    }
    weights = windows.balanced_weights("style")
    assert weights.shape == (len(windows),) and weights.sum() == pytest.approx(1.0)
    for style in ("waltz", "cha-cha"):
        assert weights[np.array(groups) == style].sum() == pytest.approx(0.5)
    # by recording: five equal shares, however long each recording is
    by_recording = windows.balanced_weights("recording")
    for name, *_ in RECORDINGS:
        assert by_recording[np.array(windows.recordings) == name].sum() == pytest.approx(0.2)
    # a recording whose manifest entry has no metre is a group of its own (unknown), not dropped
    assert Counter(windows.groups("beats_per_bar"))[None] == _expected_count(300)
    by_metre = windows.balanced_weights("beats_per_bar")
    assert by_metre[np.array(windows.recordings) == "C_2"].sum() == pytest.approx(1 / 3)


def test_one_group_is_nothing_to_balance_and_an_unknown_field_is_refused(tmp_path):
    assert _windows(tmp_path, made=RECORDINGS[:3]).balanced_weights("style") is None  # waltzes only
    with pytest.raises(KinectDataError, match="cannot group windows by 'tempo'"):
        _windows(tmp_path).groups("tempo")
    with pytest.raises(ConfigError, match="balance must be one of recording, style, beats_per_bar"):
        TrainConfig("yalta", balance="tempo")
    assert TrainConfig("yalta", balance="none").balance is None
    assert TrainConfig.from_dict(TrainConfig("cdhc", balance="style").to_dict()).balance == "style"


def test_the_sampler_draws_the_groups_evenly_and_the_ranks_share_one_order(tmp_path):
    windows = _windows(tmp_path)
    groups = np.array(windows.groups("style"))
    weights = windows.balanced_weights("style")
    padded = PaddedWindows(windows)
    one = WindowSampler(padded, World(rank=0, size=1, local_rank=0), torch.Generator().manual_seed(5), weights)
    drawn = np.concatenate([list(one) for _ in range(300)])
    assert len(drawn) == 300 * len(windows)
    share = np.mean(groups[drawn] == "cha-cha")
    assert share == pytest.approx(0.5, abs=0.01)  # unbalanced, the cha-chas are 9 of 57 windows
    assert np.mean(groups == "cha-cha") < 0.2
    # two ranks: entries 0, 2, 4... and 1, 3, 5... of the same draws as one process's
    ranks = [
        WindowSampler(padded, World(rank=r, size=2, local_rank=r), torch.Generator().manual_seed(5), weights)
        for r in (0, 1)
    ]
    first = list(WindowSampler(padded, World(rank=0, size=1, local_rank=0), torch.Generator().manual_seed(5), weights))
    a, b = (list(s) for s in ranks)
    merged = [x for pair in zip(a, b) for x in pair][: len(first)]
    assert merged == first


def test_without_weights_the_order_is_a_shuffled_dataloaders(tmp_path):
    windows = _windows(tmp_path)
    padded = PaddedWindows(windows)
    sampler = WindowSampler(padded, World(rank=0, size=1, local_rank=0), torch.Generator().manual_seed(3))
    reference = torch.utils.data.RandomSampler(range(len(windows)), generator=torch.Generator().manual_seed(3))
    assert list(sampler) == list(reference)
