"""The turning and travel drawn by the song's metre (``by_metre``): train fits them on the training
recordings of each metre, as it fits the pooled ones on all; generate, live and evaluate draw a song
its metre's processes where the run has them, else the pooled ones, and leave them out as they
leave out the pooled ones."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from conftest import TINY_TRAINING
from helpers import danced_live

pytest.importorskip("torch")

from kinectdata.core.errors import ConfigError  # noqa: E402
from kinectdata.evaluation.evaluate import evaluate  # noqa: E402
from kinectdata.inference.generate import generate  # noqa: E402
from kinectdata.inference.turning import drawn_line, run_travel, run_turning  # noqa: E402
from kinectdata.live.session import LiveDancer  # noqa: E402
from kinectdata.models.run import read_manifest  # noqa: E402
from kinectdata.training import turning as fitting  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402
from kinectdata.training.train import train  # noqa: E402

QUICK = {"tempo_rates": (), "engines": [("torch", "float32")], "checksums": False}


def _with_metres(manifest: dict, metre: int | None) -> dict:
    """The manifest with every input listed at ``metre`` beats a bar (None: none listed)."""
    inputs = [{**e, "beats_per_bar": metre} if metre is not None else dict(e) for e in manifest["inputs"]]
    return {**manifest, "inputs": inputs}


def test_a_metre_is_fitted_as_the_pooled_processes_on_its_own_recordings(centred_run, monkeypatch):
    run, dataset = centred_run
    config = json.loads((run / "config.json").read_text())
    manifest = read_manifest(dataset)
    monkeypatch.setattr(fitting, "MIN_METRE_RECORDINGS", 1)
    fitted = fitting.fit_dataset_by_metre(dataset, _with_metres(manifest, 3), config["dataset"])
    assert list(fitted) == ["3"] and fitted["3"]["recordings"] == 1
    # the one training recording is all the pooled fit saw: the same processes, by the pooled path
    assert fitted["3"]["turning"] == fitting.fit_dataset_turning(dataset, manifest, config["dataset"]).to_dict()
    assert fitted["3"]["travel"] == fitting.fit_dataset_travel(dataset, manifest, config["dataset"]).to_dict()
    assert fitting.fit_dataset_by_metre(dataset, _with_metres(manifest, None), config["dataset"]) == {}
    monkeypatch.setattr(fitting, "MIN_METRE_RECORDINGS", 2)  # too few recordings of the metre
    assert fitting.fit_dataset_by_metre(dataset, _with_metres(manifest, 3), config["dataset"]) == {}


def test_train_keeps_the_metres_only_when_asked_and_refuses_it_without_a_draw(centred_run, tmp_path):
    run, dataset = centred_run
    assert "drawn_by_metre" not in json.loads((run / "config.json").read_text())
    assert TrainConfig("yalta").by_metre is False and TrainConfig("yalta", paper=True).by_metre is False
    with pytest.raises(ConfigError, match="by_metre"):
        TrainConfig(**{**TINY_TRAINING, "by_metre": True, "turning": False, "travel": False})
    # the sample sessions list no metre and their features count no bars: nothing to fit by metre
    train(dataset, tmp_path / "asked", TrainConfig(**{**TINY_TRAINING, "epochs": 1, "by_metre": True}))
    assert "drawn_by_metre" not in json.loads((tmp_path / "asked" / "config.json").read_text())


def _run_copy(run, folder, **changes):
    """A copy of ``run`` with its config.json's top-level keys changed (None: removed)."""
    shutil.copytree(run, folder)
    config = json.loads((folder / "config.json").read_text())
    for key, value in changes.items():
        if value is None:
            config.pop(key, None)
        else:
            config[key] = value
    (folder / "config.json").write_text(json.dumps(config))
    return folder


def test_a_song_of_a_fitted_metre_is_drawn_its_metres_processes(centred_run, sample_song, tmp_path):
    run, _ = centred_run
    config = json.loads((run / "config.json").read_text())
    faster = {**config["turning"], "rms_speed": 2 * config["turning"]["rms_speed"]}
    slower = {**config["travel"], "rms_speed": config["travel"]["rms_speed"] / 2, "time_constant": 1.0}
    by_metre = _run_copy(run, tmp_path / "by_metre", drawn_by_metre={"3": {"turning": faster, "travel": slower}})
    pooled_as_3 = _run_copy(run, tmp_path / "pooled", turning=faster, travel=slower)
    three, timing = generate(by_metre, sample_song, beats_per_bar=3)
    expected, _ = generate(pooled_as_3, sample_song, beats_per_bar=3)
    np.testing.assert_allclose(three.positions, expected.positions, atol=1e-9, equal_nan=True)
    four, _ = generate(by_metre, sample_song, beats_per_bar=4)  # no metre of its own: the pooled processes
    pooled, _ = generate(run, sample_song, beats_per_bar=4)
    np.testing.assert_allclose(four.positions, pooled.positions, atol=1e-9, equal_nan=True)
    assert not np.allclose(three.positions, four.positions, equal_nan=True)
    assert "those of the training dances of 3 beats a bar" in timing["turning"]
    # --no-turning and --no-travel leave the metre's processes out as they leave out the pooled ones
    still, _ = generate(by_metre, sample_song, beats_per_bar=3, turning=False, travel=False)
    network, _ = generate(run, sample_song, turning=False, travel=False)
    np.testing.assert_allclose(still.positions, network.positions, atol=1e-9, equal_nan=True)
    doc = json.loads((by_metre / "config.json").read_text())
    assert run_turning(doc, 3).rms_speed == faster["rms_speed"]
    assert run_travel(doc, 4).rms_speed == config["travel"]["rms_speed"]
    assert run_turning({**doc, "turning": None}, 3) is None
    assert "songs of 3 beats a bar are drawn their metre's" in drawn_line(doc)


@pytest.mark.slow
def test_live_and_evaluate_draw_by_the_songs_metre_as_generate_does(centred_run, sample_song, tmp_path):
    run, dataset = centred_run
    config = json.loads((run / "config.json").read_text())
    faster = {**config["turning"], "rms_speed": 2 * config["turning"]["rms_speed"]}
    by_metre = _run_copy(run, tmp_path / "by_metre", drawn_by_metre={"3": {"turning": faster}})
    expected, _ = generate(by_metre, sample_song, seed=2, beats_per_bar=3)
    live = danced_live(by_metre, sample_song, 2, beats_per_bar=3)
    np.testing.assert_allclose(live, expected.positions, atol=1e-6, equal_nan=True)
    dancer = LiveDancer(by_metre, "torch", seed=2)
    dancer.set_metre(3)
    assert "3 beats a bar" in dancer.turning_line
    given = evaluate(by_metre, dataset, "test", bootstrap=0, baselines=False, beats_per_bar=3, **QUICK)
    pooled = evaluate(by_metre, dataset, "test", bootstrap=0, baselines=False, beats_per_bar=4, **QUICK)
    assert "drawn their metre's" in given["turning"]
    assert given["smape"]["without_reset"] != pooled["smape"]["without_reset"]  # the songs turned otherwise
