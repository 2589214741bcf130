"""``bench_learning --corpus tang2018 PATH --seeds 0,1`` end to end on a copy made in the corpus's
shape (the corpus itself has no licence): both models built, trained for a moment once per seed,
scored on the test dances, and issue 56's goals printed with their figures per seed and over the
seeds."""

from __future__ import annotations

import json
from pathlib import Path

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
    summary = run("tang2018", corpus, tmp_path / "out", ["yalta", "cdhc"], [0, 1], 0.5, bootstrap=0, changes=changes)
    printed = capsys.readouterr().out
    for model in ("yalta", "cdhc"):
        for seed in (0, 1):
            assert f"[{model} seed {seed}] goals:" in printed
            assert (tmp_path / "out" / f"seed{seed}" / model / "model.pt").is_file()
            keys = [(g["key"], g["title"]) for g in summary[model][seed]["goals"]]
            assert keys[:3] == [("a", "alive and human"), ("b", "no fixed oscillator"), ("c", "listens")], keys
            assert ("d", "FID_k against the mean pose + noise (bailando)") in keys, keys
            assert ("d", "FID_k against the mean pose + noise (aist)") in keys, keys
            assert keys[-1] == ("e", "as varied as the music"), keys
            assert (tmp_path / "out" / f"learning-real-{model}-seed{seed}.png").is_file()
        assert f"[{model}] the goals over seeds 0, 1:" in printed
    # each seed's dances are drawn with its own seed: its turning and travel too, not seed 0's
    drawn = {(Path(r).parent.name, kw["draw_seed"]) for r, (_, kw, _) in evaluated.items()}
    assert drawn == {("seed0", 0), ("seed1", 1)}
    assert "goals met in every seed:" in printed
    for model, shape in (("yalta", [2, 129, 5]), ("cdhc", [157])):  # spectra (or mel), the pulse; cdhc: the style
        built = json.loads((tmp_path / "out" / f"{model}_dataset" / "manifest.json").read_text())
        assert built["feature_shape"] == shape, (model, built["feature_shape"])
    saved = json.loads((tmp_path / "out" / "learning_real.json").read_text())
    assert set(saved) == {"yalta", "cdhc"} and set(saved["yalta"]) == {"0", "1"}
    assert "model.pt from epoch 1 (lowest free-running validation rhythm loss among the epochs moving at" in printed
    assert "keeps time with the song at other tempi: " in printed  # the tempo control ran (SoX)
    assert "dances in their song's style: " in printed

    # scored again without training: the run's own log read back, its evaluation asked for as before
    # (evaluate's figures are its tests'; here the answer it gave the first time stands in for it)
    def again_as_before(run_dir, *args, **kwargs):
        assert (args, kwargs) == evaluated[run_dir][:2]
        return evaluated[run_dir][2]

    monkeypatch.setattr(bench, "evaluate", again_as_before)
    monkeypatch.setattr(bench, "train", lambda *a, **k: pytest.fail("--rescore trained"))
    again = run("tang2018", corpus, tmp_path / "out", ["yalta"], [0, 1], 0.5, bootstrap=0, rescore=True)
    printed = capsys.readouterr().out
    assert "[yalta seed 1] the run in" in printed and "model.pt from epoch 1 (lowest free-running" in printed
    assert again["yalta"][1]["goals"] == summary["yalta"][1]["goals"]


def test_without_a_corpus_the_real_benchmark_says_why_it_is_not_run(monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(REPO))
    import benchmarks.bench_learning as bench

    monkeypatch.setattr(bench, "make_corpus", lambda *a, **k: (_ for _ in ()).throw(SystemExit("stop")))
    with pytest.raises(SystemExit):
        bench.main(["--minutes", "0.01"])
    assert "real corpus: not run (--corpus tang2018 PATH" in capsys.readouterr().out


STRETCHER_CASES = [("librosa", False, False), ("librosa", True, True), (None, True, False), ("sox", False, True)]


@pytest.mark.parametrize("found, allow, runs", STRETCHER_CASES)
def test_the_real_benchmark_stops_without_sox_unless_librosa_allowed(tmp_path, monkeypatch, capsys, found, allow, runs):
    """The goals' tempo figures are SoX's; librosa's fallback moved them on the same network, so a run
    without SoX stops with one line, unless told it may run with librosa (goal c then names it)."""
    monkeypatch.syspath_prepend(str(REPO))
    import benchmarks.bench_learning as bench
    import benchmarks.learning_real as real
    import kinectdata.align.stretch as stretch

    monkeypatch.setattr(stretch, "available_stretcher", lambda: found)
    ran = []
    monkeypatch.setattr(real, "run", lambda *a, **k: ran.append(a))
    argv = ["--corpus", "tang2018", str(tmp_path)] + (["--allow-librosa"] if allow else [])
    if runs:
        bench.main(argv)
        assert len(ran) == 1
        return
    with pytest.raises(SystemExit) as stopped:
        bench.main(argv)
    assert stopped.value.code == 2 and not ran
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1, said
    assert said[0].startswith("bench_learning: ") and "apt-get install sox" in said[0], said
    assert ("--allow-librosa" in said[0]) == (found == "librosa"), said
