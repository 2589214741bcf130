"""Reading k4arecorder .mkv files: files written in the recorder's layout by a test-side writer
(k4a_writer.py, from the SDK's recorder source) and by MKVToolNix, frames compared with FFmpeg's
decode, cut-short and damaged files, the commands."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import warnings

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from helpers import skip_unless_installed
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.mkv import K4aRecording, MkvError, MkvWarning
from kinectdata.mkv.export import describe, export_tracks
from reference.k4a_writer import VideoTrack, depth_track, imu_samples, write_k4a

N, H, W = 6, 6, 8
T0 = 7_000_333_000  # the first depth frame's device time, ns
PERIOD = 33_333_000


def _ffmpeg() -> str:
    import imageio_ffmpeg

    return imageio_ffmpeg.get_ffmpeg_exe()


@pytest.fixture(scope="module")
def take(tmp_path_factory):
    """A recording with depth, IR, BGRA colour and IMU (the IMU starting 2 ms before the video)."""
    rng = np.random.default_rng(7)
    depth = rng.integers(0, 6000, (N, H, W)).astype(np.uint16)
    ir = rng.integers(0, 65535, (N, H, W)).astype(np.uint16)
    bgra = rng.integers(0, 255, (N, H, W, 4)).astype(np.uint8)
    times = [T0 + i * PERIOD for i in range(N)]
    color = VideoTrack("COLOR", "BGRA", W, H, [im.tobytes() for im in bgra], times, {"K4A_COLOR_MODE": "BGRA_720P"})
    imu_times = [T0 - 2_000_000 + k * 625_000 for k in range(300)]
    acc, gyro = rng.normal(0, 9.8, (300, 3)), rng.normal(0, 1, (300, 3))
    path = tmp_path_factory.mktemp("mkv") / "take.mkv"
    uids = write_k4a(
        path,
        [color, depth_track("DEPTH", depth, times, "NFOV_UNBINNED"), depth_track("IR", ir, times, "ACTIVE")],
        imu_samples(imu_times, acc, gyro),
        global_tags={"K4A_DEVICE_SERIAL_NUMBER": "000123456712", "K4A_WIRED_SYNC_MODE": "STANDALONE"},
        calibration={"CalibrationInformation": {"Cameras": [], "Metadata": {"SerialId": "000123456712"}}},
    )
    return {"path": path, "depth": depth, "ir": ir, "rgb": bgra[..., 2::-1], "times": np.array(times),
            "imu_times": np.array(imu_times), "acc": acc, "gyro": gyro, "uids": uids}  # fmt: skip


def test_tracks_tags_frames_times_and_imu_are_read_as_written(take):
    with K4aRecording(take["path"]) as r:
        assert list(r.tracks) == ["COLOR", "DEPTH", "IR", "IMU"]
        assert r.timestamp_scale_ns == 1000 and r.title == "Azure Kinect"
        assert r.tags["K4A_DEVICE_SERIAL_NUMBER"] == "000123456712"
        # file time 0 is the first item of any track: the IMU's first sample, 2 ms before the video
        assert r.start_offset_us == (T0 - 2_000_000) / 1000
        depth = r.track("DEPTH")
        assert (depth.fourcc, depth.width, depth.height, depth.frame_period_ns) == ("b16g", W, H, 33_333_333)
        assert depth.tags["K4A_DEPTH_MODE"] == "NFOV_UNBINNED"
        assert depth.tags["K4A_DEPTH_TRACK"] == str(take["uids"]["DEPTH"])
        assert r.track("COLOR").tags["K4A_COLOR_MODE"] == "BGRA_720P"
        np.testing.assert_array_equal(r.device_times_us(depth), take["times"] / 1000)
        for i in range(N):
            np.testing.assert_array_equal(r.frame(depth, i), take["depth"][i])
            np.testing.assert_array_equal(r.frame(r.track("IR"), i), take["ir"][i])
            np.testing.assert_array_equal(r.frame(r.track("COLOR"), i), take["rgb"][i])
        imu = r.imu()
        np.testing.assert_array_equal(imu.acc_times_us, take["imu_times"] // 1000)
        np.testing.assert_array_equal(imu.gyro_times_us, take["imu_times"] // 1000 + 100)
        np.testing.assert_allclose(imu.acc, take["acc"], rtol=1e-6)
        np.testing.assert_allclose(imu.gyro, take["gyro"], rtol=1e-6)
        assert json.loads(r.attachments["calibration.json"])["CalibrationInformation"]["Metadata"]["SerialId"]


@pytest.mark.parametrize("track, pixel_format", [("DEPTH", "gray16le"), ("IR", "gray16le"), ("COLOR", "rgb24")])
def test_frames_equal_ffmpegs_decode(take, track, pixel_format):
    index = {"COLOR": 0, "DEPTH": 1, "IR": 2}[track]
    out = subprocess.run(
        [_ffmpeg(), "-v", "error", "-i", str(take["path"]), "-map", f"0:v:{index}", "-f", "rawvideo",
         "-pix_fmt", pixel_format, "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    dtype, shape = (np.dtype("<u2"), (N, H, W)) if pixel_format == "gray16le" else (np.uint8, (N, H, W, 3))
    ffmpeg = np.frombuffer(out, dtype).reshape(shape)
    with K4aRecording(take["path"]) as r:
        ours = np.stack([r.frame(r.track(track), i) for i in range(N)])
    np.testing.assert_array_equal(ours, ffmpeg)


def _yuv_frames(rng, fourcc):
    """Random Y, U, V planes at full and half width and the recorder's payload for each frame."""
    frames, planes = [], []
    for _ in range(3):
        y = rng.integers(16, 236, (H, W)).astype(np.uint8)
        u, v = (rng.integers(16, 241, (H // 2 if fourcc == "NV12" else H, W // 2)).astype(np.uint8) for _ in "uv")
        if fourcc == "NV12":
            frames.append(y.tobytes() + np.stack([u, v], axis=-1).tobytes())
        else:
            frames.append(np.stack([y[:, 0::2], u, y[:, 1::2], v], axis=-1).tobytes())
        planes.append((y, u, v))
    return frames, planes


@pytest.mark.parametrize("fourcc", ["NV12", "YUY2"])
def test_yuv_colour_is_ffmpegs_rgb_within_a_level(tmp_path, fourcc):
    """FFmpeg's conversion with each pixel taking its nearest chroma sample, rounded accurately:
    ours within one level (its fixed-point rounding at halves), nearly everywhere equal."""
    frames, _ = _yuv_frames(np.random.default_rng(3), fourcc)
    times = [T0 + i * PERIOD for i in range(3)]
    path = tmp_path / "colour.mkv"
    write_k4a(path, [VideoTrack("COLOR", fourcc, W, H, frames, times, {"K4A_COLOR_MODE": f"{fourcc}_720P"})])
    out = subprocess.run(
        [_ffmpeg(), "-v", "error", "-i", str(path), "-sws_flags", "neighbor+accurate_rnd+full_chroma_int",
         "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    ffmpeg = np.frombuffer(out, np.uint8).reshape(3, H, W, 3).astype(int)
    with K4aRecording(path) as r:
        ours = np.stack([r.frame(r.track("COLOR"), i) for i in range(3)]).astype(int)
    assert np.abs(ours - ffmpeg).max() <= 1
    assert np.mean(ours != ffmpeg) < 0.03


def test_mjpg_colour_is_ffmpegs_decode_within_its_idct(tmp_path):
    """Pillow's libjpeg and FFmpeg's MJPEG decoder differ only in their IDCT and chroma filters."""
    from PIL import Image

    rng = np.random.default_rng(4)
    smooth = np.linspace(0, 1, 64)[None, :, None] * np.linspace(0.2, 1, 48)[:, None, None]
    images = [(255 * smooth * rng.uniform(0.3, 1, 3)).astype(np.uint8) for _ in range(2)]
    payloads = []
    for image in images:
        buffer = io.BytesIO()
        Image.fromarray(image).save(buffer, format="JPEG", quality=95)
        payloads.append(buffer.getvalue())
    path = tmp_path / "mjpg.mkv"
    write_k4a(path, [VideoTrack("COLOR", "MJPG", 64, 48, payloads, [T0, T0 + PERIOD], {"K4A_COLOR_MODE": "MJPG_720P"})])
    out = subprocess.run(
        [_ffmpeg(), "-v", "error", "-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    ffmpeg = np.frombuffer(out, np.uint8).reshape(2, 48, 64, 3).astype(int)
    with K4aRecording(path) as r:
        ours = np.stack([r.frame(r.track("COLOR"), i) for i in range(2)]).astype(int)
    assert np.abs(ours - ffmpeg).max() <= 4 and np.abs(ours - ffmpeg).mean() < 1.0
    assert np.abs(ours - np.stack(images)).mean() < 2  # and both are the image


def test_a_file_mkvmerge_wrote_gives_the_same_frames_and_times(take, tmp_path):
    """MKVToolNix's mkvmerge rewrites the recording: its own clusters, the IMU samples one per
    block, its own statistics tags (and not the tags aimed at nothing)."""
    skip_unless_installed(None if shutil.which("mkvmerge") else "no mkvmerge", "MKVToolNix")
    remuxed = tmp_path / "remuxed.mkv"
    subprocess.run(["mkvmerge", "-q", "-o", str(remuxed), "--timestamp-scale", "1000", str(take["path"])], check=True)
    with (
        K4aRecording(take["path"]) as original,
        pytest.warns(MkvWarning, match="first IMU"),
        K4aRecording(remuxed) as r,
    ):
        for name in ("COLOR", "DEPTH", "IR"):
            np.testing.assert_array_equal(r.track(name).times_us, original.track(name).times_us)
            for i in range(N):
                np.testing.assert_array_equal(r.frame(r.track(name), i), original.frame(original.track(name), i))
        np.testing.assert_array_equal(r.imu().acc, original.imu().acc)
        # mkvmerge drops the tags aimed at nothing: the start offset comes back from the first IMU sample
        assert r.start_offset_us == original.start_offset_us and "first IMU sample" in r.problems[0]
        assert r.track("DEPTH").tags["K4A_DEPTH_MODE"] == "NFOV_UNBINNED"
        assert "calibration.json" in r.attachments


def test_mkvinfo_reads_the_writers_layout(take):
    """The fixtures are Matroska as MKVToolNix reads it: the codec, its FOURCC, the IMU's lacing."""
    skip_unless_installed(None if shutil.which("mkvinfo") else "no mkvinfo", "MKVToolNix")
    text = subprocess.run(["mkvinfo", "-v", str(take["path"])], capture_output=True, text=True, check=True).stdout
    assert 'FourCC: 0x62313667 "b16g"' in text and "Codec ID: S_K4A/IMU" in text
    assert "Timestamp scale: 1000" in text and "frame(s)" in text
    assert "Seek head" in text and "Cues" in text and "EBML void: size 1021" in text


def test_a_file_cut_short_keeps_the_frames_before_the_cut_and_says_where(take, tmp_path):
    data = take["path"].read_bytes()
    with K4aRecording(take["path"]) as r:
        last_depth = int(r.track("DEPTH").positions[-1])
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(data[: last_depth + 10])
    with pytest.warns(MkvWarning, match=r"cut\.mkv: cut short at byte"):
        r = K4aRecording(cut)
    with r:
        assert r.track("DEPTH").frame_count == N - 1
        assert r.track("COLOR").frame_count == N
        np.testing.assert_array_equal(r.frame(r.track("DEPTH"), N - 2), take["depth"][N - 2])
        assert r.problems


def _rewrite(take, path, **options):
    """The take's tracks written again with ``options`` (k4a_writer's ``killed``, ``cut_at``)."""
    times = [int(t) for t in take["times"]]
    videos = [depth_track("DEPTH", take["depth"], times, "NFOV_UNBINNED")]
    imu = imu_samples(take["imu_times"], take["acc"], take["gyro"]) if options.pop("with_imu", True) else None
    write_k4a(path, videos, imu, **options)
    return path


def test_a_recorder_killed_before_closing_still_gives_its_frames_on_the_device_clock(take, tmp_path):
    """No Info (its TimestampScale), no K4A_START_OFFSET_NS, a Segment of unknown size, the last
    block cut: the recorder's microsecond ticks are assumed and the offset comes from the IMU."""
    path = _rewrite(take, tmp_path / "killed.mkv", killed=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MkvWarning)
        with K4aRecording(path) as whole:
            last_depth = int(whole.track("DEPTH").positions[-1])
    cut = tmp_path / "killed_cut.mkv"
    cut.write_bytes(path.read_bytes()[: last_depth + 10])
    with pytest.warns(MkvWarning) as caught, K4aRecording(cut) as r:
        depth = r.track("DEPTH")
        assert r.timestamp_scale_ns == 1000 and depth.frame_count == N - 1
        np.testing.assert_array_equal(r.device_times_us(depth), take["times"][: N - 1] / 1000)
        assert r.start_offset_us == (T0 - 2_000_000) / 1000
    said = " ".join(str(w.message) for w in caught)
    assert "no Info element" in said and "first IMU sample" in said and "cut short at byte" in said
    plain = _rewrite(take, tmp_path / "killed_no_imu.mkv", killed=True, with_imu=False)
    with pytest.warns(MkvWarning) as caught, K4aRecording(plain) as r:
        assert "the device's times are unknown" in r.problems[-1] and "no Info element" in r.problems[0]
        np.testing.assert_array_equal(r.track("DEPTH").times_us, (take["times"] - T0) // 1000)
        with pytest.raises(MkvError, match="device's times are unknown"):
            r.device_times_us(r.track("DEPTH"))
    assert "device time of the file's start: unknown" in CliRunner().invoke(main, ["mkv", "info", str(plain)]).output


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_file_cut_anywhere_after_its_first_cluster_gives_the_frames_before_the_cut(take, tmp_path, data):
    raw = take["path"].read_bytes()
    with K4aRecording(take["path"]) as r:
        first_cluster = int(min(t.positions.min() for t in r.tracks.values())) - 16
        depth_ends = r.track("DEPTH").positions + r.track("DEPTH").sizes
    cut_at = data.draw(st.integers(first_cluster, len(raw) - 1))
    path = tmp_path / "prefix.mkv"
    path.write_bytes(raw[:cut_at])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MkvWarning)
        with K4aRecording(path) as r:
            kept = r.track("DEPTH").frame_count
            assert kept == int(np.sum(depth_ends <= cut_at)) and r.problems
            for i in range(kept):
                np.testing.assert_array_equal(r.frame(r.track("DEPTH"), i), take["depth"][i])


def test_bytes_after_the_segment_are_not_read(take, tmp_path):
    padded = tmp_path / "padded.mkv"
    padded.write_bytes(take["path"].read_bytes() + bytes(4096))  # a recorder's preallocated tail
    with K4aRecording(padded) as r:
        assert r.track("DEPTH").frame_count == N and not r.problems


def test_not_a_recording_is_one_line(tmp_path):
    for name, payload, reason in [
        ("empty.mkv", b"", "empty file"),
        ("text.mkv", b"time,x\n0,1\n", "no EBML header"),
        ("webm.mkv", bytes.fromhex("1A45DFA3") + b"\x87" + bytes.fromhex("4282") + b"\x84" + b"avi!", "not Matroska"),
    ]:
        path = tmp_path / name
        path.write_bytes(payload)
        with pytest.raises(MkvError, match=reason) as caught:
            K4aRecording(path)
        assert str(path) in str(caught.value) and "\n" not in str(caught.value)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_files_are_read_or_refused_in_one_line(take, tmp_path, data):
    raw = bytearray(take["path"].read_bytes())
    for _ in range(data.draw(st.integers(1, 6))):
        raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    raw = raw[: data.draw(st.integers(1, len(raw)))]
    path = tmp_path / "damaged.mkv"
    path.write_bytes(bytes(raw))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MkvWarning)
            r = K4aRecording(path)
    except MkvError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        return
    with r:
        try:
            describe(path)  # what `mkv info` prints, the IMU's samples among it
            if "IMU" in r.tracks:
                r.imu()
        except KinectDataError as exc:
            assert "\n" not in str(exc)
        for track in r.tracks.values():
            for i in range(min(track.frame_count, 2)):
                try:
                    if track.codec == "V_MS/VFW/FOURCC":
                        r.frame(track, i)
                except MkvError as exc:
                    assert "\n" not in str(exc)
                except KinectDataError as exc:  # the pixel decoder's own one-line errors
                    assert "\n" not in str(exc)


def test_mkv_info_and_export(take, tmp_path):
    runner = CliRunner()
    result = runner.invoke(main, ["mkv", "info", str(take["path"])])
    assert result.exit_code == 0, result.output
    assert "DEPTH (V_MS/VFW/FOURCC b16g): 8x6, mode NFOV_UNBINNED, 30 fps nominal" in result.output
    assert "6 frames" in result.output and "dropped frames 0" in result.output
    assert "IMU (S_K4A/IMU): 300 samples, 1600.0 Hz measured" in result.output
    plain = runner.invoke(main, ["info", str(take["path"])])  # the skeleton command says what the file is
    assert plain.exit_code == 0 and "DEPTH (V_MS/VFW/FOURCC b16g)" in plain.output and "kinectdata mkv" in plain.output
    info = describe(take["path"])
    assert info["tracks"][1]["first_device_time_us"] == T0 / 1000
    out = tmp_path / "take.h5"
    result = runner.invoke(
        main,
        ["mkv", "export", str(take["path"]), "--track", "depth", "--track", "imu", "--start", "0.05", "-o", str(out)],
    )
    assert result.exit_code == 0, result.output
    with h5py.File(out) as f:
        # file time 0 is 2 ms before the first depth frame: frames at 0.002, 0.0353, 0.0687... s
        kept = (take["times"] - (T0 - 2_000_000)) / 1e9 >= 0.05
        np.testing.assert_array_equal(f["depth/frames"][:], take["depth"][kept])
        np.testing.assert_array_equal(f["depth/device_time_us"][:], take["times"][kept] // 1000)
        assert f["imu/acc"].shape[1] == 3 and f["imu/time_s"][0] >= 0.05
        assert json.loads(f.attrs["tags"])["K4A_DEVICE_SERIAL_NUMBER"] == "000123456712"


def test_export_faults_leave_no_file(take, tmp_path):
    out = tmp_path / "none.h5"
    with pytest.raises(KinectDataError, match="no frames in the selection"):
        export_tracks(take["path"], out, ("depth",), start_s=100.0)
    assert not out.exists() and not list(tmp_path.iterdir())
    result = CliRunner().invoke(main, ["mkv", "export", str(take["path"]), "--points", "-o", str(out)])
    assert result.exit_code == 1 and not out.exists()
    assert "calibration" in result.output and "Traceback" not in result.output


def _body_json(path, stamps_us):
    """A body-tracking JSON (the offline processor's layout) with one body in every frame."""
    from test_azure_json import make_body, make_doc, write

    rng = np.random.default_rng(5)
    return write(path.parent, make_doc([(int(t), [make_body(rng, 1)[0]]) for t in stamps_us]), path.name)


def test_body_tracking_frames_fall_on_the_depth_frames_of_their_recording(take, tmp_path):
    from kinectdata.mkv.body import place_body_frames

    device_us = take["times"] // 1000
    with K4aRecording(take["path"]) as r:
        # the tracker skipped frame 2; its stamps are the depth frames' device times
        placed = place_body_frames(np.delete(device_us, 2), r)
        assert placed.clock == "device" and placed.frame.tolist() == [0, 1, 3, 4, 5]
        np.testing.assert_array_equal(placed.error_us, 0)
        # an SDK before 1.2 stamped the file's own times
        old = place_body_frames(device_us - r.start_offset_us, r)
        assert old.clock == "file" and old.frame.tolist() == list(range(N))
        # another take's stamps fall on nothing
        assert place_body_frames(device_us + 10_000_000, r).placed == 0
        # one body frame alone is placed too
        assert place_body_frames(device_us[3:4], r).frame.tolist() == [3]
    # a take started after 71.6 minutes of uptime: the SDK's playback wraps the offset at 2^32 us
    late = tmp_path / "late.mkv"
    offset_ns = 5_000_000_000_000  # 83 minutes
    times = [offset_ns + i * PERIOD for i in range(N)]
    write_k4a(late, [depth_track("DEPTH", take["depth"], times, "NFOV_UNBINNED")])
    with K4aRecording(late) as r:
        wrapped_us = (offset_ns // 1000) % 2**32 + np.arange(N) * PERIOD // 1000
        placed = place_body_frames(wrapped_us, r)
        assert placed.clock == "device_uint32" and placed.placed == N
    body = _body_json(tmp_path / "take_body.json", np.delete(device_us, 2))
    result = CliRunner().invoke(main, ["mkv", "info", str(take["path"]), "--body", str(body)])
    assert result.exit_code == 0, result.output
    assert "body tracking: 5 of 5 frames on DEPTH frames (from frame 0), on the device's clock, at most 0 us apart" in (
        result.output
    )
