"""align: the exact grid, audio pairing, trimming, refusals, the HDF5 file and its atomicity."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import soundfile as sf
from conftest import REPO
from helpers import random_motion
from scipy.spatial.transform import Rotation

from kinectdata.align.aligned import AlignedRecording
from kinectdata.align.audio import load_audio
from kinectdata.align.recipe import align, align_files
from kinectdata.core.errors import AlignmentError, AudioError, FormatError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.dataset.collection import find_sessions
from kinectdata.formats import read_motion


@pytest.fixture
def noise_wav(tmp_path):
    """8 s of 44.1 kHz stereo noise: a stand-in for the music of the real fixture recording."""
    x = np.random.default_rng(0).uniform(-0.5, 0.5, (8 * 44100, 2)).astype(np.float32)
    path = tmp_path / "music.wav"
    sf.write(path, x, 44100, subtype="FLOAT")
    return path


def test_real_fixture_on_an_exact_grid_against_independent_interpolation(fixture_csv, noise_wav, tmp_path):
    offset = 0.75
    rec = align_files(fixture_csv, noise_wav, tmp_path / "out.h5", offset=offset)
    src = read_motion(fixture_csv)
    n = rec.n_frames
    np.testing.assert_array_equal(rec.motion.times, np.arange(n) / 30.0)
    # output time 0 is audio sample ceil(0.75 * 16000) = 12000, i.e. motion time 0
    motion_t = rec.motion.times + 12000 / 16000 - offset
    assert motion_t[-1] <= src.times[-1] < motion_t[-1] + 1 / 30
    j = src.joint_set.index("HandRight")
    for d in range(3):
        ref = np.interp(motion_t, src.times, src.positions[:, j, d])
        np.testing.assert_allclose(rec.motion.positions[:, j, d], ref, atol=1e-12)
    audio = load_audio(noise_wav)
    np.testing.assert_array_equal(rec.audio, audio.samples[12000 : 12000 + rec.audio.size])
    assert rec.audio.size == round((n + 1) * 16000 / 30)  # one more frame period, the source has it
    s = rec.summary
    dt = np.diff(src.times)
    assert s["dropped_frames"] == 2 and s["source_frames"] == 154
    # a Kinect v2 at 30 Hz stamping 32.9, 33.0 and 34.1 ms in turn: the median interval would say 30.30 fps
    assert np.median(dt) == pytest.approx(0.033, abs=1e-4)
    span_rate = (src.n_frames - 1 + 2) / (src.times[-1] - src.times[0])  # frame periods (2 dropped) over the span
    assert s["source_fps"] == pytest.approx(span_rate, rel=1e-3) and s["source_fps"] == pytest.approx(30.0, abs=0.01)
    assert s["offset_source"] == "given" and s["audio_trimmed_start_s"] == pytest.approx(0.75)


def test_saved_file_reads_back_identically(fixture_csv, noise_wav, tmp_path):
    rec = align_files(fixture_csv, noise_wav, tmp_path / "a.h5", offset=0.5)
    back = AlignedRecording.load(tmp_path / "a.h5")
    np.testing.assert_array_equal(back.motion.times, rec.motion.times)
    np.testing.assert_allclose(back.motion.positions, rec.motion.positions, atol=1e-6, equal_nan=True)
    np.testing.assert_array_equal(back.motion.position_mask, rec.motion.position_mask)
    np.testing.assert_array_equal(back.position_interpolated, rec.position_interpolated)
    np.testing.assert_array_equal(back.audio, rec.audio)
    assert back.offset == rec.offset and back.summary == rec.summary
    assert back.provenance.motion["sha256"] == rec.provenance.motion["sha256"]
    assert len(back.provenance.audio["sha256"]) == 64
    assert back.motion.joint_set.name == "kinect_v2"


def test_negative_offset_trims_the_motion_start(fixture_csv, noise_wav):
    rec = align_files(fixture_csv, noise_wav, offset=-0.4, min_coverage=0.5)
    assert rec.summary["motion_trimmed_start_s"] == pytest.approx(0.4, abs=1e-9)
    assert rec.summary["audio_trimmed_start_s"] == 0.0
    src = read_motion(fixture_csv)
    j = src.joint_set.index("Head")
    np.testing.assert_allclose(
        rec.motion.positions[:, j, 1], np.interp(rec.motion.times + 0.4, src.times, src.positions[:, j, 1])
    )


def test_audio_shorter_than_the_motion_is_refused(fixture_csv, tmp_path):
    short = tmp_path / "short.wav"
    sf.write(short, np.zeros(2 * 16000, np.float32), 16000)
    out = tmp_path / "never.h5"
    with pytest.raises(
        AlignmentError, match=r"short\.wav: the audio \(2\.00 s\) covers only .* shorter than the motion"
    ):
        align_files(fixture_csv, short, out, offset=0.0)
    assert list(tmp_path.iterdir()) == [short]  # nothing written, no temporary left behind


def test_unreadable_audio_and_bad_recording_leave_nothing(fixture_csv, noise_wav, tmp_path):
    junk = tmp_path / "junk.flac"
    junk.write_bytes(b"\x00" * 100)
    with pytest.raises(AudioError, match=r"junk\.flac: cannot read audio"):
        align_files(fixture_csv, junk, tmp_path / "o.h5", offset=0.0)
    bad = tmp_path / "bad.csv"
    bad.write_text(fixture_csv.read_text().replace("2.69467", "x", 1))
    with pytest.raises(FormatError, match=r"bad\.csv, line 1, column 'SpineBase.z': non-numeric value 'x'"):
        align_files(bad, noise_wav, tmp_path / "o.h5", offset=0.0)
    assert not (tmp_path / "o.h5").exists()


def test_every_sample_session_aligns_with_the_true_offset():
    sessions = find_sessions(REPO / "sample_data")
    assert len(sessions) == 3
    for s in sessions:
        rec = align_files(s.skeleton, s.audio, offset="auto")
        truth = s.load_truth()
        assert abs(rec.offset.seconds - truth["offset_s"]) < 1 / 30, s.name
        assert rec.offset.source == "clap"
        assert rec.motion.has_orientations and rec.n_frames > 500
        # the longer foot loss listed in the truth stays masked and is reported
        long_losses = {sp["joint"] for sp in truth["tracking_spans"] if sp["end_s"] - sp["start_s"] > 0.3}
        assert long_losses <= {g["joint"] for g in rec.gaps}
        q = rec.motion.orientations
        ok = rec.motion.orientation_mask[1:] & rec.motion.orientation_mask[:-1]
        assert (np.einsum("tjc,tjc->tj", q[1:], q[:-1])[ok] > 0).all()  # sign-continuous


def test_align_other_rates_and_options(fixture_csv, noise_wav):
    src = read_motion(fixture_csv)
    audio = load_audio(noise_wav, sample_rate=22050)
    rec = align(src, audio, fps=60.0, offset=0.1)
    assert rec.sample_rate == 22050 and rec.fps == 60.0
    np.testing.assert_array_equal(rec.motion.times, np.arange(rec.n_frames) / 60.0)
    with pytest.raises(Exception, match="fps must be a positive number"):
        align(src, audio, fps=0, offset=0.1)


def test_audio_ending_first_limits_the_frames_so_each_has_its_full_audio(tmp_path):
    sample = REPO / "sample_data" / "synth_003"
    x, sr = sf.read(f"{sample}.flac")
    cut = tmp_path / "cut.wav"
    sf.write(cut, x[: int(18.51 * sr)], sr)
    rec = align_files(f"{sample}.csv", cut, offset="auto", min_coverage=0.5)
    # every frame has its whole period of audio, and the kept audio ends with the source's
    assert round(rec.n_frames * 16000 / 30) <= rec.audio.size <= round((rec.n_frames + 1) * 16000 / 30)
    assert rec.n_frames / 30 <= 18.51 - rec.summary["audio_trimmed_start_s"] + 1e-9
    assert rec.summary["audio_trimmed_end_s"] == pytest.approx(0.0, abs=1 / 16000)


def test_too_little_overlap_is_refused_even_without_a_coverage_requirement(fixture_csv, noise_wav):
    for offset in (100.0, -100.0, -5.16):
        with pytest.raises(AlignmentError, match="overlap by less than two frames|covers only"):
            align_files(fixture_csv, noise_wav, offset=offset, min_coverage=0.0)


def test_short_edge_gap_is_not_reported_as_long(fixture_csv, noise_wav, tmp_path):
    lines = fixture_csv.read_text().splitlines()
    cells = lines[0].rstrip(",").split(",")
    cells[1 + 4 * 7 + 3] = "0"  # HandLeft not tracked in the first frame only
    lines[0] = ",".join(cells) + ","
    path = tmp_path / "edge.csv"
    path.write_text("\n".join(lines) + "\n")
    rec = align_files(path, noise_wav, offset=0.0)
    assert rec.gaps == [] and not rec.motion.position_mask[0, 7]


@pytest.mark.parametrize("fmt", ["htr", "ntu", "azure_json"])
def test_every_format_aligns_and_saves(fmt, tmp_path, noise_wav):
    m = random_motion(T=60, seed=2)
    if fmt == "htr":
        path = REPO / "tests" / "data" / "htr" / "two_segments.htr"
    elif fmt == "ntu":
        path = tmp_path / "S001C001P001R001A001.skeleton"
        lines = [str(m.n_frames)]
        q = Rotation.random(25, random_state=0).as_quat()[:, [3, 0, 1, 2]]
        for f in range(m.n_frames):
            lines += ["1", "72057594037931101 0 1 1 1 1 0 0.1 0.2 2", "25"]
            lines += [" ".join(map(str, [*np.nan_to_num(m.positions[f, j]), 0, 0, 0, 0, *q[j], 2])) for j in range(25)]
        path.write_text("\n".join(lines) + "\n")
    else:
        import json

        names = list(load_joint_set("azure_kinect").names)
        q = Rotation.random(32, random_state=0).as_quat()[:, [3, 0, 1, 2]].tolist()
        frames = [
            {
                "timestamp_usec": 1000 + 33333 * f,
                "frame_id": f,
                "num_bodies": 1,
                "bodies": [{"body_id": 1, "joint_positions": [[10.0 * f, 0, 2000]] * 32, "joint_orientations": q}],
            }
            for f in range(60)
        ]
        path = tmp_path / "azure.json"
        path.write_text(json.dumps({"joint_names": names, "bone_list": [], "frames": frames}))
    rec = align_files(path, noise_wav, tmp_path / "out.h5", offset=0.0, min_coverage=0.0)
    back = AlignedRecording.load(tmp_path / "out.h5")
    assert back.n_frames == rec.n_frames >= 2 and back.provenance.motion["format"] == fmt


def test_azure_skeleton_comes_out_upright(tmp_path):
    names = list(load_joint_set("azure_kinect").names)
    pos = np.zeros((32, 3))
    pos[names.index("HEAD")] = [100.0, -600.0, 2000.0]  # Azure: y down, so the head has smaller y
    pos[names.index("PELVIS")] = [100.0, 100.0, 2000.0]
    frames = [
        {
            "timestamp_usec": 33333 * f,
            "num_bodies": 1,
            "bodies": [{"body_id": 1, "joint_positions": pos.tolist(), "joint_orientations": [[1, 0, 0, 0]] * 32}],
        }
        for f in range(3)
    ]
    (tmp_path / "a.json").write_text(json.dumps({"joint_names": names, "frames": frames}))
    m = read_motion(tmp_path / "a.json")
    head, pelvis = m.joint_positions("HEAD")[0], m.joint_positions("PELVIS")[0]
    assert head[1] > pelvis[1] and head[0] == pytest.approx(-0.1)  # y up; x to the sensor's left


def test_absurd_positions_are_masked_as_tracking_loss_and_counted():
    """A recorder's overflow (1e300, inf) must not reach the aligned file as a valid position."""
    motion = read_motion(REPO / "sample_data" / "synth_001.csv")
    motion.positions[100, 3, 0] = 1e300
    motion.positions[200, 5, 1] = np.inf
    audio = load_audio(REPO / "sample_data" / "synth_001.flac")
    rec = align(motion, audio, offset=0.0)
    valid = rec.motion.position_mask
    assert np.isfinite(rec.motion.positions[valid]).all() and np.abs(rec.motion.positions[valid]).max() < 10
    assert rec.summary["implausible_positions"] == 2
    from kinectdata.align.recipe import format_summary

    assert "implausible     2 joint position(s)" in format_summary(rec)


def test_auto_offset_on_a_too_short_recording_is_one_line_naming_both_files():
    motion = read_motion(REPO / "sample_data" / "synth_001.csv").select(slice(0, 1))
    audio = load_audio(REPO / "sample_data" / "synth_001.flac")
    with pytest.raises(AlignmentError, match=r"synth_001.csv: 1 frame\(s\), 0.00 s: too short .*synth_001.flac"):
        align(motion, audio, offset="auto")


def test_an_ambiguous_offset_names_the_recording_and_the_audio(tmp_path):
    motion = read_motion(REPO / "sample_data" / "synth_001.csv")
    noise = np.random.default_rng(0).normal(0, 0.1, 16000 * 30).astype(np.float32)
    sf.write(tmp_path / "noise.wav", noise, 16000)
    with pytest.raises(AlignmentError, match=r"synth_001.csv with .*noise.wav: cannot determine the audio-to-motion"):
        align(motion, load_audio(tmp_path / "noise.wav"), offset="auto")


def test_audio_at_a_rate_no_music_has_is_refused_by_align_and_generate_alike(tmp_path, trained_run):
    sf.write(tmp_path / "one_hz.wav", np.zeros(30, np.float32), 1)
    with pytest.raises(AudioError, match=r"one_hz.wav: sample rate 1 Hz: too low for music \(at least 4000 Hz"):
        load_audio(tmp_path / "one_hz.wav")
    from click.testing import CliRunner

    from kinectdata.cli import main

    for args in (["align", str(REPO / "sample_data" / "synth_001.csv")], ["generate", "--run", str(trained_run[0])]):
        result = CliRunner().invoke(main, [*args, str(tmp_path / "one_hz.wav"), "-o", str(tmp_path / "out.csv")])
        assert result.exit_code == 1 and "sample rate 1 Hz: too low for music" in result.stderr, result.stderr


def test_auto_offset_with_audio_too_short_is_one_line_naming_both_files(tmp_path):
    """A few samples of audio crashed the envelopes (a ValueError from numpy) before any check."""
    motion = read_motion(REPO / "sample_data" / "synth_001.csv")
    for samples in (100, 16000):
        sf.write(tmp_path / "short.wav", np.full(samples, 0.01, np.float32), 16000)
        with pytest.raises(AlignmentError, match=r"short\.wav: [\d.]+ s of audio: too short .* to .*synth_001\.csv"):
            align(motion, load_audio(tmp_path / "short.wav"), offset="auto")


def test_too_little_coverage_names_the_recording_too(fixture_csv, tmp_path):
    sf.write(tmp_path / "short.wav", np.zeros(16000, np.float32), 16000)
    motion = read_motion(fixture_csv)
    with pytest.raises(
        AlignmentError, match=rf"short\.wav: .* of the motion's [\d.]+ s \({re.escape(str(fixture_csv))}\)"
    ):
        align(motion, load_audio(tmp_path / "short.wav"), offset=0.0)


def test_implausible_orientations_are_masked_and_counted():
    """A quaternion with a 1e300 component, or all zeros, is no rotation: masked like lost tracking."""
    motion = read_motion(REPO / "sample_data" / "synth_001.csv")
    joint = int(np.flatnonzero(motion.joint_set.orientation_mask)[1])
    motion.orientations[100, joint] = [1e300, 0.0, 0.0, 1.0]
    motion.orientations[101, joint] = [0.0, 0.0, 0.0, 0.0]
    assert motion.orientation_mask[100:102, joint].all()  # the container takes them as valid
    rec = align(motion, load_audio(REPO / "sample_data" / "synth_001.flac"), offset=0.0)
    q = rec.motion.orientations[rec.motion.orientation_mask]
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-6)
    assert rec.summary["implausible_orientations"] == 2 and rec.summary["implausible_positions"] == 0
    from kinectdata.align.recipe import format_summary

    assert "0 joint position(s) not finite or beyond 1000 m, 2 orientation(s)" in format_summary(rec)


def test_implausible_values_are_found_in_every_block_of_a_long_recording():
    """implausible_values checks a block of frames at a time: values at the first frame, on both sides
    of a block boundary and at the last frame are all found, and nothing else is."""
    from kinectdata.align.recipe import _CHECK_FRAMES, implausible_values

    js = load_joint_set("kinect_v2")
    n = 2 * _CHECK_FRAMES + 3
    pos = np.random.default_rng(0).normal(0, 1, (n, len(js), 3))
    quats = np.tile([0.0, 0.0, 0.0, 1.0], (n, len(js), 1))
    bad_positions = {(0, 1), (_CHECK_FRAMES - 1, 2), (_CHECK_FRAMES, 2), (n - 1, 24)}
    bad_orientations = {(5, 1), (2 * _CHECK_FRAMES, 4)}  # SpineMid, ShoulderLeft: joints with orientations
    for f, j in bad_positions:
        pos[f, j, 1] = 1e300
    for f, j in bad_orientations:
        quats[f, j] = [0.0, 0.0, 2.0, 2.0]
    motion = Motion(np.arange(n) / 30.0, pos, js, position_mask=np.isfinite(pos).all(-1), orientations=quats)
    positions, orientations = implausible_values(motion)
    assert {tuple(int(v) for v in i) for i in np.argwhere(positions)} == bad_positions
    assert {tuple(int(v) for v in i) for i in np.argwhere(orientations)} == bad_orientations


def test_the_dataset_path_through_the_recipe_steps_masks_implausible_positions_too():
    """build-dataset calls resolve_offset, plan_timeline, resample_onto and summarize itself, not align."""
    from kinectdata.align.recipe import plan_timeline, resample_onto, resolve_offset, summarize

    motion = read_motion(REPO / "sample_data" / "synth_001.csv")
    motion.positions[300:303, 7] = 1e300  # three frames of one joint: filled across (0.1 s < max_gap)
    motion.positions[400, 2, 1] = -np.inf
    audio = load_audio(REPO / "sample_data" / "synth_001.flac")
    offset = resolve_offset(motion, audio, "auto")
    truth = json.loads((REPO / "sample_data" / "synth_001.truth.json").read_text())
    assert offset.seconds == pytest.approx(truth["offset_s"], abs=1 / 30)  # the overflow is no clap
    tl = plan_timeline(motion, audio.samples.size, audio.sample_rate, offset.seconds)
    res, gaps = resample_onto(motion, tl)
    valid = res.motion.position_mask
    assert np.abs(res.motion.positions[valid]).max() < 10
    summary = summarize(motion, tl, res, gaps, offset, audio.samples.size, tl.kept_samples(audio.samples.size))
    assert summary["implausible_positions"] == 4


def test_the_summary_says_where_the_source_rate_comes_from(tmp_path):
    """A file with timestamps is timed by them; an NTU .skeleton has none (its frames are counted at
    a nominal 30 fps), and align says so instead of "from the timestamps"."""
    from test_ntu import make_body, skeleton_text

    from kinectdata.align.recipe import format_summary

    rng = np.random.default_rng(0)
    (tmp_path / "take.skeleton").write_text(skeleton_text([[("1", make_body(rng))] for _ in range(90)]), newline="")
    song = REPO / "sample_data" / "synth_001.flac"
    ntu = format_summary(align_files(tmp_path / "take.skeleton", song, offset=0.0))
    assert "90 frames, 30.00 fps (from frame index at nominal 30 fps)" in ntu, ntu
    csv = format_summary(align_files(REPO / "sample_data" / "synth_001.csv", song, offset=0.0))
    assert "fps (from the timestamps)" in csv
