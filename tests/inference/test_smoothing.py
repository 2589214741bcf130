"""The generated motion low-passed as a run says (``smooth_hz``, :mod:`kinectdata.inference.smoothing`):
the filter against scipy's transfer-function form, frame by frame as over the whole motion, the
quaternions kept unit and on one hemisphere; generate, live and evaluate smooth alike, and the
exports say how."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from conftest import TINY_TRAINING
from helpers import danced_live
from scipy.signal import butter, freqz, lfilter, lfilter_zi

from kinectdata.core.body_quality import mean_jerk
from kinectdata.core.errors import ConfigError
from kinectdata.inference.smoothing import ORDER, MotionSmoother, smooth_motion, smoothing_line
from kinectdata.targets.specs import load_target_spec

FPS = 30.0


def _reference(x: np.ndarray, cutoff: float) -> np.ndarray:
    """Each column through the transfer function (b, a) with scipy's lfilter, at rest on its first
    sample: the same filter by another road than the second-order sections."""
    b, a = butter(ORDER, cutoff, fs=FPS)
    return np.stack([lfilter(b, a, c, zi=lfilter_zi(b, a) * c[0])[0] for c in x.T], axis=1)


def test_positions_are_low_passed_as_scipys_transfer_function_from_rest():
    spec = load_target_spec("kinect_v2_positions")
    rng = np.random.default_rng(0)
    t = np.arange(300) / FPS
    slow = 0.2 * np.sin(2 * np.pi * 1.0 * t)[:, None]  # a 1 Hz sway...
    fast = 0.02 * np.sin(2 * np.pi * 12.0 * t)[:, None]  # ...and a 12 Hz shake
    x = 1.0 + slow + fast + 0.001 * rng.standard_normal((len(t), spec.dim))
    out = smooth_motion(x, spec, FPS, 6.0)
    np.testing.assert_allclose(out, _reference(x, 6.0), atol=1e-12)
    np.testing.assert_allclose(out[0], x[0], atol=1e-12)  # at rest on the first frame: no rise from 0
    _, gain = freqz(*butter(ORDER, 6.0, fs=FPS), worN=[1.0, 12.0], fs=FPS)
    assert abs(gain[0]) > 0.99 and abs(gain[1]) < 0.25  # the sway kept, the shake cut to a quarter
    still = np.full((50, spec.dim), 0.3)
    np.testing.assert_allclose(smooth_motion(still, spec, FPS, 6.0), still, atol=1e-12)


def test_frame_by_frame_gives_the_whole_motions_frames():
    spec = load_target_spec("kinect_v2_positions")
    x = np.random.default_rng(1).standard_normal((120, spec.dim))
    smoother = MotionSmoother(spec, FPS, 4.0)
    stepped = np.stack([smoother.step(frame) for frame in x])
    np.testing.assert_allclose(stepped, smooth_motion(x, spec, FPS, 4.0), atol=1e-12)


def test_quaternions_stay_unit_and_a_flipped_sign_is_the_same_rotation():
    spec = load_target_spec("kinect_v2_full")
    assert spec.orientations
    rng = np.random.default_rng(2)
    x = rng.standard_normal((80, spec.dim))
    for cols in spec.quaternion_slices:
        x[:, cols] = np.array([0.0, np.sin(0.2), 0.0, np.cos(0.2)]) + 0.01 * rng.standard_normal((80, 4))
        x[:, cols] /= np.linalg.norm(x[:, cols], axis=1, keepdims=True)
    flipped = x.copy()
    for cols in spec.quaternion_slices:
        flipped[1::2, cols] *= -1  # every other frame as -q: a sensor's or a network's sign is arbitrary
    out, out_flipped = smooth_motion(x, spec, FPS, 6.0), smooth_motion(flipped, spec, FPS, 6.0)
    np.testing.assert_allclose(out_flipped, out, atol=1e-12)
    for cols in spec.quaternion_slices:
        np.testing.assert_allclose(np.linalg.norm(out[:, cols], axis=1), 1.0, atol=1e-12)
        # without the hemisphere the filter would average q and -q towards zero
        assert np.abs(out[:, cols] - x[:, cols]).max() < 0.05
    np.testing.assert_allclose(out[:, spec.position_slice], _reference(x[:, spec.position_slice], 6.0), atol=1e-12)
    stepper = MotionSmoother(spec, FPS, 6.0)
    np.testing.assert_allclose(np.stack([stepper.step(f) for f in flipped]), out, atol=1e-12)


def test_a_cutoff_at_or_above_half_the_frame_rate_or_not_positive_is_refused():
    spec = load_target_spec("kinect_v2_positions")
    with pytest.raises(ConfigError, match="below half the frame rate"):
        smooth_motion(np.zeros((5, spec.dim)), spec, FPS, 15.0)
    pytest.importorskip("torch")
    from kinectdata.training.config import TrainConfig

    with pytest.raises(ConfigError, match="smooth_hz"):
        TrainConfig(**{**TINY_TRAINING, "smooth_hz": -1.0})
    assert TrainConfig("yalta").smooth_hz is None and TrainConfig("yalta", paper=True).smooth_hz is None
    assert TrainConfig(**{**TINY_TRAINING, "smooth_hz": 0.0}).smooth_hz is None  # 0: not smoothed
    assert smoothing_line({"train": {}}) == "not smoothed"


def test_the_command_line_turns_a_models_default_low_pass_off_with_0(tmp_path):
    pytest.importorskip("torch")
    from click.testing import CliRunner

    from kinectdata.cli import main
    from kinectdata.cli.train import make_train_config

    assert make_train_config("cdhc").smooth_hz == 6.0  # the cdhc model's real-dance default
    assert make_train_config("cdhc", smooth_hz=0.0).smooth_hz is None
    result = CliRunner().invoke(main, ["train-baseline", "--help"])
    assert "0: not smoothed. [default: none / 6]" in " ".join(result.output.split())  # help lines wrap
    negative = ["--data", str(tmp_path), "--out", str(tmp_path / "r"), "--smooth-hz", "-1"]
    result = CliRunner().invoke(main, ["train-baseline", *negative])
    assert result.exit_code == 2 and "--smooth-hz" in result.output


def _smoothed_copy(run, folder, cutoff):
    shutil.copytree(run, folder)
    config = json.loads((folder / "config.json").read_text())
    config["train"]["smooth_hz"] = cutoff
    (folder / "config.json").write_text(json.dumps(config))
    return folder


@pytest.mark.slow
def test_generate_live_and_evaluate_smooth_the_motion_alike(centred_run, sample_song, tmp_path):
    pytest.importorskip("torch")
    from kinectdata.evaluation.evaluate import evaluate
    from kinectdata.inference.export import stream_metadata
    from kinectdata.inference.generate import generate

    run, dataset = centred_run
    smoothed = _smoothed_copy(run, tmp_path / "smoothed", 5.0)
    plain, _ = generate(run, sample_song, seed=3)
    made, timing = generate(smoothed, sample_song, seed=3)
    assert timing["smoothing"] == "low-passed at 5 Hz (causal Butterworth, order 2)"
    # the sample run's positions are the targets where the first frame put them: the same filter
    flat = plain.positions.reshape(plain.n_frames, -1)
    expected = _reference(flat, 5.0).reshape(plain.positions.shape)
    np.testing.assert_allclose(made.positions, expected, atol=1e-5)
    assert mean_jerk(made.positions, FPS) < 0.5 * mean_jerk(plain.positions, FPS)

    np.testing.assert_allclose(danced_live(smoothed, sample_song, 3), made.positions, atol=1e-5, equal_nan=True)

    quick = {"tempo_rates": (), "engines": [("torch", "float32")], "checksums": False, "baselines": False}
    scored = evaluate(smoothed, dataset, "test", bootstrap=0, out=tmp_path / "e1", **quick)
    unscored = evaluate(run, dataset, "test", bootstrap=0, out=tmp_path / "e2", **quick)
    assert scored["smoothing"].startswith("low-passed at 5 Hz") and unscored["smoothing"] == "not smoothed"
    assert scored["smape"]["without_reset"] != unscored["smape"]["without_reset"]
    assert scored["smape"]["with_reset"] == unscored["smape"]["with_reset"]  # the network's own prediction
    config = json.loads((smoothed / "config.json").read_text())
    assert stream_metadata(config)["smoothing"] == {
        "filter": "butterworth",
        "order": 2,
        "cutoff_hz": 5.0,
        "causal": True,
    }


def test_train_refuses_a_cutoff_the_datasets_frame_rate_cannot_carry_naming_it(sample_dataset, tmp_path):
    pytest.importorskip("torch")
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    fps = json.loads((sample_dataset / "manifest.json").read_text())["config"]["fps"]
    with pytest.raises(ConfigError, match=rf"{sample_dataset.name}: .*below half the frame rate.*or 0 for none"):
        train(sample_dataset, tmp_path / "r", TrainConfig(**{**TINY_TRAINING, "smooth_hz": fps / 2}))
    assert not (tmp_path / "r").exists()  # nothing half-written
