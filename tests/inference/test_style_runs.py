"""A run whose features hear the song's style: generate hears it in the song or takes --style, live
hears it in a file before it plays and asks for it from a device, and the style changes the dance."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import soundfile
from click.testing import CliRunner
from conftest import REPO, TINY_TRAINING

pytest.importorskip("torch")
pytest.importorskip("librosa")

from kinectdata.align.audio import load_audio  # noqa: E402
from kinectdata.cli import main  # noqa: E402
from kinectdata.core.errors import ConfigError  # noqa: E402
from kinectdata.features import feature_config, style_input_of  # noqa: E402
from kinectdata.inference.generate import generate  # noqa: E402
from kinectdata.live import sources  # noqa: E402
from kinectdata.live.clock import VirtualClock  # noqa: E402
from kinectdata.live.session import LiveDancer, run_live  # noqa: E402

SAMPLES = REPO / "sample_data"


@pytest.fixture(scope="module")
def style_run(tmp_path_factory):
    """(run, song): a tiny yalta run on the sample sessions with the style input (two training
    songs told waltz and rumba), and the first 12 s of the third session's song."""
    from kinectdata.dataset.build import build_dataset
    from kinectdata.dataset.config import BuildConfig
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    out = tmp_path_factory.mktemp("style")
    listed = []
    for name, split, style in (("synth_001", "train", "waltz"), ("synth_003", "train", "rumba"),
                               ("synth_002", "val", "rumba")):  # fmt: skip
        truth = json.loads((SAMPLES / f"{name}.truth.json").read_text())
        listed.append({"name": name, "recording": str(SAMPLES / f"{name}.csv"), "split": split, "style": style,
                       "audio": str(SAMPLES / f"{name}.flac"), "offset": truth["offset_s"]})  # fmt: skip
    (out / "recordings.json").write_text(json.dumps(listed))
    config = BuildConfig.from_pipeline("yalta2016", features="yalta2016_rhythm_style", target="positions")
    with pytest.warns(Warning):  # no test split
        build_dataset(out / "recordings.json", out / "dataset", config, allow_outside_paths=True)
    train(out / "dataset", out / "run", TrainConfig(**{**TINY_TRAINING, "epochs": 1}))
    samples, rate = soundfile.read(SAMPLES / "synth_002.flac", dtype="float32")
    soundfile.write(out / "song.wav", samples[: 12 * rate], rate)  # 12 s: beats enough to hear a style
    return out / "run", out / "song.wav"


def _classifier(run):
    config = json.loads((run / "config.json").read_text())
    return style_input_of(feature_config(config["dataset"]["features"])).classifier


def test_generate_hears_the_style_or_takes_it_and_the_style_changes_the_dance(style_run):
    run, song = style_run
    heard = _classifier(run).style_of(load_audio(song, 16000).samples, 16000)
    motion, timing = generate(run, song)
    assert timing["style"] == f"{heard} (heard in the music)"
    told, told_timing = generate(run, song, style=heard)
    assert told_timing["style"] == f"{heard} (given)"
    np.testing.assert_array_equal(told.positions, motion.positions)  # hearing it is being told it
    other = next(s for s in ("rumba", "waltz") if s != heard)
    changed, _ = generate(run, song, style=other)
    assert np.abs(changed.positions - motion.positions).max() > 1e-4
    with pytest.raises(ConfigError, match="style 'tango': the run knows rumba, waltz"):
        generate(run, song, style="tango")


def test_the_cli_says_which_style_it_danced(style_run, tmp_path):
    run, song = style_run
    result = CliRunner().invoke(main, ["generate", "--run", str(run), str(song), "-o", str(tmp_path / "d.csv"),
                                       "--style", "waltz"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "  style: waltz (given)" in result.output
    bad = CliRunner().invoke(main, ["generate", "--run", str(run), str(song), "-o", str(tmp_path / "e.csv"),
                                    "--style", "x"])  # fmt: skip
    assert bad.exit_code == 1 and "style 'x': the run knows rumba, waltz" in bad.output
    assert not (tmp_path / "e.csv").exists()


class _Device:
    """A source that, like an input device, has no whole song to hear before it plays."""

    name = "a test device"

    def __init__(self, samples, block):
        self.samples, self.block = samples, block

    def blocks(self):
        for first in range(0, self.samples.size, self.block):
            yield sources.AudioBlock(self.samples[first : first + self.block], first / 16000)

    def close(self):
        pass


def test_live_hears_a_file_and_asks_a_device_for_the_style(style_run):
    run, song = style_run
    dancer = LiveDancer(run, "torch")
    samples = load_audio(song, 16000).samples[: 3 * 16000]
    with pytest.raises(ConfigError, match="cannot be heard from a device before the song has played: give --style"):
        run_live(dancer, _Device(samples, 160), [], VirtualClock(0.0), duration=1.0)
    stats = run_live(LiveDancer(run, "torch"), _Device(samples, 160), [], VirtualClock(0.0), duration=1.0,
                     style="waltz")  # fmt: skip
    assert stats.summary()["frames_sent"] > 0
    clock = VirtualClock(0.0)
    stats = run_live(LiveDancer(run, "torch"), sources.FileSource(song, 16000, 160, clock), [], clock, duration=1.0)
    assert stats.summary()["frames_sent"] > 0


def test_generate_dances_a_song_at_its_styles_tempo_and_plays_the_dance_back_at_the_songs(style_run, tmp_path):
    import shutil

    from kinectdata.align.stretch import stretch_audio
    from kinectdata.inference.style_tempo import style_tempo_factor, warp_back

    run, song = style_run
    samples = load_audio(song, 16000).samples
    config = json.loads((run / "config.json").read_text())
    features = feature_config(config["dataset"]["features"])
    factor, heard = style_tempo_factor(samples, features, 0.01)
    assert heard is not None and abs(factor - 1) > 0.01  # the song is off its style's tempo
    played = tmp_path / "played"
    shutil.copytree(run, played)
    config["train"]["style_tempo"] = 0.01
    (played / "config.json").write_text(json.dumps(config))
    asked = {"style": heard, "beats_per_bar": 4, "turning": False, "travel": False}
    motion, timing = generate(played, song, **asked)
    assert timing["style_tempo"].endswith(f"this song x{factor:.2f}")
    # the same network on the song played at that tempo by hand, its dance warped back by hand
    soundfile.write(tmp_path / "faster.wav", stretch_audio(samples, factor, 16000), 16000, subtype="FLOAT")
    faster, faster_timing = generate(run, tmp_path / "faster.wav", **asked)
    assert faster_timing["style_tempo"] == "every song at its own tempo"
    expected = warp_back(faster.positions, factor, motion.n_frames)
    assert motion.n_frames == int(len(samples) / 16000 * 30)
    np.testing.assert_allclose(motion.positions, expected, atol=1e-4)


@pytest.mark.slow
def test_evaluate_dances_the_split_as_generate_does_and_says_which_songs_it_played(style_run, tmp_path):
    from kinectdata.evaluation.evaluate import evaluate, format_results, split_recordings
    from kinectdata.evaluation.rhythm_eval import recording_audio
    from kinectdata.inference.style_tempo import style_tempo_factor
    from kinectdata.models.run import read_manifest

    run, _ = style_run
    config = json.loads((run / "config.json").read_text())
    dataset = Path(config["dataset"]["path"])
    # the val recording's music over its motion, as every free run of evaluate hears it
    manifest = read_manifest(dataset, checksums=False)
    (rec,) = split_recordings(dataset, manifest, "val")
    entry = next(e for e in manifest["inputs"] if e["name"] == rec["recording"])
    samples = recording_audio(entry, rec["info"], len(rec["current"]), 30.0, 16000)
    factor, _ = style_tempo_factor(samples, feature_config(config["dataset"]["features"]), 0.01)
    assert abs(factor - 1) > 0.01
    asked = {"bootstrap": 0, "engines": [], "baselines": False, "tempo_rates": ()}
    results = evaluate(run, dataset, "val", out=tmp_path / "played", style_tempo=0.01, **asked)
    assert results["style_tempo"]["band"] == 0.01
    assert results["style_tempo"]["played"]["synth_002"] == pytest.approx(factor)
    assert "this song" not in format_results(results) and "synth_002 x" in format_results(results)
    # the network alone from the command line: --style-tempo 0
    result = CliRunner().invoke(main, ["evaluate", "--run", str(run), "--data", str(dataset), "--split", "val",
                                       "--out", str(tmp_path / "as_it_is"), "--bootstrap", "0",
                                       "--style-tempo", "0"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "synth_002 x" not in result.output
    as_it_is = json.loads((tmp_path / "as_it_is" / "results.json").read_text())
    assert as_it_is["style_tempo"] == {"band": None, "line": "every song at its own tempo", "played": {}}
    played, plain = (r["smape"]["without_reset"]["smape_normalised"] for r in (results, as_it_is))
    assert played != plain  # another dance: the song played faster or slower, warped back


def test_evaluate_plays_a_split_song_at_the_tempo_of_the_style_the_build_gave_it(style_run, tmp_path):
    # the build hears the whole song; evaluate plays the stretch the dance covers and must not hear it
    # again (the two can disagree): told another style in the dataset, the song is played at that one's
    import shutil

    from kinectdata.evaluation.evaluate import evaluate, split_recordings
    from kinectdata.evaluation.rhythm_eval import recording_audio
    from kinectdata.inference.style_tempo import style_tempo_factor
    from kinectdata.models.run import read_manifest

    run, _ = style_run
    config = json.loads((run / "config.json").read_text())
    dataset = tmp_path / "dataset"
    shutil.copytree(config["dataset"]["path"], dataset)
    manifest = read_manifest(dataset, checksums=False)
    record = next(r for r in manifest["recordings"] if r["name"] == "synth_002")
    told = next(s for s in _classifier(run).styles if s != record["style"]["style"])
    record["style"] = {"style": told, "source": "heard"}
    (dataset / "manifest.json").write_text(json.dumps(manifest))
    (rec,) = split_recordings(dataset, manifest, "val")
    assert rec["style"] == told
    entry = next(e for e in manifest["inputs"] if e["name"] == rec["recording"])
    samples = recording_audio(entry, rec["info"], len(rec["current"]), 30.0, 16000)
    features = feature_config(config["dataset"]["features"])
    factor, _ = style_tempo_factor(samples, features, 0.01, told)
    assert factor != pytest.approx(style_tempo_factor(samples, features, 0.01)[0])  # the styles' tempi differ
    asked = {"bootstrap": 0, "engines": [], "baselines": False, "tempo_rates": ()}
    results = evaluate(run, dataset, "val", out=tmp_path / "played", style_tempo=0.01, **asked)
    assert results["style_tempo"]["played"]["synth_002"] == pytest.approx(factor)
