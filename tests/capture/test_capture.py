"""kinectdata capture: OpenNI2's Dummy device, audio on the same clock, and align TAKE/."""

from __future__ import annotations

import json
import threading
import time
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner
from helpers import FakeInput, skip_unless_installed

from kinectdata.align.take import align_take
from kinectdata.capture.openni import OpenNI2Sensor, _oni_zero_clock
from kinectdata.capture.take import CaptureWarning, capture_take, read_take
from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.formats.csv_writer import write_csv
from kinectdata.oni import OniFile
from kinectdata.oni.skeleton import TrackedFrame, nite_motion
from reference import openni as openni_ref


@pytest.fixture(scope="module")
def openni2():
    skip_unless_installed(openni_ref.openni2_missing(), "OpenNI2")


def test_the_oni_time_zero_is_placed_by_the_least_delayed_frame():
    rng = np.random.default_rng(0)
    device_us = 5_000_000 + np.arange(40) * 33_333 + rng.integers(-40, 40, 40)  # the device's clock and jitter
    zero_clock = 100.0  # the clock time at which the first recorded frame was captured
    arrival = zero_clock + (device_us - device_us[0]) / 1e6 + 0.004 + rng.uniform(0, 0.01, 40)
    arrival[17] = zero_clock + (device_us[17] - device_us[0]) / 1e6 + 0.001  # the quickest delivery
    frames = [[int(d), i, float(a)] for i, (d, a) in enumerate(zip(device_us, arrival))]
    file_us = (device_us - device_us[0]).astype(np.uint64)
    clock, matched, shift = _oni_zero_clock(frames, file_us, "t.oni")
    assert matched == 40 and clock == pytest.approx(zero_clock + 0.001, abs=1e-9) and shift == device_us[0]
    clock, matched, shift = _oni_zero_clock(frames[2:], file_us, "t.oni")  # the session missed the first two
    assert matched == 38 and clock == pytest.approx(zero_clock + 0.001, abs=1e-9) and shift == device_us[0]


def test_capture_from_the_dummy_device(openni2, tmp_path):
    before = time.monotonic()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        doc = capture_take(tmp_path / "take", OpenNI2Sensor(device="Dummy"), duration_s=0.8)
    after = time.monotonic()
    assert read_take(tmp_path / "take") == doc
    assert doc["device"]["uri"] == "Dummy" and doc["audio"] is None and doc["offset_s"] is None
    with OniFile(tmp_path / "take" / "take.oni") as oni:
        assert not oni.truncated and oni.stream("depth").n_frames == doc["oni"]["depth_frames"] >= 10
    assert doc["oni"]["frames_matched_to_clock"] >= doc["oni"]["depth_frames"] - 1
    assert before < doc["oni"]["zero_clock_s"] < after
    if doc["skeleton"] is None:
        assert any("NiTE2" in p for p in doc["problems"])
        with pytest.raises(KinectDataError, match="this take has no skeleton .* `kinectdata oni skeleton"):
            align_take(tmp_path / "take", tmp_path / "a.h5")
    with pytest.raises(KinectDataError, match="already holds a take"):
        capture_take(tmp_path / "take", OpenNI2Sensor(device="Dummy"), duration_s=0.5)


def test_a_take_with_audio_aligns_without_an_offset_guess(openni2, tmp_path):
    take = tmp_path / "take"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        streams = []
        doc = capture_take(
            take,
            OpenNI2Sensor(device="Dummy"),
            duration_s=1.5,
            audio_device="fake",
            audio_stream_factory=lambda **kw: streams.append(FakeInput(**kw)) or streams[-1],
        )
    audio = doc["audio"]
    assert audio["first_sample_clock_s"] == pytest.approx(streams[0].t0, abs=0.002)  # from the stream's own clock
    samples, rate = sf.read(take / "take.wav")
    assert rate == 48000 and samples.shape[0] == audio["frames"] and samples.shape[0] / rate > 1.4
    # the audio started first (the sensor is opened after it), by a fraction of a second
    assert doc["offset_s"] == pytest.approx(doc["oni"]["zero_clock_s"] - audio["first_sample_clock_s"])
    assert 0 < doc["offset_s"] < 5
    # a skeleton made afterwards (as `oni skeleton` would), one frame per depth frame, .oni-stamped
    with OniFile(take / "take.oni") as oni:
        stamps = oni.stream("depth").timestamps_us
    rng = np.random.default_rng(0)
    frames = [
        TrackedFrame(
            int(t),
            i + 1,
            {
                1: np.c_[
                    rng.normal(0, 300, (15, 3)) + [0, 0, 2500],
                    np.ones(15),
                    np.tile([0, 0, 0, 1.0], (15, 1)),
                    np.ones(15),
                ]
            },
        )
        for i, t in enumerate(stamps[3:])
    ]
    motion = nite_motion(frames, str(take / "take.oni"))
    write_csv(motion, take / "take.csv", "canonical", time_origin=float(stamps[3]) / 1e6)
    result = CliRunner().invoke(main, ["align", str(take), "-o", str(tmp_path / "a.h5")])
    assert result.exit_code == 0, result.output
    from kinectdata.align.aligned import AlignedRecording

    rec = AlignedRecording.load(tmp_path / "a.h5", audio=False)
    expected = doc["oni"]["zero_clock_s"] + float(stamps[3]) / 1e6 - audio["first_sample_clock_s"]
    assert rec.offset.source == "given" and rec.offset.seconds == pytest.approx(expected, abs=1e-9)
    result = CliRunner().invoke(main, ["align", str(take), str(take / "take.wav"), "-o", str(tmp_path / "b.h5")])
    assert result.exit_code == 2 and "a take folder brings its own audio" in result.output


def test_a_failed_capture_leaves_nothing(openni2, tmp_path):
    with pytest.raises(KinectDataError, match="OpenNI2 device NoSuchSensor"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            capture_take(tmp_path / "take", OpenNI2Sensor(device="NoSuchSensor"), duration_s=0.5)
    assert list((tmp_path / "take").iterdir()) == []


def test_capture_command(openni2, tmp_path):
    result = CliRunner().invoke(main, ["capture", "--device", "Dummy", "--duration", "0.5", "-o", str(tmp_path / "t")])
    assert result.exit_code == 0, result.output
    assert "depth frames (depth) from Dummy" in result.output and "take.json" in result.output
    assert json.loads((tmp_path / "t" / "take.json").read_text())["format"] == "kinectdata.take"
    shown = CliRunner().invoke(main, ["info", str(tmp_path / "t")])
    assert shown.exit_code == 0 and "depth frames (depth) from Dummy" in shown.output, shown.output
    assert CliRunner().invoke(main, ["capture", "--list"]).exit_code == 0


def test_real_audio_capture_where_an_input_exists(tmp_path):
    from kinectdata.capture.audio import AudioCapture, input_devices

    try:
        devices = input_devices()
    except KinectDataError as exc:
        pytest.skip(f"hardware: no audio capture here: {exc}")
    if not devices:
        pytest.skip("hardware: no audio input device on this machine")
    capture = AudioCapture(tmp_path / "a.wav", devices[0]["index"], int(devices[0]["sample_rate"]))
    capture.start()
    time.sleep(0.5)
    capture.stop()
    assert capture.frames > 0 and capture.first_sample_clock_s is not None
    assert sf.info(tmp_path / "a.wav").frames == capture.frames


def fake_session(tracked_users_by_frame):
    """A stand-in for the OpenNI2 child process: records OpenNI2's Dummy device for real, and
    reports its frames on a device clock 5 s ahead of the file's, with a live tracker's output."""

    def run(take, device, duration_s, color, lossy, nite_folder):
        openni_ref.record_dummy(take / "take.oni", duration_s)
        with OniFile(take / "take.oni") as oni:
            stamps = oni.stream("depth").timestamps_us.astype(int)
        now = time.monotonic()
        frames = [[int(t) + 5_000_000, i, now + t / 1e6 + 0.002] for i, t in enumerate(stamps)]
        skeleton = [[int(t) + 5_000_000, i, tracked_users_by_frame(i)] for i, t in enumerate(stamps)]
        return {"device": {"uri": "Dummy", "vendor": "", "name": ""}, "frames": frames, "skeleton": skeleton}

    return run


def test_a_live_skeleton_is_put_on_the_oni_timeline(openni2, tmp_path, monkeypatch):
    import kinectdata.capture.openni as take_module

    rows = np.c_[np.zeros((15, 3)) + [0, 0, 2500], np.ones(15), np.tile([0, 0, 0, 1.0], (15, 1)), np.ones(15)]
    monkeypatch.setattr(take_module, "_run_session", fake_session(lambda i: {3: rows.tolist()} if i >= 4 else {}))
    monkeypatch.setattr(take_module, "find_nite", lambda nite_dir=None: tmp_path)
    doc = capture_take(tmp_path / "take", OpenNI2Sensor(device="Dummy"), duration_s=0.6)
    with OniFile(tmp_path / "take" / "take.oni") as oni:
        stamps = oni.stream("depth").timestamps_us
    from kinectdata.formats import read_motion

    skeleton = read_motion(tmp_path / "take" / "take.csv")
    assert doc["skeleton"]["frames"] == len(stamps) - 4 and doc["skeleton"]["user"] == 3
    assert skeleton.metadata["time_origin"]["value"] == pytest.approx(stamps[4] / 1e6)  # .oni time, not the device's
    np.testing.assert_allclose(skeleton.times, (stamps[4:] - stamps[4]) / 1e6, atol=1e-6)


def test_nobody_tracked_keeps_the_recording(openni2, tmp_path, monkeypatch):
    import kinectdata.capture.openni as take_module

    monkeypatch.setattr(take_module, "_run_session", fake_session(lambda i: {}))
    monkeypatch.setattr(take_module, "find_nite", lambda nite_dir=None: tmp_path)
    with pytest.warns(CaptureWarning, match="tracked no skeleton"):
        doc = capture_take(tmp_path / "take", OpenNI2Sensor(device="Dummy"), duration_s=0.4)
    assert doc["skeleton"] is None and any("tracked no skeleton" in p for p in doc["problems"])
    assert (tmp_path / "take" / "take.oni").is_file() and (tmp_path / "take" / "take.json").is_file()


def test_a_recorder_that_hangs_while_finishing_is_reported_not_waited_for(monkeypatch):
    """OpenNI2's recorder can deadlock in its destroy: the session gives up after its timeout and
    reports it, instead of keeping the capture command waiting."""
    from kinectdata.capture import openni_session

    released = threading.Event()
    calls = []
    recorder = SimpleNamespace(stop=lambda: calls.append("stop"), close=lambda: released.wait(30))
    monkeypatch.setattr(openni_session, "STOP_TO_DESTROY_S", 0.0)
    monkeypatch.setattr(openni_session, "FINISH_TIMEOUT_S", 0.2)
    started = time.monotonic()
    assert openni_session._finish_recording(recorder) is False
    assert calls == ["stop"] and time.monotonic() - started < 5
    released.set()
    finished = SimpleNamespace(stop=lambda: None, close=lambda: None)
    assert openni_session._finish_recording(finished) is True
