"""Writing any recording in any format the writers know (``kd.write_motion``, ``kinectdata convert``):
each reader-writer pair that can carry the data reads back equal, what a format cannot carry is
named in one line, and a motion a format cannot hold is refused with nothing left behind."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO
from scipy.spatial.transform import Rotation

import kinectdata as kd
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.core.jointsets import JointSet, load_joint_set
from kinectdata.formats import read_motion

KINECT_CSV = REPO / "tests" / "data" / "kinect_v2_csv" / "Ges01_wavehand.csv"


def _rigid_motion(frames: int = 24, seed: int = 0, joint_set: str = "kinect_v2") -> kd.Motion:
    """A body of fixed bone lengths turning every joint at random (forward kinematics), its root
    travelling, at 30 fps from t = 2 s, with orientations: what every 3-D writer can carry."""
    js = load_joint_set(joint_set)
    rng = np.random.default_rng(seed)
    J = len(js)
    offsets = rng.normal(0, 0.15, (J, 3))
    local = Rotation.random(frames * J, random_state=seed).as_matrix().reshape(frames, J, 3, 3)
    glob, pos = np.zeros((frames, J, 3, 3)), np.zeros((frames, J, 3))
    done: set[int] = set()
    while len(done) < J:  # parents first
        for j, p in enumerate(js.parents):
            if j in done or (p >= 0 and p not in done):
                continue
            if p < 0:
                glob[:, j], pos[:, j] = local[:, j], rng.normal(0, 1, (frames, 3))
            else:
                glob[:, j] = glob[:, p] @ local[:, j]
                pos[:, j] = pos[:, p] + np.einsum("tab,b->ta", glob[:, p], offsets[j])
            done.add(j)
    quats = Rotation.from_matrix(glob.reshape(-1, 3, 3)).as_quat().reshape(frames, J, 4)
    return kd.Motion(times=2.0 + np.arange(frames) / 30.0, positions=pos, joint_set=js, orientations=quats)


def _same_rotations(a: np.ndarray, b: np.ndarray) -> float:
    """The largest angle, radians, between the rotations of two [..., 4] quaternion arrays."""
    ra, rb = Rotation.from_quat(a.reshape(-1, 4)), Rotation.from_quat(b.reshape(-1, 4))
    return float((ra.inv() * rb).magnitude().max())


def test_the_writers_registered_are_the_ones_convert_offers():
    from kinectdata.cli.convert import convert

    offered = next(p for p in convert.params if p.name == "out_format").type.choices
    from kinectdata.apps.convert import writers

    assert sorted(offered) == sorted(writers())


def test_a_kinect_recording_to_canonical_csv_and_arrays_reads_back_whole(tmp_path):
    motion = read_motion(KINECT_CSV)
    assert not motion.position_mask.all() or motion.confidence.min() < 1  # gaps or inferred joints to keep
    for name, reading in (("take.csv", {}), ("take.npz", {"schema": tmp_path / "take.schema.json"})):
        written = kd.write_motion(motion, tmp_path / name)
        assert written.lost == ()
        back = read_motion(tmp_path / name, **reading)
        assert back.joint_set == motion.joint_set
        np.testing.assert_array_equal(back.position_mask, motion.position_mask)
        np.testing.assert_allclose(back.positions, motion.positions, atol=5e-7)  # the CSV's 6 decimals
        np.testing.assert_allclose(back.confidence, motion.confidence, atol=5e-7)
        np.testing.assert_allclose(back.times, motion.times, atol=5e-7)


def test_orientations_and_a_time_origin_survive_csv_and_arrays(tmp_path):
    motion = _rigid_motion()
    for name, reading in (("rigid.csv", {}), ("rigid.npz", {"schema": tmp_path / "rigid.schema.json"})):
        kd.write_motion(motion, tmp_path / name)
        back = read_motion(tmp_path / name, **reading)
        np.testing.assert_allclose(back.positions, motion.positions, atol=5e-7)
        np.testing.assert_array_equal(back.orientation_mask, motion.orientation_mask)  # leaves have none
        ok = motion.orientation_mask
        assert _same_rotations(back.orientations[ok], motion.orientations[ok]) < 1e-5
        assert back.metadata["time_origin"]["value"] == pytest.approx(2.0)  # times read from the first frame
        np.testing.assert_allclose(back.times, motion.times - 2.0, atol=5e-7)


def test_a_joint_set_kinectdata_does_not_ship_travels_with_the_arrays(tmp_path):
    base = load_joint_set("kinect_v2")
    names = [f"j{i}" for i in range(len(base))]
    own = JointSet.custom("my_rig", names, [None if p < 0 else names[p] for p in base.parents])
    motion = dataclasses.replace(_rigid_motion(), joint_set=own, orientations=None, orientation_mask=None)
    kd.write_motion(motion, tmp_path / "rig.npz")
    schema = json.loads((tmp_path / "rig.schema.json").read_text())
    assert schema["joint_set"] == "rig.joints.json" and (tmp_path / "rig.joints.json").exists()
    back = read_motion(tmp_path / "rig.npz", schema=tmp_path / "rig.schema.json")
    assert (back.joint_set.name, back.joint_set.names, back.joint_set.parents) == ("my_rig", own.names, own.parents)
    np.testing.assert_array_equal(back.positions, motion.positions)


def test_a_rigid_body_as_bvh_comes_back_at_its_positions_and_says_what_bvh_drops(tmp_path):
    rigid = dataclasses.replace(_rigid_motion(seed=3), orientations=None, orientation_mask=None)
    written = kd.write_motion(rigid, tmp_path / "rigid.bvh")
    assert [line.split(" (")[0] for line in written.lost] == [
        "the kinect_v2 joint set's roles, sides and SMPL-24 mapping"
    ]
    back = read_motion(tmp_path / "rigid.bvh")
    index = [back.joint_set.names.index(n) for n in rigid.joint_set.names]
    np.testing.assert_allclose(back.positions[:, index], rigid.positions, atol=2e-6)  # cm to 6 decimals
    np.testing.assert_allclose(back.times, rigid.times - rigid.times[0], atol=1e-8)


def test_a_kinect_recording_as_bvh_names_each_thing_left_out(tmp_path):
    written = kd.write_motion(read_motion(KINECT_CSV), tmp_path / "take.bvh")
    said = " | ".join(written.lost)
    assert "the confidences (BVH has none)" in said
    assert "bone lengths that change from frame to frame" in said  # a sensor's bones stretch
    assert "the frames' own times" in said  # the recorder's clock jitters
    assert written.describe().startswith(f"wrote {tmp_path / 'take.bvh'} (bvh); not carried: ")


def test_smpl24_arrays_read_back_with_the_shipped_schema(tmp_path):
    motion = _rigid_motion(frames=60, joint_set="smpl24")
    motion = dataclasses.replace(motion, times=np.arange(60) / 60.0, orientations=None, orientation_mask=None)
    written = kd.write_motion(motion, tmp_path / "dance.npy")
    assert written.format == "smpl24"
    assert written.lost == ("the frame times (resampled from the first frame to --fps)",)
    assert np.load(tmp_path / "dance.npy").dtype == np.float32
    back = read_motion(tmp_path / "dance.npy", schema="smpl24")
    np.testing.assert_allclose(back.positions, motion.positions, atol=1e-5)  # float32 of metres
    kd.write_motion(motion, tmp_path / "dance30.npy", fps=30.0)
    half = read_motion(tmp_path / "dance30.npy", schema="smpl24", array_fps=30.0)
    np.testing.assert_allclose(half.positions, motion.positions[::2], atol=1e-5)  # every other frame


def test_a_2d_openpose_recording_round_trips_as_json_lines(tmp_path):
    js = load_joint_set("openpose_mpi")
    rng = np.random.default_rng(1)
    positions = rng.uniform(0, 640, (12, len(js), 2))
    confidence = rng.uniform(0.2, 1.0, (12, len(js)))
    motion = kd.Motion(times=np.arange(12) / 25.0, positions=positions, joint_set=js, confidence=confidence)
    written = kd.write_motion(motion, tmp_path / "pose.jsonl")
    assert "frame times" in written.lost[0]
    back = read_motion(tmp_path / "pose.jsonl", video_fps=25.0)
    np.testing.assert_allclose(back.positions, positions, atol=5e-7)
    np.testing.assert_allclose(back.confidence, confidence, atol=5e-7)
    np.testing.assert_allclose(back.times, motion.times, atol=1e-12)


def test_what_a_format_cannot_hold_is_refused_naming_the_output_and_nothing_is_left(tmp_path):
    motion = read_motion(KINECT_CSV)
    with pytest.raises(ConfigError, match=r"take\.txt: no writer claims its extension"):
        kd.write_motion(motion, tmp_path / "take.txt")
    with pytest.raises(KinectDataError, match=r"pose\.jsonl: OpenPose JSON holds openpose_mpi joints"):
        kd.write_motion(motion, tmp_path / "pose.jsonl")
    with pytest.raises(ConfigError, match="option.s. unit do not apply to the csv writer"):
        kd.write_motion(motion, tmp_path / "take.csv", unit="m")
    flat = kd.Motion(
        times=np.arange(3) / 30.0, positions=np.zeros((3, 15, 2)), joint_set=load_joint_set("openpose_mpi")
    )
    with pytest.raises(KinectDataError, match=r"flat\.npz: joint arrays hold 3-D joints"):
        kd.write_motion(flat, tmp_path / "flat.npz")
    assert list(tmp_path.iterdir()) == []


def test_convert_on_the_command_line_says_what_it_left_out(tmp_path):
    out = tmp_path / "take.bvh"
    run = subprocess.run(
        [sys.executable, "-m", "kinectdata", "convert", str(KINECT_CSV), "-o", str(out)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.count("\n") == 1 and "not carried: " in run.stdout and out.exists()
    bad = subprocess.run(
        [sys.executable, "-m", "kinectdata", "convert", str(KINECT_CSV), "-o", str(tmp_path / "t.csv"), "--fps", "30"],
        capture_output=True,
        text=True,
    )
    assert bad.returncode != 0 and "--fps applies to a smpl24 output" in bad.stderr
    assert "Traceback" not in bad.stderr and not (tmp_path / "t.csv").exists()


@pytest.mark.parametrize(
    "source, reading",
    [
        (REPO / "tests" / "data" / "htr" / "two_segments.htr", {}),  # a joint set read from the file, orientations
        (REPO / "sample_data" / "synth_001.csv", {}),  # a Kinect v2 export with gaps and inferred joints
    ],
    ids=["htr", "kinect_csv"],
)
def test_other_readers_go_through_the_lossless_writers_whole(tmp_path, source, reading):
    motion = read_motion(source, **reading)
    for name, back_reading in (("out.csv", {}), ("out.npz", {"schema": tmp_path / "out.schema.json"})):
        assert kd.write_motion(motion, tmp_path / name).lost == ()
        back = read_motion(tmp_path / name, **back_reading)
        assert (back.joint_set.names, back.joint_set.parents) == (motion.joint_set.names, motion.joint_set.parents)
        np.testing.assert_array_equal(back.position_mask, motion.position_mask)
        np.testing.assert_allclose(back.positions, motion.positions, atol=5e-7)
        np.testing.assert_allclose(back.times, motion.times, atol=5e-7)
        if motion.has_orientations:
            ok = motion.orientation_mask
            np.testing.assert_array_equal(back.orientation_mask, ok)
            assert _same_rotations(back.orientations[ok], motion.orientations[ok]) < 1e-5
