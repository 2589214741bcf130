"""The command line: help texts, exit codes, the quickstart, synth determinism."""

from __future__ import annotations

import subprocess
import sys

import pytest
from click.testing import CliRunner
from conftest import REPO

from kinectdata.cli import main

COMMANDS = [
    "info",
    "formats",
    "oni",
    "align",
    "build-dataset",
    "inspect",
    "verify",
    "synth",
    "quickstart",
    "train-baseline",
    "evaluate",
    "generate",
    "export",
    "sweep",
    "render",
    "report",
]


def run(*args):
    return CliRunner().invoke(main, list(map(str, args)))


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_explains_itself(command):
    result = run(command, "--help")
    assert result.exit_code == 0 and "Usage: " in result.output


def test_align_help_states_units():
    text = run("align", "--help").output
    for phrase in ["frames per second", "in Hz", "in seconds", "audio_time = motion_time + offset", "(0..1)"]:
        assert phrase in " ".join(text.split()), phrase


def test_top_level_help_lists_commands():
    out = run("--help").output
    assert all(c in out for c in COMMANDS)


def test_align_cli_writes_file_and_summary(fixture_csv, tmp_path):
    sample = REPO / "sample_data"
    out = tmp_path / "a.h5"
    result = run("align", sample / "synth_003.csv", sample / "synth_003.flac", "-o", out)
    assert result.exit_code == 0, result.output
    assert "offset          +0.01" in result.output and "(clap, confidence 1.00)" in result.output
    assert out.is_file()


def test_errors_exit_nonzero_with_the_file_named(fixture_csv, tmp_path):
    out = tmp_path / "x.h5"
    result = run("align", fixture_csv, REPO / "sample_data" / "synth_001.flac", "-o", out)  # no clap in it
    assert result.exit_code == 1 and "cannot determine the audio-to-motion offset" in result.output
    result = run("align", tmp_path / "nothing.csv", REPO / "sample_data" / "synth_001.flac", "-o", out)
    assert result.exit_code == 1 and "nothing.csv: no such file" in result.output
    result = run("align", fixture_csv, fixture_csv, "-o", out, "--offset", "0")
    assert result.exit_code == 1 and "Ges01_wavehand.csv: cannot read audio" in result.output
    result = run("align", fixture_csv, fixture_csv, "-o", out, "--offset", "soon")
    assert result.exit_code == 2 and "neither 'auto' nor a number" in result.output
    assert not out.exists()


def test_info_on_the_real_fixture(fixture_csv):
    result = run("info", fixture_csv)
    assert result.exit_code == 0
    assert "schema kinectreader" in result.output and "154 over 5.167 s" in result.output


def test_synth_is_deterministic(tmp_path):
    for d in ("a", "b"):
        assert run("synth", tmp_path / d, "--seed", 5, "--duration", 9).exit_code == 0
    for suffix in (".csv", ".flac", ".truth.json"):
        a = (tmp_path / "a" / f"synth_005{suffix}").read_bytes()
        assert a == (tmp_path / "b" / f"synth_005{suffix}").read_bytes()


@pytest.mark.slow
def test_quickstart_runs_on_the_bundled_samples(tmp_path, monkeypatch):
    pytest.importorskip("torch")
    monkeypatch.chdir(REPO)
    result = run(
        "quickstart", "--out", tmp_path / "qs", "--epochs", 1, "--units", 16, "--corpus-minutes", 0.5, "--minutes", 1
    )
    assert result.exit_code == 0, result.output
    assert result.output.count("offset error against the ground truth") == 4
    assert len(list((tmp_path / "qs" / "aligned").glob("*.h5"))) == 4
    assert "input [N, 1, 129, 5] float32" in result.output and "current [N, 65] float32" in result.output
    assert (tmp_path / "qs" / "dataset" / "manifest.json").is_file()
    assert (tmp_path / "qs" / "learn_dataset" / "manifest.json").is_file()
    assert "epoch 1: train loss" in result.output and "SMAPE without reset" in result.output
    assert "silence test" in result.output and "forward time" in result.output
    for verdict in ("generated motion follows the beat: ", "listens to the music: ", "generated motion is alive: "):
        assert verdict in result.output
    for name in ("loss.png", "model.pt", "stream.ts", "generated.csv", "evaluation/results.json"):
        assert (tmp_path / "qs" / "run" / name).is_file(), name


@pytest.mark.slow
def test_listen_to_dance_quickstart(tmp_path):
    pytest.importorskip("torch")
    result = run(
        "quickstart", "--pipeline", "listen-to-dance", "--out", tmp_path / "qs", "--epochs", 1, "--corpus-minutes", 0.5
    )
    assert result.exit_code == 0, result.output
    assert result.output.count("(clap)") == 4  # every offset from the 2-D clap
    assert "input [N, 80] float32" in result.output and "current [N, 44] float32" in result.output
    assert "(real motion: " in result.output and "generated motion follows the beat: " in result.output
    for name in ("loss.png", "model.pt", "generated.jsonl", "evaluation/rhythm_real.png"):
        assert (tmp_path / "qs" / "run" / name).is_file(), name
    assert run("quickstart", "--pipeline", "listen-to-dance", "--samples", tmp_path).exit_code == 2


@pytest.mark.slow
def test_training_commands_end_to_end(sample_dataset, tmp_path):
    pytest.importorskip("torch")
    runs = tmp_path / "run"
    tiny = ["--units", 8, "--sequence", 30, "--batch-size", 8, "--epochs", 1, "--noise-eta", 0]
    result = run("train-baseline", "--data", sample_dataset, "--out", runs, *tiny)
    assert result.exit_code == 0, result.output
    assert "epoch   1: train loss" in result.output and "validation SMAPE" in result.output
    result = run("train-baseline", "--data", sample_dataset, "--out", runs, *tiny)
    assert result.exit_code == 1 and "already holds a run; use --resume" in result.output
    result = run("train-baseline", "--data", sample_dataset, "--out", runs, "--resume", "--epochs", 2)
    assert result.exit_code == 0, result.output
    assert "epoch   2: train loss" in result.output and "epoch   1" not in result.output
    result = run("train-baseline", "--data", sample_dataset, "--out", runs, "--resume", "--units", 9)
    assert result.exit_code == 1 and "cannot resume with other settings: units 9 (the run's: 8)" in result.output
    result = run("evaluate", "--run", runs, "--data", sample_dataset, "--silence", 1)
    assert result.exit_code == 2 and "--silence" in result.output
    result = run("evaluate", "--run", runs, "--data", sample_dataset, "--silence", 2)
    assert result.exit_code == 0, result.output
    assert "SMAPE without reset" in result.output and "% denormalised" in result.output
    song = REPO / "sample_data" / "synth_001.flac"
    result = run("generate", "--run", runs, song, "-o", tmp_path / "dance.csv")
    assert result.exit_code == 0 and "x real time" in result.output and (tmp_path / "dance.csv").is_file()
    result = run("export", "--run", runs, "-o", tmp_path / "robot.ts", "--precision", "float16")
    assert result.exit_code == 0 and (tmp_path / "robot.ts").is_file()
    result = run("generate", "--run", tmp_path, song, "-o", tmp_path / "x.csv")
    assert result.exit_code == 1 and "not a training run" in result.output


def test_training_commands_say_how_to_get_torch(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "torch", None)  # import torch raises ImportError
    result = run("train-baseline", "--data", tmp_path, "--out", tmp_path / "r")
    assert result.exit_code == 1 and "pip install 'kinectdata[train]'" in result.output


def test_python_dash_m_runs_the_cli():
    out = subprocess.run([sys.executable, "-m", "kinectdata", "--version"], capture_output=True, text=True, check=True)
    assert "kinectdata" in out.stdout


def test_speed_ratios_below_one_keep_their_digits():
    from kinectdata.cli.train import _ratio

    assert [_ratio(v) for v in (0.25, 0.0031, 12.34, 1234.4)] == ["0.25", "0.0031", "12.3", "1234"]


def test_info_reports_a_declared_rate_the_timestamps_contradict_and_frozen_frames(tmp_path):
    """An LSL-Kinect export that declares 15 Hz but is stamped at 30 Hz, with a stalled stretch."""
    from kinectdata.formats import read_motion
    from kinectdata.formats.csv_writer import write_csv

    src = read_motion(REPO / "sample_data" / "synth_001.csv")
    src.positions[101:111] = src.positions[100]  # 10 frames repeat frame 100
    src.position_mask[100:111] = src.position_mask[100]
    path = tmp_path / "lsl.csv"
    write_csv(src, path, "lsl_kinect")
    text = path.read_text().replace("Stream nominal rate : 30", "Stream nominal rate : 15", 1)
    path.write_text(text)
    out = CliRunner().invoke(main, ["info", str(path)]).output
    assert "declared rate   15 fps in the file (Stream nominal rate), but the timestamps give 30.0" in out
    assert "frozen frames   10 repeat the frame before exactly" in out


def test_info_and_inspect_show_an_aligned_file(tmp_path):
    import h5py

    from kinectdata.align.recipe import align_files

    align_files(REPO / "sample_data" / "synth_001.csv", REPO / "sample_data" / "synth_001.flac", tmp_path / "a.h5")
    with h5py.File(tmp_path / "a.h5", "r") as f:  # independent: the file's own datasets
        frames, samples = f["motion/positions"].shape[0], f["audio/samples"].shape[0]
    for command in ("info", "inspect"):
        result = CliRunner().invoke(main, [command, str(tmp_path / "a.h5")])
        assert result.exit_code == 0, result.output
        assert f"frames          {frames} at 30 fps" in result.output
        assert f"audio           {samples} samples at 16000 Hz" in result.output
        assert "offset          " in result.output and "(clap)" in result.output
