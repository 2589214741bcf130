"""A run's sway gain (``train --sway``, :mod:`kinectdata.targets.sway`) end to end on the sample
sessions built root-centred: train fits it from the network's whole training songs and the dancers',
generate moves the whole body by the scaled root (a rigid shift per frame), live scales each frame as
generate does, evaluate says so and ``sway=False`` leaves the network's root alone, and the exports
carry it."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO, TINY_TRAINING
from helpers import danced_live

pytest.importorskip("torch")

from kinectdata.cli import main  # noqa: E402
from kinectdata.core.errors import ConfigError  # noqa: E402
from kinectdata.inference.export import stream_metadata  # noqa: E402
from kinectdata.inference.generate import generate  # noqa: E402
from kinectdata.targets.sway import SwayGain  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402
from kinectdata.training.train import train  # noqa: E402

SONG = REPO / "sample_data" / "synth_001.flac"
HALF = SwayGain(0.5, 0.2, 0.1, 1).to_dict()


def _with_sway(run, folder, sway):
    shutil.copytree(run, folder)
    config = json.loads((folder / "config.json").read_text())
    config["sway"] = sway
    (folder / "config.json").write_text(json.dumps(config))
    return folder


def test_train_keeps_a_sway_gain_only_when_asked_and_only_with_a_travel(centred_run, tmp_path):
    run, dataset = centred_run
    assert "sway" not in json.loads((run / "config.json").read_text())  # off by default
    tiny = [f"--{k.replace('_', '-')}={v}" for k, v in {**TINY_TRAINING, "epochs": 1}.items()]
    said = CliRunner().invoke(
        main, ["train-baseline", "--data", str(dataset), "--out", str(tmp_path / "on"), *tiny, "--sway=true"]
    )
    assert said.exit_code == 0, said.output
    sway = SwayGain.from_dict(json.loads((tmp_path / "on" / "config.json").read_text())["sway"])
    assert f"  the network's sway along the floor scaled by {sway.gain:.2f}" in said.output
    assert sway.songs == 1 and sway.band == (1.0, 4.0)
    assert 0 < sway.network_speed and 0 < sway.dancers_speed
    assert sway.gain == pytest.approx(min(1.0, sway.dancers_speed / sway.network_speed))
    still = TrainConfig(**{**TINY_TRAINING, "epochs": 1, "sway": True, "travel": False})
    train(dataset, tmp_path / "still", still)
    assert "sway" not in json.loads((tmp_path / "still" / "config.json").read_text())  # its targets hold the travel
    assert TrainConfig("yalta", paper=True).sway is False


def test_generate_shifts_each_frame_by_the_scaled_root(centred_run, tmp_path):
    run, _ = centred_run
    swayed = _with_sway(run, tmp_path / "swayed", HALF)
    plain, _ = generate(run, SONG, turning=False, travel=False)
    calmed, timing = generate(swayed, SONG, turning=False, travel=False)
    assert timing["turning"].startswith("the network's sway along the floor scaled by 0.50")
    names = list(plain.joint_set.names)
    root = json.loads((run / "config.json").read_text())["dataset"]["target"]["root"]
    shift = plain.positions - calmed.positions  # [T, J, 3]
    np.testing.assert_allclose(shift[..., 1], 0.0, atol=1e-9)  # heights kept
    np.testing.assert_allclose(shift, shift[:, :1].repeat(shift.shape[1], axis=1), atol=1e-9)  # every joint alike
    place = plain.positions[:, names.index(root)][:, [0, 2]]
    moved = shift[:, 0, [0, 2]]
    np.testing.assert_allclose(moved - moved[0], 0.5 * (place - place[0]), atol=1e-9)
    assert np.abs(place - place[0]).max() > 1e-3  # and the network's root does move


@pytest.mark.slow
def test_live_evaluate_and_the_exports_scale_the_sway_as_generate_does(centred_run, sample_song, tmp_path):
    from kinectdata.evaluation.evaluate import evaluate

    run, dataset = centred_run
    swayed = _with_sway(run, tmp_path / "swayed", HALF)
    made, _ = generate(swayed, sample_song, seed=3)
    np.testing.assert_allclose(danced_live(swayed, sample_song, 3), made.positions, atol=1e-5, equal_nan=True)
    assert stream_metadata(json.loads((swayed / "config.json").read_text()))["sway"] == HALF

    quick = {"tempo_rates": (), "engines": [("torch", "float32")], "checksums": False, "baselines": False}
    scored = evaluate(swayed, dataset, "test", bootstrap=0, out=tmp_path / "e1", **quick)
    alone = evaluate(swayed, dataset, "test", bootstrap=0, out=tmp_path / "e2", sway=False, **quick)
    assert "sway along the floor scaled by 0.50" in scored["turning"]
    assert "sway" not in alone["turning"]
    assert scored["smape"]["without_reset"] != alone["smape"]["without_reset"]
    assert scored["smape"]["with_reset"] == alone["smape"]["with_reset"]  # the network's own prediction


def test_train_refuses_sway_at_a_frame_rate_that_cannot_carry_the_band_before_training(
    sample_dataset, tmp_path, monkeypatch
):
    import kinectdata.training.train as training

    fps = json.loads((sample_dataset / "manifest.json").read_text())["config"]["fps"]
    monkeypatch.setattr(training, "SWAY_BAND_HZ", (1.0, fps / 2))  # a band up to the Nyquist rate
    with pytest.raises(ConfigError, match=rf"{sample_dataset.name}: --sway .* {fps:g} fps cannot carry"):
        train(sample_dataset, tmp_path / "r", TrainConfig(**{**TINY_TRAINING, "sway": True}))
    assert not (tmp_path / "r").exists()  # refused before anything was written
