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

from kinectdata.dataset.build import EmptySplitWarning

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


@pytest.mark.slow
def test_a_candidate_runs_on_the_folds_it_names_from_the_command_line(tmp_path, monkeypatch, capsys, recwarn):
    """``--fold 2 --set ... --features yalta=PRESET --tag cand``: only fold 2 built and trained, with
    the preset's features in a dataset of its own, the settings in the run's config, the run named
    by the tag; no warning that the fold's dataset has no test split (it has none by design)."""
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.bench_learning import main

    corpus = make_tang2018_copy(tmp_path, seconds=8.0)
    out = tmp_path / "out"
    small = ["--set", "sequence=60", "--set", "stride=60", "--set", "epochs=1", "--set", "units=16"]
    candidate = ["--set", "bend_weight=10", "--set", "inputs=music", "--set", "facing=true"]
    main(["--corpus", "tang2018", str(corpus), "--folds", "2", "--fold", "2", "--models", "yalta", "--out", str(out),
          "--minutes", "0.5", "--threads", "1", "--features", "yalta=yalta2016_rhythm_style", "--tag", "cand",
          *small, *candidate])  # fmt: skip
    printed = capsys.readouterr().out
    assert "[yalta seed 0] fold 2: trained " in printed and "fold 1: trained" not in printed
    assert "    epoch   1 step " in printed  # each epoch shown as it ends, as the acceptance run shows it
    assert not (out / "fold1").exists()  # the fold not named is neither built nor trained
    built = json.loads((out / "fold2" / "yalta-yalta2016_rhythm_style_dataset" / "manifest.json").read_text())
    assert built["feature_shape"] == [6, 129, 5]  # spectra, pulse, a plane per style: not [2, ...]
    trained = json.loads((out / "fold2" / "yalta-cand-seed0" / "config.json").read_text())["train"]
    assert (trained["bend_weight"], trained["inputs"], trained["facing"], trained["units"]) == (10, "music", True, 16)
    assert (out / "learning_folds-cand.json").is_file()
    assert not [w for w in recwarn if issubclass(w.category, EmptySplitWarning)]

    # scored again without training (after a change to what is drawn at generation): the run kept
    import benchmarks.learning_real as real

    monkeypatch.setattr(real, "train", lambda *a, **k: pytest.fail("--rescore trained"))
    model = (out / "fold2" / "yalta-cand-seed0" / "model.pt").read_bytes()
    main(["--corpus", "tang2018", str(corpus), "--folds", "2", "--fold", "2", "--models", "yalta", "--out", str(out),
          "--threads", "1", "--features", "yalta=yalta2016_rhythm_style", "--tag", "cand", "--rescore"])  # fmt: skip
    printed = capsys.readouterr().out
    assert f"[yalta seed 0] fold 2: the run in {out / 'fold2' / 'yalta-cand-seed0'}, not trained again" in printed
    assert "d. FID_k against the mean pose + noise (aist): " in printed
    assert (out / "fold2" / "yalta-cand-seed0" / "model.pt").read_bytes() == model


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--set", "bend_weight=10"], "--set tries a candidate on the folds: give --folds K"),
        (["--folds", "3", "--set", "bend_weight"], "--set takes NAME=VALUE, not 'bend_weight'"),
        (["--folds", "3", "--fold", "1,x"], "--fold takes whole numbers separated by commas, not '1,x'"),
        (["--folds", "3", "--features", "cdhc=x", "--models", "yalta"], "--features names cdhc, a model not in"),
        (["--folds", "3", "--threads", "0"], "--threads takes a whole number of at least 1, not 0"),
    ],
)
def test_a_candidate_given_wrongly_is_refused_in_one_line(tmp_path, monkeypatch, capsys, argv, said):
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.bench_learning import main

    with pytest.raises(SystemExit) as stopped:
        main(["--corpus", "tang2018", str(tmp_path), "--allow-librosa", *argv])
    assert stopped.value.code == 2
    assert said in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--fold", "4"], "there is no fold 4 of 3 (the folds are numbered 1-3)"),
        (["--set", "bendy=3"], "the yalta model has no setting bendy"),
        ([], "not a folder"),
    ],
)
def test_a_fault_found_once_running_stops_in_one_line_before_anything_is_built(
    tmp_path, monkeypatch, capsys, argv, said
):
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.bench_learning import main

    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stopped:
        main(["--corpus", "tang2018", str(tmp_path / "missing"), "--folds", "3", "--models", "yalta",
              "--allow-librosa", "--out", str(out), *argv])  # fmt: skip
    assert stopped.value.code == 1
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not list(out.glob("fold*"))
