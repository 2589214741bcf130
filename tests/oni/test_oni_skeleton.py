"""Skeletons for .oni recordings: NiTE2 conversion, its absence, and --timeline."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner
from conftest import DATA
from scipy.spatial.transform import Rotation

from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.formats import read_motion
from kinectdata.formats.csv_writer import write_csv
from kinectdata.oni.skeleton import TrackedFrame, find_nite, nite_motion, oni_timeline, retime

ONI = DATA / "oni" / "openni2_dummy_depth.oni"  # 29 depth frames, 33 ms apart


def joints(seed: int, conf: float = 1.0) -> np.ndarray:
    """[15, 9]: x, y, z mm, position confidence, qx, qy, qz, qw, orientation confidence."""
    rng = np.random.default_rng(seed)
    out = np.zeros((15, 9))
    out[:, 0:3] = rng.normal(0, 400, (15, 3)) + [0, 0, 2500]
    out[:, 3] = conf
    out[:, 4:8] = Rotation.random(15, random_state=seed).as_quat() * 2.0  # NiTE's need not be unit
    out[:, 8] = 1.0
    return out


def test_nite_frames_become_a_motion_of_the_longest_tracked_user():
    frames = []
    for k in range(10):
        users = {2: joints(k)}
        if k < 3:
            users[7] = joints(100 + k)
        frames.append(TrackedFrame(1_000_000 + 33_367 * k, k + 1, users))
    frames.insert(5, TrackedFrame(frames[4].timestamp_us, 5, {2: joints(4)}))  # the same depth frame twice
    first = frames[0].users[2].copy()
    frames[0].users[2][6, 3] = 0.0  # LEFT_HAND not tracked
    frames[0].users[2][8, 8] = 0.0  # TORSO orientation not tracked
    m = nite_motion(frames, "take.oni")
    assert m.joint_set.name == "nite" and m.n_frames == 10 and m.metadata["user"] == 2
    np.testing.assert_allclose(m.times, np.arange(10) * 0.033367)
    assert m.metadata["time_origin"] == {"value": 1_000_000.0, "unit": "us"}
    np.testing.assert_allclose(m.positions[0, 0], first[0, 0:3] / 1000.0)
    assert not m.position_mask[0, 6] and np.isnan(m.positions[0, 6]).all() and m.confidence[0, 6] == 0.0
    expected_q = first[:, 4:8] / np.linalg.norm(first[:, 4:8], axis=1, keepdims=True)
    np.testing.assert_allclose(m.orientations[0, 0], expected_q[0])
    assert not m.orientation_mask[0, 8] and m.orientation_mask[0, 0]
    assert nite_motion(frames, "take.oni", user=7).n_frames == 3
    with pytest.raises(KinectDataError, match="user 9 was never tracked; tracked users: \\[2, 7\\]"):
        nite_motion(frames, "take.oni", user=9)
    with pytest.raises(KinectDataError, match="take.oni: NiTE2 tracked no skeleton in 2 frames"):
        nite_motion([TrackedFrame(0, 1, {}), TrackedFrame(1, 2, {})], "take.oni")


def test_a_nite_skeleton_csv_keeps_the_recording_timestamps(tmp_path):
    frames = [TrackedFrame(500_000 + 33_000 * k, k + 1, {1: joints(k)}) for k in range(6)]
    m = nite_motion(frames, "take.oni")
    write_csv(m, tmp_path / "s.csv", "canonical", time_origin=0.5)
    back = read_motion(tmp_path / "s.csv")
    assert back.joint_set.name == "nite"
    np.testing.assert_allclose(back.times, m.times, atol=1e-6)
    assert back.metadata["time_origin"]["value"] == pytest.approx(0.5)
    np.testing.assert_allclose(back.positions, m.positions, atol=1e-6)


def test_without_nite2_the_error_says_what_is_missing_and_where(tmp_path, monkeypatch):
    monkeypatch.setenv("NITE2_REDIST64", str(tmp_path / "redist"))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(KinectDataError) as err:
        find_nite(tmp_path / "mine")
    message = str(err.value)
    for place in ("mine", "redist", "NiTE2", "/usr/lib"):
        assert place in message, place
    assert "libNiTE2.so" in message and "--nite DIR" in message and "NITE2_REDIST64" in message
    result = CliRunner().invoke(main, ["oni", "skeleton", str(ONI), "-o", str(tmp_path / "s.csv")])
    assert result.exit_code == 1 and "NiTE2 is not installed" in result.output
    assert not (tmp_path / "s.csv").exists()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "libNiTE2.so").write_bytes(b"")
    assert find_nite(tmp_path / "mine") == (tmp_path / "mine").resolve()


def skeleton_csv(path, n: int, fps: float = 25.0):
    """A nite skeleton of n frames with its own (wrong) clock."""
    frames = [TrackedFrame(round(k * 1e6 / fps), k + 1, {1: joints(k)}) for k in range(n)]
    write_csv(nite_motion(frames, str(path)), path, "canonical")


def test_retime_takes_the_oni_depth_timestamps(tmp_path):
    skeleton_csv(tmp_path / "s.csv", 29)
    m = retime(read_motion(tmp_path / "s.csv"), ONI)
    np.testing.assert_allclose(m.times, np.arange(29) * 0.033)
    np.testing.assert_allclose(oni_timeline(ONI), m.times)
    assert m.metadata["timeline"] == {"oni": str(ONI), "stream": "depth"}
    skeleton_csv(tmp_path / "short.csv", 20)
    with pytest.raises(KinectDataError, match="short.csv: 20 skeleton frames, but .* has 29 depth frames"):
        retime(read_motion(tmp_path / "short.csv"), ONI)


def test_align_with_an_oni_timeline(tmp_path):
    skeleton_csv(tmp_path / "s.csv", 29)
    sf.write(tmp_path / "a.wav", np.random.default_rng(0).normal(0, 0.1, 48000).astype(np.float32), 48000)
    out = tmp_path / "a.h5"
    args = ["align", str(tmp_path / "s.csv"), str(tmp_path / "a.wav"), "-o", str(out), "--offset", "0"]
    result = CliRunner().invoke(main, [*args, "--timeline", str(ONI)])
    assert result.exit_code == 0, result.output
    assert "30.30 fps (from the timestamps)" in result.output  # the .oni's 33 ms steps, not the CSV's 40 ms
    from kinectdata.align.aligned import AlignedRecording

    rec = AlignedRecording.load(out, audio=False)
    assert rec.n_frames == 28 and rec.provenance.options["timeline"] == str(ONI)
