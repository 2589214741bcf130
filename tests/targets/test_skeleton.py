"""Rest skeletons from recordings and forward kinematics from a target's orientations."""

from __future__ import annotations

import numpy as np
from conftest import REPO

from kinectdata.formats import read_motion
from kinectdata.synth import synthesize_recording
from kinectdata.targets.skeleton import bone_offsets, merge_bone_offsets, rebuild_positions
from kinectdata.targets.specs import extract_targets, load_target_spec

YALTA = load_target_spec("yalta65")


def test_true_motion_is_rebuilt_exactly_from_yalta65():
    """The synthetic dancer is posed by forward kinematics with frames pointing at the child: the
    measured offsets are its bones, and rebuilding gives its joints back to rounding."""
    motion = synthesize_recording(seed=3, duration_s=10.0).true_motion
    skeleton = bone_offsets(motion, YALTA)
    assert {v["frame"] for v in skeleton.values()} == {"parent"} and skeleton["SpineMid"]["spread"] < 1e-9
    values, mask = extract_targets(motion, YALTA)
    positions, placed = rebuild_positions(values, YALTA, skeleton)
    js = motion.joint_set
    reached = {js.names[j] for j in np.flatnonzero(placed[0])}
    # the three listed positions and every joint whose parent's frame is in yalta65 (the thumbs hang
    # off the wrists; not the hand tips and feet: HandLeft/Right and the ankles carry no orientation in it)
    assert reached == {
        *("SpineBase", "SpineMid", "SpineShoulder", "Neck", "Head"),
        *("ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft", "ShoulderRight", "ElbowRight", "WristRight"),
        *("HandRight", "HipLeft", "KneeLeft", "AnkleLeft", "HipRight", "KneeRight", "AnkleRight"),
        *("ThumbLeft", "ThumbRight"),
    }
    np.testing.assert_allclose(positions[placed], motion.positions[placed], atol=1e-9)


def test_a_noisy_recording_gives_a_skeleton_within_centimetres():
    motion = read_motion(REPO / "sample_data" / "synth_001.csv")
    skeleton = merge_bone_offsets([bone_offsets(motion, YALTA), bone_offsets(motion, YALTA)])
    values, mask = extract_targets(motion, YALTA)
    positions, placed = rebuild_positions(values, YALTA, skeleton)
    ok = placed & motion.position_mask
    error = np.linalg.norm(positions[ok] - motion.positions[ok], axis=-1)
    assert np.median(error) < 0.02 and np.percentile(error, 95) < 0.05


def test_masked_orientations_leave_their_subtree_unplaced():
    motion = synthesize_recording(seed=3, duration_s=10.0).true_motion
    skeleton = bone_offsets(motion, YALTA)
    values, mask = extract_targets(motion, YALTA)
    elbow = YALTA.columns("ElbowLeft", "orientation")
    values[:5, elbow] = 0.0  # masked quaternions are stored as 0
    positions, placed = rebuild_positions(values, YALTA, skeleton)
    js = motion.joint_set
    assert not placed[:5, js.index("WristLeft")].any() and placed[5:, js.index("WristLeft")].all()
    assert placed[:5, js.index("ElbowLeft")].all()


def test_positions_only_targets_have_no_skeleton():
    motion = synthesize_recording(seed=3, duration_s=10.0).true_motion
    assert bone_offsets(motion, load_target_spec("kinect_v2_positions")) == {}
    assert merge_bone_offsets([]) == {}


def test_root_centred_targets_are_put_back_around_the_root():
    """With root-centring the hands are offsets from the root at each frame: the rebuilt hands must
    sit on the rebuilt wrists even when the dancer travels."""
    motion = synthesize_recording(seed=3, duration_s=10.0).true_motion
    motion.positions[:, :, 0] += np.linspace(0, 2.0, motion.n_frames)[:, None]  # travel 2 m sideways
    skeleton = bone_offsets(motion, YALTA)
    values, _ = extract_targets(motion, YALTA, root_centre=True)
    positions, placed = rebuild_positions(values, YALTA, skeleton, root_centred=True)
    js = motion.joint_set
    hand, wrist = js.index("HandRight"), js.index("WristRight")
    gap = np.linalg.norm(positions[:, hand] - positions[:, wrist], axis=-1)
    true_gap = np.linalg.norm(motion.positions[:, hand] - motion.positions[:, wrist], axis=-1)
    np.testing.assert_allclose(gap, true_gap, atol=1e-9)
