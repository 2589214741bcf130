"""evaluate with the baselines, a second protocol and a given metre, on the tiny trained run of the
sample dataset (yalta65 targets, kinect_v2 joints, mapped to SMPL-24 for the field's metrics)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

torch = pytest.importorskip("torch")
pytest.importorskip("librosa")

from kinectdata.evaluation.evaluate import evaluate, format_results  # noqa: E402


@pytest.fixture(scope="module")
def evaluated(trained_run, sample_dataset, tmp_path_factory):
    run, _ = trained_run
    out = tmp_path_factory.mktemp("evaluation_baselines")
    results = evaluate(
        run,
        sample_dataset,
        "test",
        out=out,
        silence_seconds=2.0,
        timing_frames=20,
        engines=[("torch", "float32")],  # no ONNX export: not what is tested here
        bootstrap=20,
        more_protocols=("aist",),
        baselines=True,
        beats_per_bar=3,
        checksums=False,
    )
    return results, out


def test_each_protocol_writes_its_table(evaluated):
    results, out = evaluated
    first, aist = json.loads((out / "metrics.json").read_text()), json.loads((out / "metrics_aist.json").read_text())
    assert first["protocol"]["name"] == "bailando" and aist["protocol"]["name"] == "aist"
    assert results["field"]["protocol"] == "bailando" and results["field"]["metrics_json"] == str(out / "metrics.json")
    other = results["field_protocols"]["aist"]
    assert other["protocol"] == "aist" and other["metrics_json"] == str(out / "metrics_aist.json")
    assert set(results["field_protocols"]) == {"aist"}
    for entry, record in ((results["field"], first), (other, aist)):
        assert entry["metrics"] == json.loads(json.dumps(record["metrics"]))
        assert set(entry["baselines"]) == {"mean_pose_noise", "mean_pose_noise_own_speed", "retrieval"}
        for metrics in entry["baselines"].values():
            assert set(metrics) == set(entry["metrics"])


def test_the_baselines_are_scored_and_compared_with_the_model(evaluated, sample_dataset):
    results, _ = evaluated
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    training = [r["name"] for r in manifest["recordings"] if r["split"] == "train" and r.get("snr_db") is None]
    assert training == ["synth_003"]
    assert results["field"]["retrieved"] == {"synth_002": "synth_003"}  # the one training song
    for entry in (results["field"], results["field_protocols"]["aist"]):
        comparison = entry["comparison"]
        assert set(comparison) == {"mean_pose_noise", "mean_pose_noise_own_speed", "retrieval"}
        for name, row in comparison.items():
            for metric in ("FID_k", "FID_g"):
                assert row[metric] == entry["metrics"][metric]["generated"]
                assert row[f"{metric}_baseline"] == entry["baselines"][name][metric]["generated"]
            # one test song: no FID (it needs two sequences), so nothing is beaten
            assert row["FID_k"] is None and row["beats"] is False
    printed = format_results(results)
    for protocol in ("bailando", "aist"):
        assert (
            f"  beats the mean training pose + noise at the training dances' speed ({protocol}): no (FID_k n/a"
            in printed
        )
        assert f"  beats a training dance chosen by its music (retrieval) ({protocol}): no" in printed
        assert (
            f"  beats the same noise at each song's own speed (an oracle: it knows the answer's speed) ({protocol})"
            in printed
        )


def test_the_retrieval_baseline_is_the_training_dance_scored_as_a_free_run(evaluated, trained_run, sample_dataset):
    """Independent: synth_003's real motion read from its shard, frames 1.. cut to the test song's
    length, scored by the field's metrics by hand, gives the retrieval baseline's figures."""
    from kinectdata.evaluation.evaluate import split_recordings
    from kinectdata.evaluation.protocols import PROTOCOLS
    from kinectdata.evaluation.rhythm_eval import split_beats
    from kinectdata.evaluation.run_field import run_field_scores
    from kinectdata.targets.normalization import Normalizer
    from kinectdata.targets.specs import TargetSpec

    results, _ = evaluated
    run, _ = trained_run
    config = json.loads((run / "config.json").read_text())
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    (train,) = [r for r in manifest["recordings"] if r["name"] == "synth_003"]
    with h5py.File(sample_dataset / train["shard"], "r") as f:
        rows = slice(train["start"], train["start"] + train["frames"])
        dance = norm.invert(f["current"][rows], spec, mask=f["mask"][rows])
    recordings = split_recordings(sample_dataset, manifest, "test")
    (test,) = recordings
    real = {"synth_002": (norm.invert(test["current"], spec, mask=test["mask"]), test["mask"])}
    T = len(test["current"])
    assert len(dance) - 1 >= T - 1  # the training dance is long enough: no repeat
    retrieved = {"synth_002": dance[1:T]}
    beats = split_beats(recordings, manifest, config["dataset"]["fps"])
    scored = run_field_scores(retrieved, real, beats, spec, config["dataset"], PROTOCOLS["aist"], bootstrap=20)
    mine = scored.to_dict()["metrics"]
    theirs = results["field_protocols"]["aist"]["baselines"]["retrieval"]
    assert set(mine) == set(theirs)
    compared = [m for m in mine if mine[m]["generated"] is not None]
    assert {"BAS", "PFC"} <= set(compared)  # FID and diversity need two sequences
    for metric in mine:
        if mine[metric]["generated"] is None:
            assert theirs[metric]["generated"] is None
        else:
            assert theirs[metric]["generated"] == pytest.approx(mine[metric]["generated"], rel=1e-6, abs=1e-9)


def speed_by_hand(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    both = mask[1:] & mask[:-1]
    steps = np.where(both, np.diff(np.nan_to_num(values), axis=0) ** 2, 0.0)
    return steps.sum(axis=0) / np.maximum(both.sum(axis=0), 1)


def test_baseline_runs_make_motion_at_the_training_speed_the_own_speed_and_the_retrieved_dance(
    trained_run, sample_dataset
):
    from kinectdata.evaluation.evaluate import baseline_runs, split_recordings
    from kinectdata.targets.normalization import Normalizer
    from kinectdata.targets.specs import TargetSpec

    run, _ = trained_run
    config = json.loads((run / "config.json").read_text())
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    (test,) = recordings = split_recordings(sample_dataset, manifest, "test")
    values, mask = norm.invert(test["current"], spec, mask=test["mask"]), test["mask"]
    runs, retrieved = baseline_runs(sample_dataset, manifest, recordings, {"synth_002": (values, mask)}, config, norm)
    assert set(runs) == {"mean_pose_noise", "mean_pose_noise_own_speed", "retrieval"}
    assert retrieved == {"synth_002": "synth_003"}
    (train,) = [r for r in manifest["recordings"] if r["name"] == "synth_003"]
    with h5py.File(sample_dataset / train["shard"], "r") as f:
        rows = slice(train["start"], train["start"] + train["frames"])
        train_mask = f["mask"][rows]
        dance = norm.invert(f["current"][rows], spec, mask=train_mask)
    mean_pose = norm.invert(np.asarray(config["dataset"]["start_pose"], np.float32)[None], spec)[0]
    # the baseline moves at the one training dance's speed; the oracle at the test song's own
    for name, speed in (
        ("mean_pose_noise", speed_by_hand(dance, train_mask)),
        ("mean_pose_noise_own_speed", speed_by_hand(values, mask)),
    ):
        noise = runs[name]["synth_002"]
        assert noise.shape == (len(values) - 1, spec.dim)
        np.testing.assert_allclose(np.mean(np.diff(noise, axis=0) ** 2, axis=0), speed, rtol=1e-6, atol=1e-12)
        moving = noise.std(axis=0) > 0
        assert moving.any()
        assert np.all(np.abs(noise.mean(axis=0) - mean_pose)[moving] < 0.6 * noise.std(axis=0)[moving])
    np.testing.assert_array_equal(runs["retrieval"]["synth_002"], dance[1 : len(values)])


def test_the_metre_given_is_used_and_printed(evaluated):
    results, _ = evaluated
    assert results["listening"]["metres"] == {"synth_002": {"beats_per_bar": 3, "source": "given", "scores": {}}}
    assert all(r["beats_per_bar"] == 3 for r in results["listening"]["real"]["recordings"].values())
    printed = format_results(results)
    assert "  metre          beats per bar: synth_002 3 (given)" in printed


def test_without_a_given_metre_the_synthetic_songs_four_is_estimated(trained_run, sample_dataset):
    """The synthesizer writes its music in 4 (sample_data/synth_002.truth.json): estimated from the audio."""
    from conftest import REPO

    from kinectdata.evaluation.evaluate import split_songs
    from kinectdata.models.run import load_model

    truth = json.loads((REPO / "sample_data" / "synth_002.truth.json").read_text())
    run, _ = trained_run
    net, config = load_model(run)
    found = split_songs(net, config, sample_dataset, "test", checksums=False)
    metre = found.metres["synth_002"]
    assert (metre.beats_per_bar, metre.source) == (truth["beats_per_bar"], "estimated") == (4, "estimated")
    assert [s.beats_per_bar for s in found.songs] == [4]
    given = split_songs(net, config, sample_dataset, "test", beats_per_bar=3, checksums=False)
    assert given.metres["synth_002"].source == "given" and [s.beats_per_bar for s in given.songs] == [3]


def test_the_command_line_passes_the_metre_on(evaluated, trained_run, sample_dataset, monkeypatch, tmp_path):
    import kinectdata.evaluation.evaluate as module
    from kinectdata.cli import main

    results, _ = evaluated
    calls = []

    def fake(*args, **kwargs):
        calls.append((args, kwargs))
        return results

    monkeypatch.setattr(module, "evaluate", fake)
    run, _ = trained_run
    args = ["evaluate", "--run", str(run), "--data", str(sample_dataset), "--out", str(tmp_path / "e")]
    outcome = CliRunner().invoke(main, [*args, "--beats-per-bar", "3"])
    assert outcome.exit_code == 0, outcome.output
    assert calls[-1][1]["beats_per_bar"] == 3
    assert "metre          beats per bar: synth_002 3 (given)" in outcome.output
    outcome = CliRunner().invoke(main, args)
    assert outcome.exit_code == 0 and calls[-1][1]["beats_per_bar"] is None
    outcome = CliRunner().invoke(main, [*args, "--beats-per-bar", "1"])
    assert outcome.exit_code == 2 and "--beats-per-bar" in outcome.output
    assert len(calls) == 2  # the refused value never reaches evaluate
