"""kinectdata capture --sensor k4a: an Azure Kinect through pyk4a, here a stand-in for pyk4a with a
simulated camera (reference/fake_pyk4a.py) whose recorder writes k4arecorder's layout; the take's
clock placement checked against the simulated camera's own exposure times."""

from __future__ import annotations

import json
import os
import sys
import warnings

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner
from helpers import FakeInput

from kinectdata.capture import k4a_session
from kinectdata.capture.k4a import K4aSensor, device_clock_zero
from kinectdata.capture.take import CaptureWarning, capture_take, read_take
from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.mkv import K4aRecording
from reference import fake_pyk4a

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SMALL = {"depth_mode": "NFOV_2X2BINNED", "fps": 30}


@pytest.fixture
def pyk4a_fake(tmp_path, monkeypatch):
    """``import pyk4a`` finds the stand-in, in this process and in the session's child process."""
    shim = tmp_path / "shim"
    shim.mkdir()
    (shim / "pyk4a.py").write_text("from reference.fake_pyk4a import *  # noqa: F403\n")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(shim), REPO, os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setitem(sys.modules, "pyk4a", fake_pyk4a)  # removed again when the test ends
    for name in ("FAKE_K4A_DEVICES", "FAKE_K4A_HOST_CLOCK", "FAKE_K4A_LOST_AFTER", "FAKE_K4A_CRASH_AFTER"):
        monkeypatch.delenv(name, raising=False)
    return monkeypatch


def test_the_device_clock_is_placed_by_the_image_that_waited_least():
    rng = np.random.default_rng(1)
    device_us = 2_000_000 + np.arange(60) * 33_333.0
    zero = 50.0  # the clock at device time 0
    host_ns = (zero + device_us / 1e6 + 0.004 + rng.uniform(0, 0.003, 60)) * 1e9
    host_ns[23] = (zero + device_us[23] / 1e6 + 0.0031) * 1e9
    arrival = host_ns / 1e9 + rng.uniform(0.002, 0.02, 60)
    placed = device_clock_zero(device_us, host_ns, arrival)
    assert placed.source == "host" and placed.zero_clock_s == pytest.approx(zero + 0.0031, abs=1e-6)
    assert 2 < placed.delay_ms < 20
    # host stamps from another clock (Orbbec's wrapper: the wall clock): the arrival times stand in
    wall = host_ns + 1.7e18
    placed = device_clock_zero(device_us, wall, arrival)
    assert placed.source == "arrival" and placed.delay_ms is None
    assert placed.zero_clock_s == pytest.approx(np.min(arrival - device_us / 1e6))
    assert device_clock_zero(device_us, np.zeros(60), arrival).source == "arrival"  # no host stamps at all


def test_a_session_records_what_it_reads_and_the_file_holds_it(tmp_path, monkeypatch):
    """In-process, so that the simulated camera's own start time is known: the file's time 0 is
    placed within the host stamps' delay of the true exposure time."""
    settings = {"device_index": 0, "color_resolution": "720P", "mkv": str(tmp_path / "t.mkv"), "duration": 0.5, **SMALL}
    started = []
    real_start = fake_pyk4a.PyK4A.start
    monkeypatch.setattr(fake_pyk4a.PyK4A, "start", lambda device: (real_start(device), started.append(device)))
    status = k4a_session.run(settings, k4a=fake_pyk4a)
    frames = status["frames"]
    assert status["device"] == {"serial": fake_pyk4a.SERIAL, "index": 0} and 10 <= len(frames) <= 17
    depth_us = np.array([f[0][0] for f in frames])
    with K4aRecording(tmp_path / "t.mkv") as mkv:
        assert list(mkv.tracks) == ["COLOR", "DEPTH", "IR"] and not mkv.problems
        np.testing.assert_array_equal(mkv.device_times_us(mkv.track("DEPTH")), depth_us)
        np.testing.assert_array_equal(mkv.frame(mkv.track("DEPTH"), 4), np.full((288, 320), 1004))
        assert mkv.tags["K4A_DEVICE_SERIAL_NUMBER"] == fake_pyk4a.SERIAL and mkv.track("COLOR").width == 1280
    placed = device_clock_zero(depth_us, [f[0][1] for f in frames], [f[-1] for f in frames])
    truth = started[0].exposure_clock_s
    assert placed.source == "host"
    assert truth + fake_pyk4a.HOST_DELAY_S - 1e-5 <= placed.zero_clock_s <= truth + fake_pyk4a.HOST_DELAY_S + 0.002


def test_a_k4a_take_with_audio_on_one_clock(pyk4a_fake, tmp_path):
    take = tmp_path / "take"
    streams = []
    with warnings.catch_warnings():
        warnings.simplefilter("error", CaptureWarning)  # nothing doubtful in a clean take
        doc = capture_take(
            take,
            K4aSensor(**SMALL),
            duration_s=1.0,
            audio_device="fake",
            audio_stream_factory=lambda **kw: streams.append(FakeInput(**kw)) or streams[-1],
        )
    assert read_take(take) == doc and doc["sensor"] == "k4a" and doc["format_version"] == 2
    mkv = doc["mkv"]
    assert mkv["tracks"] == ["DEPTH", "IR"] and mkv["placed_by"] == "host" and mkv["clock_track"] == "DEPTH"
    assert mkv["frames"] == mkv["frames_read"] == mkv["frames_matched_to_clock"] >= 20
    with K4aRecording(take / "take.mkv") as recording:
        first_us = float(recording.device_times_us(recording.track("DEPTH"))[0])
        assert recording.start_offset_us == mkv["start_offset_us"] == first_us  # the SDK's: the first image's
    assert abs(first_us - fake_pyk4a.DEVICE_START_US) <= 3
    # the file's time 0 is device time start_offset; device time 0 was exposed at device_zero_clock_s
    assert mkv["zero_clock_s"] == pytest.approx(mkv["device_zero_clock_s"] + first_us / 1e6)
    assert doc["offset_s"] == pytest.approx(mkv["zero_clock_s"] - doc["audio"]["first_sample_clock_s"])
    assert 0 < doc["offset_s"] < 5  # the audio starts first, the camera after the child process does
    assert sf.info(take / "take.wav").frames == doc["audio"]["frames"]


def _body_json(path, stamps_us, skip: int):
    from test_azure_json import make_body, make_doc, write

    rng = np.random.default_rng(2)
    return write(path.parent, make_doc([(int(t), [make_body(rng, 1)[0]]) for t in stamps_us[skip:]]), path.name)


def test_align_places_the_body_tracking_of_a_k4a_take_by_its_device_times(pyk4a_fake, tmp_path):
    take = tmp_path / "take"
    streams = []
    doc = capture_take(
        take,
        K4aSensor(**SMALL),
        duration_s=1.2,
        audio_device="fake",
        audio_stream_factory=lambda **kw: streams.append(FakeInput(**kw)) or streams[-1],
    )
    runner = CliRunner()
    result = runner.invoke(main, ["align", str(take), "-o", str(tmp_path / "none.h5")])
    assert result.exit_code == 1 and "no take_body.json: run the Azure Kinect Body Tracking SDK" in result.output
    with K4aRecording(take / "take.mkv") as recording:
        device_us = recording.device_times_us(recording.track("DEPTH"))
        file_us = recording.track("DEPTH").times_us
    shown = runner.invoke(main, ["info", str(take)])
    assert shown.exit_code == 0 and "skeleton        none yet (the Azure Kinect Body Tracking SDK" in shown.output
    assert f"offset          {doc['offset_s']:+.4f} s" in shown.output and "next" not in shown.output
    _body_json(take / "take_body.json", device_us, skip=3)  # the tracker found the dancer from frame 3
    shown = runner.invoke(main, ["info", str(take)])
    assert "skeleton        take_body.json" in shown.output and f"kinectdata align {take} -o" in shown.output
    result = runner.invoke(main, ["align", str(take), "-o", str(tmp_path / "a.h5")])
    assert result.exit_code == 0, result.output
    from kinectdata.align.aligned import AlignedRecording

    rec = AlignedRecording.load(tmp_path / "a.h5", audio=False)
    expected = doc["mkv"]["zero_clock_s"] + file_us[3] / 1e6 - doc["audio"]["first_sample_clock_s"]
    assert rec.offset.source == "given" and rec.offset.seconds == pytest.approx(expected, abs=1e-9)
    # a body-tracking JSON of another recording is refused, not aligned at a guessed offset
    _body_json(take / "take_body.json", device_us + 7_777_777, skip=0)
    result = runner.invoke(main, ["align", str(take), "-o", str(tmp_path / "b.h5")])
    assert result.exit_code == 1 and "not this take's body tracking" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "b.h5").exists()


def test_host_stamps_on_another_clock_fall_back_to_arrival(pyk4a_fake, tmp_path):
    pyk4a_fake.setenv("FAKE_K4A_HOST_CLOCK", "wall")  # Orbbec's K4A wrapper
    with pytest.warns(CaptureWarning, match="not on this machine's monotonic clock"):
        doc = capture_take(tmp_path / "take", K4aSensor(**SMALL), duration_s=0.5)
    mkv = doc["mkv"]
    assert mkv["placed_by"] == "arrival" and mkv["host_delay_ms"] is None
    assert mkv["start_offset_us"] > 1.6e15  # device times synced to the epoch, as the wrapper's are
    assert mkv["frames"] == mkv["frames_matched_to_clock"]


@pytest.mark.parametrize(
    ("env", "device", "message"),
    [
        ({"FAKE_K4A_DEVICES": "0"}, 0, r"Azure Kinect device 0: cannot be started \(no such device"),
        ({}, 3, "Azure Kinect device 3: cannot be started"),
        ({"FAKE_K4A_LOST_AFTER": "5"}, 0, "Azure Kinect device 0: stopped after 5 captures: the device was lost"),
        ({"FAKE_K4A_CRASH_AFTER": "5"}, 0, r"Azure Kinect device 0: the recording process failed \(exit 3\)"),
    ],
)
def test_a_failed_k4a_capture_names_the_device_and_leaves_nothing(pyk4a_fake, tmp_path, env, device, message):
    for name, value in env.items():
        pyk4a_fake.setenv(name, value)
    with pytest.raises(KinectDataError, match=message):
        capture_take(tmp_path / "take", K4aSensor(device_index=device, **SMALL), duration_s=0.5)
    assert list((tmp_path / "take").iterdir()) == []


def test_a_camera_that_stops_delivering_is_reported(tmp_path, monkeypatch):
    monkeypatch.setattr(k4a_session, "TIMEOUT_MS", 20)
    monkeypatch.setenv("FAKE_K4A_STALL_AFTER", "3")
    settings = {"device_index": 0, "color_resolution": "OFF", "mkv": str(tmp_path / "t.mkv"), "duration": 5, **SMALL}
    status = k4a_session.run(settings, k4a=fake_pyk4a)
    assert status == {"error": "no capture for 0.06 s: the camera stopped"}


def test_without_pyk4a_the_error_says_what_to_install(tmp_path):
    with pytest.raises(KinectDataError, match=r"Azure Kinect device 0: pyk4a cannot be imported .*kinectdata\[k4a\]"):
        capture_take(tmp_path / "take", K4aSensor(module="no_such_pyk4a_here", **SMALL), duration_s=0.2)
    assert list((tmp_path / "take").iterdir()) == []


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"depth_mode": "NFOV"}, "depth mode 'NFOV': not one of OFF, NFOV_2X2BINNED"),
        ({"color_resolution": "4K"}, "colour resolution '4K': not one of OFF, 720P"),
        ({"fps": 60}, "60 fps: an Azure Kinect runs at 5, 15 or 30"),
        ({"depth_mode": "WFOV_UNBINNED"}, "WFOV_UNBINNED runs at most at 15 fps"),
        ({"depth_mode": "OFF"}, "nothing to record"),
    ],
)
def test_settings_the_device_cannot_run_are_refused_before_recording(settings, message):
    with pytest.raises(KinectDataError, match=message):
        K4aSensor(**settings)


def test_capture_command_with_k4a(pyk4a_fake, tmp_path):
    runner = CliRunner()
    out = tmp_path / "t"
    args = ["capture", "--sensor", "k4a", "--depth-mode", "nfov_2x2binned", "--duration", "0.5", "-o", str(out)]
    result = runner.invoke(main, [*args, "--color"])
    assert result.exit_code == 0, result.output
    assert "depth frames (COLOR, DEPTH, IR) from Azure Kinect 000123412345" in result.output
    assert "save its JSON as" in result.output and json.loads((out / "take.json").read_text())["sensor"] == "k4a"
    listed = runner.invoke(main, ["capture", "--list"])
    assert "Azure Kinect devices (--sensor k4a): 1 connected (--device 0..0)" in listed.output
    for bad, words in (
        (["--device", "Dummy"], "a k4a device is its index"),
        (["--no-skeleton"], "a k4a take has no live skeleton"),
        (["--fps", "30", "--depth-mode", "WFOV_UNBINNED"], "runs at most at 15 fps"),
    ):
        result = runner.invoke(main, [*args[:-1], str(tmp_path / "u"), *bad])
        assert result.exit_code != 0 and words in result.output and "Traceback" not in result.output, result.output
    assert not (tmp_path / "u").exists() or not list((tmp_path / "u").iterdir())


def test_a_real_azure_kinect_where_one_is_connected(tmp_path):
    try:
        import pyk4a
    except ImportError as exc:
        pytest.skip(f"hardware: pyk4a is not installed here ({exc})")
    if pyk4a.connected_device_count() == 0:
        pytest.skip("hardware: no Azure Kinect connected")
    doc = capture_take(tmp_path / "take", K4aSensor(), duration_s=1.0)
    mkv = doc["mkv"]
    assert mkv["frames"] >= 20 and mkv["frames_matched_to_clock"] == mkv["frames_read"]
    assert mkv["placed_by"] == "host" and 0 < mkv["host_delay_ms"] < 100
