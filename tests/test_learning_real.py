"""``bench_learning --corpus tang2018 PATH`` end to end on a copy made in the corpus's shape (the
corpus itself has no licence): both models built, trained for a moment, scored on the test
dances, and issue 25's goals printed with their figures."""

from __future__ import annotations

import json

import pytest
from conftest import REPO
from corpus_copies import make_tang2018_copy


@pytest.mark.slow
def test_the_real_corpus_benchmark_prints_every_goal(tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(REPO))
    import benchmarks.learning_real as bench
    from benchmarks.learning_real import run

    evaluated = {}

    def remembered(run_dir, *args, **kwargs):
        evaluated[run_dir] = (args, kwargs, real_evaluate(run_dir, *args, **kwargs))
        return evaluated[run_dir][2]

    real_evaluate = bench.evaluate
    monkeypatch.setattr(bench, "evaluate", remembered)

    corpus = make_tang2018_copy(tmp_path, seconds=8.0)
    small = {"sequence": 60, "stride": 60, "epochs": 1}
    tiny_cdhc = {"channels": 16, "decoder_channels": 16, "context": 30}  # 8-s songs: no room for 264 frames
    changes = {"yalta": {**small, "units": 16}, "cdhc": {**small, **tiny_cdhc}}
    summary = run("tang2018", corpus, tmp_path / "out", 0.01, ["yalta", "cdhc"], 0, bootstrap=0, changes=changes)
    printed = capsys.readouterr().out
    for model in ("yalta", "cdhc"):
        assert f"[{model}] goals:" in printed
        goals = [goal for goal, _, _ in summary[model]["goals"]]
        assert goals[:3] == ["a. alive and human", "b. no fixed oscillator", "c. listens"], goals
        assert any(g.startswith("d. beats the mean pose + noise (bailando)") for g in goals), goals
        assert any(g.startswith("d. beats the mean pose + noise (aist)") for g in goals), goals
        assert (tmp_path / "out" / f"learning-real-{model}.png").is_file()
    for model, shape in (("yalta", [2, 129, 5]), ("cdhc", [153])):  # spectra (or mel) with the pulse
        built = json.loads((tmp_path / "out" / f"{model}_dataset" / "manifest.json").read_text())
        assert built["feature_shape"] == shape, (model, built["feature_shape"])
    saved = json.loads((tmp_path / "out" / "learning_real.json").read_text())
    assert set(saved) == {"yalta", "cdhc"}
    assert "model.pt from epoch 1 (lowest free-running validation rhythm loss among the epochs moving at" in printed
    assert "the noise at each test song's own speed (an oracle): FID_k" in printed

    # scored again without training: the run's own log read back, its evaluation asked for as before
    # (evaluate's figures are its tests'; here the answer it gave the first time stands in for it)
    def again_as_before(run_dir, *args, **kwargs):
        assert (args, kwargs) == evaluated[run_dir][:2]
        return evaluated[run_dir][2]

    monkeypatch.setattr(bench, "evaluate", again_as_before)
    monkeypatch.setattr(bench, "train", lambda *a, **k: pytest.fail("--rescore trained"))
    again = run("tang2018", corpus, tmp_path / "out", 0.01, ["yalta"], 0, bootstrap=0, rescore=True)
    printed = capsys.readouterr().out
    assert "[yalta] the run in" in printed and "model.pt from epoch 1 (lowest free-running" in printed
    assert again["yalta"]["goals"] == summary["yalta"]["goals"]


def test_without_a_corpus_the_real_benchmark_says_why_it_is_not_run(monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(REPO))
    import benchmarks.bench_learning as bench

    monkeypatch.setattr(bench, "make_corpus", lambda *a, **k: (_ for _ in ()).throw(SystemExit("stop")))
    with pytest.raises(SystemExit):
        bench.main(["--minutes", "0.01"])
    assert "real corpus: not run (--corpus tang2018 PATH" in capsys.readouterr().out
