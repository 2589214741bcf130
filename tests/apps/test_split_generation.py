"""``generate --data DATASET --split test``: a dance for every recording of a split, each from its
own music, frame k on the recording's frame k."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
import soundfile
from click.testing import CliRunner
from conftest import REPO

pytest.importorskip("torch")

from kinectdata.align.audio import load_audio  # noqa: E402
from kinectdata.apps.split_generation import generate_split  # noqa: E402
from kinectdata.cli import main  # noqa: E402
from kinectdata.dataset.shards import read_index  # noqa: E402
from kinectdata.evaluation.evaluate import split_recordings  # noqa: E402
from kinectdata.formats import read_motion  # noqa: E402
from kinectdata.inference.generate import generate  # noqa: E402
from kinectdata.inference.start import StartPose  # noqa: E402
from kinectdata.targets.normalization import Normalizer  # noqa: E402
from kinectdata.targets.specs import TargetSpec  # noqa: E402


def test_each_recording_of_the_split_gets_a_dance_from_its_own_music(trained_run, sample_dataset, tmp_path):
    """The sample dataset's test split is synth_002: its music over its frames is the song from where
    the build's alignment trimmed it (an independent cut of the FLAC), and the dance has exactly the
    recording's frames, starts from the recording's true first pose and is what generate makes from
    that music and that pose."""
    run, _ = trained_run
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    (record,) = [r for r in manifest["recordings"] if r["split"] == "test" and r.get("snr_db") is None]
    called = []
    (song,) = generate_split(run, sample_dataset, "test", tmp_path / "out", progress=called.append)
    assert called == [record["name"]] and song.name == record["name"]
    assert song.motion == tmp_path / "out" / f"{record['name']}.csv" and song.timing["frames"] == record["frames"]
    music, rate = soundfile.read(song.music, dtype="float32")
    assert rate == 16000
    with h5py.File(sample_dataset / record["shard"], "r") as f:
        info = next(x["info"] for x in read_index(f) if x["name"] == record["name"])
    first = round(info["alignment"]["audio_trimmed_start_s"] * rate)
    whole = load_audio(REPO / "sample_data" / "synth_002.flac", rate).samples
    np.testing.assert_array_equal(music, whole[first : first + music.size])
    assert music.size == int(np.ceil(record["frames"] / 30 * rate))
    danced = read_motion(song.motion)
    # frame 0 is the recording's true first pose (as evaluate starts its free runs): its SpineBase
    # where the dataset's real motion has it, independently of the model
    config = json.loads((run / "config.json").read_text())["dataset"]
    (real,) = [r for r in split_recordings(sample_dataset, manifest, "test") if r["name"] == record["name"]]
    norm, spec = Normalizer.from_dict(config["normalisation"]), TargetSpec.from_dict(config["target"])
    true_first = norm.invert(real["current"][:1], spec)[0, spec.columns("SpineBase", "position")]
    np.testing.assert_allclose(danced.positions[0, danced.joint_set.index("SpineBase")], true_first, atol=1e-5)
    start = StartPose(real["current"][0], None, "the recording's first pose")
    again, _ = generate(run, song.music, start=start)  # the rest is what generate makes from that music and pose
    np.testing.assert_allclose(danced.positions, again.positions, atol=1e-5, equal_nan=True)
    assert not np.allclose(np.nan_to_num(generate(run, song.music)[0].positions[0]), np.nan_to_num(danced.positions[0]))


def test_the_command_takes_audio_or_a_split_not_both(trained_run, sample_dataset, tmp_path):
    run, _ = trained_run
    song = str(REPO / "sample_data" / "synth_001.flac")
    base = ["generate", "--run", str(run), "-o", str(tmp_path / "out")]
    done = CliRunner().invoke(main, [*base, "--data", str(sample_dataset), "--split", "test"])
    assert done.exit_code == 0 and "1 dances of the test split" in done.output, done.output
    for wrong in ([], [song, "--data", str(sample_dataset)]):
        result = CliRunner().invoke(main, [*base, *wrong])
        assert result.exit_code == 2 and "give AUDIO, or --data DATASET" in result.output
    result = CliRunner().invoke(main, [*base, "--data", str(sample_dataset), "--split", "val", "--beats-per-bar", "3"])
    assert result.exit_code == 2 and "--beats-per-bar is for AUDIO" in result.output
    result = CliRunner().invoke(main, [*base, "--data", str(sample_dataset), "--split", "val", "--style", "waltz"])
    assert result.exit_code == 2 and "--style is for AUDIO" in result.output
    result = CliRunner().invoke(main, [*base, "--data", str(sample_dataset), "--split", "nosuch"])
    assert result.exit_code == 1 and "the nosuch split has no recordings to generate for" in result.output
