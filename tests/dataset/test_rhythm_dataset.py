"""Datasets with the music's pulse stacked on the spectra (``--features yalta2016_rhythm``,
``listen_to_dance_rhythm``): shapes, both input channels against computations done independently,
the sample songs' known tempi and beats, and the models that take these inputs."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO
from rhythm_reference import reference_frames
from scipy import signal

from kinectdata.align.audio import load_audio
from kinectdata.align.recipe import align_files
from kinectdata.cli import main
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.config import BuildConfig
from kinectdata.features import PRESETS, feature_config
from kinectdata.models.registry import model_kind

torch = pytest.importorskip("torch")
pytest.importorskip("librosa")  # the reference's mel filterbank

SAMPLES = REPO / "sample_data"
SR = 16000
PULSE = PRESETS["yalta2016_rhythm"].parts[1]


@pytest.fixture(scope="module")
def yalta_rhythm(tmp_path_factory):
    """(folder, manifest) of the three sample sessions built from the command line with the STFT
    and the pulse as two channels."""
    out = tmp_path_factory.mktemp("rhythm") / "dataset"
    result = CliRunner().invoke(
        main,
        ["build-dataset", str(SAMPLES), "-o", str(out), "--features", "yalta2016_rhythm", "--split-ratios", "1,1,1"],
    )
    assert result.exit_code == 0, result.output
    return out, json.loads((out / "manifest.json").read_text())


def _recording(out, manifest, name):
    """(features [T, 2, 129, 5] of the dataset, audio samples at 16 kHz, frame starts in them, truth)."""
    rec = next(r for r in manifest["recordings"] if r["name"] == name)
    aligned = align_files(SAMPLES / f"{name}.csv", SAMPLES / f"{name}.flac", offset=rec["offset"]["seconds"])
    first = round(aligned.summary["audio_trimmed_start_s"] * SR)
    audio = load_audio(SAMPLES / f"{name}.flac").samples.astype(np.float64)
    with h5py.File(out / rec["shard"], "r") as f:
        rows = f["input"][rec["start"] : rec["start"] + rec["frames"]]
    starts = first + np.round(np.arange(rec["frames"]) * SR / 30).astype(np.int64)
    truth = json.loads((SAMPLES / f"{name}.truth.json").read_text())
    return rows, audio, starts, truth


def _reference_stft(audio: np.ndarray, start: int) -> np.ndarray:
    """[129, 5] the yalta2016 STFT of one slice, written independently (as in test_dataset.py):
    scipy.signal.stft, dB floored 80 dB under each frame's peak, min-max into 0.1..0.9."""
    piece = np.zeros(534)
    available = audio[start : start + 534]
    piece[: available.size] = available
    _, _, z = signal.stft(
        piece[:480], window="hamming", nperseg=160, noverlap=80, nfft=256, boundary=None, padded=False, detrend=False
    )
    out = np.empty((129, 5))
    for i in range(5):
        db = 10 * np.log10(np.abs(z[:, i]) ** 2 + 1e-300)
        db = np.maximum(db, db.max() - 80.0)
        silent = 10 * np.log10(np.mean(piece[80 * i : 80 * i + 160] ** 2) + 1e-300) < -60.0 or db.max() == db.min()
        out[:, i] = 0.1 if silent else 0.1 + 0.8 * (db - db.min()) / (db.max() - db.min())
    return out


def test_inputs_are_the_stft_and_the_pulse_computed_independently(yalta_rhythm):
    out, manifest = yalta_rhythm
    assert manifest["feature_shape"] == [2, 129, 5]
    assert feature_config(manifest["config"]["features"]) == PRESETS["yalta2016_rhythm"]
    rows, audio, starts, truth = _recording(out, manifest, "synth_002")
    assert rows.shape == (len(starts), 2, 129, 5) and rows.dtype == np.float32
    settled = np.flatnonzero(starts / SR > PULSE.window_s + PULSE.detrend_s + 0.2)  # a whole window of audio
    chosen = np.concatenate([settled[::97], [len(starts) - 1]])
    for k in chosen:
        np.testing.assert_allclose(rows[k, 0], _reference_stft(audio, int(starts[k])), atol=1e-4, err_msg=f"frame {k}")
    expected = reference_frames(audio, starts[chosen], PULSE)  # [F, 1, 129, 5]
    np.testing.assert_allclose(rows[chosen, 1], expected[:, 0], atol=1e-6)
    assert np.abs(expected).max() > 0.5  # the music has a pulse


@pytest.mark.parametrize("name", ["synth_001", "synth_002", "synth_003"])
def test_the_pulse_channel_shows_the_songs_tempo_and_beats(yalta_rhythm, name):
    """The synthesised songs' tempi (96, 104, 116 BPM) and beat times are known (truth.json): the
    most salient tempo, averaged over the frames that see 6 s of music, is the song's or an octave
    of it, and at the grid tempo nearest the song's the phase is the time since the last beat."""
    out, manifest = yalta_rhythm
    rows, _, starts, truth = _recording(out, manifest, name)
    bpm, beats = truth["tempo_bpm"], np.asarray(truth["beat_times_s"])
    instant = (starts[:, None] + PULSE.instants[None, :]) / SR  # [T, 5] audio times of the values
    full = instant[:, 0] > beats[0] + PULSE.window_s + 0.5
    assert full.sum() > 150
    values = rows[full, 1].astype(np.float64).reshape(-1, 43, 3, 5)  # rows: tempo by tempo (salience, cos, sin)
    salience = values[:, :, 0].mean(axis=(0, 2))
    best = PULSE.tempi_bpm[np.argmax(salience)]
    assert any(abs(best / (bpm * f) - 1) < 0.04 for f in (0.5, 1, 2)), (best, bpm)
    k = int(np.argmin(np.abs(np.log(PULSE.tempi_bpm / bpm))))
    phase = np.arctan2(values[:, k, 2], values[:, k, 1])  # [F, 5]
    t = instant[full]
    since = t - beats[np.clip(np.searchsorted(beats, t, side="right") - 1, 0, None)]
    predicted = 2 * np.pi * PULSE.tempi_bpm[k] / 60 * since
    agreement = np.mean(np.cos(phase - predicted))  # 1: the same phase throughout
    assert agreement > 0.9, agreement


def test_the_yalta_model_takes_two_channels_and_streams_as_it_runs_whole(yalta_rhythm):
    out, manifest = yalta_rhythm
    kind = model_kind("yalta")
    kind.check_dataset(manifest)
    config = kind.network_config(kind.settings_type(units=16), manifest)
    assert config["input_shape"] == [2, 129, 5]
    torch.manual_seed(0)
    net = kind.build(config)
    assert net.convs[0].weight.shape[1] == 2  # the first convolution sees both channels
    rec = manifest["recordings"][0]
    with h5py.File(out / rec["shard"], "r") as f:
        audio = torch.from_numpy(f["input"][rec["start"] + 300 : rec["start"] + 308])[None]  # [1, 8, 2, 129, 5]
        first_pose = torch.from_numpy(f["current"][rec["start"] + 299])[None]
    net.train()
    net(audio, first_pose).sum().backward()  # trains: gradients reach the pulse channel's weights
    assert net.convs[0].weight.grad[:, 1].abs().sum() > 0
    net.eval()
    with torch.no_grad():
        whole = net(audio, first_pose)[0]
        silenced = audio.clone()
        silenced[:, :, 1] = 0
        assert (net.convs(silenced[0]) - net.convs(audio[0])).abs().max() > 1e-2  # the pulse changes the audio code
        from kinectdata.models.yalta import StreamingYalta

        stream = StreamingYalta(net)
        state = stream.initial_state()
        pose, poses = first_pose[0], []
        for t in range(audio.shape[1]):
            pose, *state = stream(audio[0, t], pose, *state)
            poses.append(pose)
    np.testing.assert_allclose(torch.stack(poses).numpy(), whole.numpy(), atol=1e-5)
    with pytest.raises(ValueError, match=r"\[1, 129, 5\]"):
        kind.check_dataset({**manifest, "feature_shape": [153]})


def test_listen_to_dance_rhythm_with_3d_positions_suits_the_cdhc_model(tmp_path):
    config = BuildConfig.from_pipeline(
        "listen-to-dance",
        features="listen_to_dance_rhythm",
        target="positions",
        normalisation="maxabs",
        split_ratios=(1 / 3, 1 / 3, 1 / 3),
    )
    manifest = build_dataset(SAMPLES, tmp_path / "ltd_rhythm", config)
    assert manifest["feature_shape"] == [153] and manifest["target_dim"] == 25 * 3
    assert not any("metre" in r for r in manifest["recordings"])  # its levels count beats, not bars
    kind = model_kind("cdhc")
    kind.check_dataset(manifest)
    net_config = kind.network_config(kind.settings_type(channels=8, decoder_channels=8), manifest)
    assert net_config["input_dim"] == 153 and net_config["inputs"] == "music" and net_config["output"] == "linear"
    net = kind.build(net_config).eval()
    rec = manifest["recordings"][0]
    with h5py.File(tmp_path / "ltd_rhythm" / rec["shard"], "r") as f:
        audio = torch.from_numpy(f["input"][rec["start"] : rec["start"] + 40])[None]
        previous = torch.from_numpy(f["current"][rec["start"] : rec["start"] + 40])[None]
    assert audio.shape == (1, 40, 153)
    with torch.no_grad():
        poses = net(audio, previous)
    assert poses.shape == (1, 40, 75) and torch.isfinite(poses).all()


def test_the_report_draws_the_spectrum_of_stacked_features(yalta_rhythm, tmp_path):
    """``kinectdata report`` on a dataset whose inputs are the STFT with the pulse stacked on (the
    real-dance recipe's) draws the spectrum and says the pulse is not drawn; it failed on them."""
    out, _ = yalta_rhythm
    result = CliRunner().invoke(main, ["report", str(out), "-o", str(tmp_path / "report.html")])
    assert result.exit_code == 0, result.output
    page = (tmp_path / "report.html").read_text()
    assert "STFT frames side by side" in page and "The pulse stacked after the spectrum is not drawn." in page
