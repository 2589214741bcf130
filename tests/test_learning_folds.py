"""``bench_learning --corpus tang2018 PATH --folds K`` end to end on a copy made in the corpus's shape:
each fold built, trained for a moment and scored on its own held-out dances, the test dances in
none, and the held-out dances of all the folds read together."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest
import yaml
from conftest import REPO
from corpus_copies import make_tang2018_copy

TEST_DANCES = {"C_2", "C_4", "R_2", "R_3", "T_5", "W_1", "W_3"}


@pytest.mark.slow
def test_folds_score_every_dance_outside_the_test_split_once(tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.learning_folds import run_folds

    corpus = make_tang2018_copy(tmp_path, seconds=8.0)
    small = {"sequence": 60, "stride": 60, "epochs": 1, "units": 16}
    summary = run_folds("tang2018", corpus, tmp_path / "out", 0.5, ["yalta"], [0], 2, changes={"yalta": small})
    printed = capsys.readouterr().out
    for fold in (1, 2):
        assert f"[yalta seed 0] fold {fold}: trained " in printed
        with h5py.File(next((tmp_path / "out" / f"fold{fold}" / "yalta_dataset").glob("val-*.h5")), "r") as f:
            assert f["current"].shape[0] > 0
        built = json.loads((tmp_path / "out" / f"fold{fold}" / "yalta_dataset" / "manifest.json").read_text())
        assert not {r["name"] for r in built["recordings"]} & TEST_DANCES  # the test dances in no fold
    assert "a. alive and human:" in printed and "c. listens:" in printed
    for protocol in ("bailando", "aist"):  # d against baselines made from each fold's own training dances
        assert f"d. FID_k against the mean pose + noise ({protocol}): " in printed
    assert "FID_k / the baseline's n/a" not in printed
    assert "[yalta seed 0] the 7 held-out dances of the 2 folds together:" in printed
    assert "dances in their song's style: " in printed
    listed = yaml.safe_load((tmp_path / "out" / "recordings.yaml").read_text())["recordings"]
    outside_test = sorted(r["name"] for r in listed if r["split"] != "test")
    runs = summary["yalta"][0]["runs"]
    assert sorted(runs) == outside_test and len(outside_test) == 7  # every dance outside the test split, once
    assert {Path(r).parent.name for r in runs.values()} == {"fold1", "fold2"}
    assert summary["yalta"][0]["real"][0].startswith("real follows the beat: ")
    assert summary["yalta"][0]["verdicts"][0].startswith("generated follows the beat: ")
