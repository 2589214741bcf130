"""kinectdata info: timing doubts (declared rate, frozen runs), implausible values, aligned files."""

from __future__ import annotations

import warnings

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO

from kinectdata.cli import main
from kinectdata.core import body_checks
from kinectdata.core.motion import Motion
from kinectdata.formats import read_motion
from kinectdata.formats.csv_writer import write_csv


def info(path) -> str:
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 0, result.output
    return result.output


def _lsl(tmp_path, times, positions, declared: int):
    """An LSL-Kinect export of the given [T] times (s) and [T, 25, 3] positions declaring ``declared`` Hz."""
    src = read_motion(REPO / "sample_data" / "synth_001.csv")
    path = tmp_path / "lsl.csv"
    write_csv(Motion(times, positions, src.joint_set), path, "lsl_kinect")
    text = path.read_text()
    assert "Stream nominal rate : 30," in text
    path.write_text(text.replace("Stream nominal rate : 30,", f"Stream nominal rate : {declared},", 1))
    return path


def _thirds(n: int) -> np.ndarray:
    """A 30.00 fps recorder stamping 33.0, 33.0, 34.0 ms in turn (median interval 33.0 ms)."""
    k = np.arange(n)
    return (k // 3) * 0.1 + np.array([0.0, 0.033, 0.066])[k % 3]


@pytest.mark.parametrize("declared", [15, 30])
def test_the_rate_is_the_timestamps_and_a_contradicting_declared_rate_is_reported(tmp_path, declared):
    p = np.random.default_rng(0).normal(size=(300, 25, 3))
    out = info(_lsl(tmp_path, _thirds(300), p, declared))
    assert "; 30.00 fps (mean interval 33.33 ms)" in out  # not 30.30, the median interval's
    line = "declared rate   15 fps in the file (Stream nominal rate), but the timestamps give 30.00 fps (+100%)"
    assert (line in out) == (declared == 15)
    assert "frozen frames" not in out


def test_runs_of_frozen_frames_are_reported_with_figures(tmp_path):
    """11 % of the frames frozen, as in the real file: runs of 20, 10 and 3 frames in 300."""
    p = np.random.default_rng(1).normal(size=(300, 25, 3))
    for start, length in ((50, 20), (150, 10), (250, 3)):
        p[start : start + length] = p[start - 1]
    t = np.arange(300) / 30.0
    out = info(_lsl(tmp_path, t, p, 30))
    frozen = 20 + 10 + 3
    assert (
        f"frozen frames   {frozen} repeat the frame before exactly ({100 * frozen / 300:.1f}% of the frames), "
        f"in 3 run(s); the longest holds the pose of {49 / 30:.3f} s for 20 frame(s) ({20 / 30:.3f} s)"
    ) in out
    assert "declared rate" not in out


def test_implausible_positions_are_reported_with_the_first_frame(tmp_path):
    src = read_motion(REPO / "sample_data" / "synth_001.csv")
    src.positions[120, 3, 0] = 1e300
    src.positions[130, 4, 2] = -5e4
    write_csv(src, tmp_path / "big.csv", "dumpkinectskeleton")
    out = info(tmp_path / "big.csv")
    t = src.times[120] - src.times[0]
    assert "implausible     2 position(s) not finite or beyond 1000 m, 0 orientation(s) not unit quaternions, " in out
    assert f"first at frame 120 ({t:.3f} s): align masks them as tracking loss" in out


def test_the_bodys_figures_leave_out_implausible_positions_without_overflowing(tmp_path):
    """A joint at 1e300 m in every other frame: the bone lengths are those of the frames where it is
    plausible (as align will mask it), and numpy is never asked to square 1e300."""
    src = read_motion(REPO / "sample_data" / "synth_001.csv")
    src.positions[::2, 3, 0] = 1e300
    write_csv(src, tmp_path / "big.csv", "dumpkinectskeleton")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = info(tmp_path / "big.csv")
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in caught]
    src.position_mask[::2, 3] = False
    bones = body_checks.bone_lengths(src)
    shortest, longest = min(bones, key=bones.get), max(bones, key=bones.get)
    assert (
        f"bones           {len(bones)}, median length {np.median(list(bones.values())):.3g} m (shortest {shortest} "
        f"{bones[shortest]:.3g} m, longest {longest} {bones[longest]:.3g} m)"
    ) in out


def test_info_on_an_aligned_file_shows_frames_audio_offset_and_each_joints_validity(tmp_path):
    from kinectdata.align.recipe import align_files

    src = read_motion(REPO / "sample_data" / "synth_001.csv")
    src.positions[200:260, 7] = np.nan  # 2 s lost: a masked gap in one joint
    src.position_mask[200:260, 7] = False
    src.confidence[200:260, 7] = 0.0
    src.positions[300, 9, 1] = 1e300
    write_csv(src, tmp_path / "rec.csv", "dumpkinectskeleton")
    align_files(tmp_path / "rec.csv", REPO / "sample_data" / "synth_001.flac", tmp_path / "a.h5", offset=-0.8)
    with h5py.File(tmp_path / "a.h5", "r") as f:  # independent: the file's own datasets
        mask = f["motion/position_mask"][()]
        frames, samples, sr = mask.shape[0], f["audio/samples"].shape[0], int(f.attrs["sample_rate"])
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in f["joints/names"][()]]
    out = info(tmp_path / "a.h5")
    assert f"frames          {frames} at 30 fps, {frames / 30:.3f} s" in out
    assert f"audio           {samples} samples at {sr} Hz, {samples / sr:.3f} s" in out
    assert "offset          -0.800 s (given): audio time = motion time + offset" in out
    share = mask.mean(axis=0)
    whole = int((share == 1).sum())
    worst = int(np.argmin(share))
    assert worst == 7 and f"joints          {whole} of {len(names)} valid in every frame; least valid: " in out
    assert f"least valid: {names[7]} {100 * share[7]:.1f}%" in out
    assert "implausible     1 value(s) of the source masked as tracking loss when aligned" in out


def test_info_refuses_a_foreign_h5_in_one_line(tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = np.zeros(3)
    result = CliRunner().invoke(main, ["info", str(tmp_path / "other.h5")])
    assert result.exit_code == 1 and "other.h5" in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_a_reader_that_stops_reading_ends_info_quietly():
    """``kinectdata info FILE | head -1``: the command ends as a shell tool does when its reader goes
    (exit status 141, 128 + SIGPIPE), with nothing on standard error (it printed "Error: Broken pipe")."""
    import subprocess
    import sys

    command = [sys.executable, "-m", "kinectdata", "info", str(REPO / "sample_data" / "synth_001.csv")]
    p = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = p.stdout.readline()  # the file's name comes before the file is read: the rest follows later
    p.stdout.close()
    errors = p.stderr.read()
    p.wait(timeout=60)
    assert first.startswith(b"file ")
    assert (p.returncode, errors) == (141, b"")
