"""Azure Kinect offline-processor JSON reader: values against documents built here, and bad input."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.formats import detect_format, read_motion
from kinectdata.formats.azure_json import _sniff, read_azure_json

# As the SDK's offline processor writes them (older SDKs spell SPINE_NAVAL).
NAMES = [
    "PELVIS", "SPINE_NAVAL", "SPINE_CHEST", "NECK", "CLAVICLE_LEFT", "SHOULDER_LEFT", "ELBOW_LEFT",
    "WRIST_LEFT", "HAND_LEFT", "HANDTIP_LEFT", "THUMB_LEFT", "CLAVICLE_RIGHT", "SHOULDER_RIGHT",
    "ELBOW_RIGHT", "WRIST_RIGHT", "HAND_RIGHT", "HANDTIP_RIGHT", "THUMB_RIGHT", "HIP_LEFT", "KNEE_LEFT",
    "ANKLE_LEFT", "FOOT_LEFT", "HIP_RIGHT", "KNEE_RIGHT", "ANKLE_RIGHT", "FOOT_RIGHT", "HEAD", "NOSE",
    "EYE_LEFT", "EAR_LEFT", "EYE_RIGHT", "EAR_RIGHT",
]  # fmt: skip
# The SDK sample's g_boneList: note the pairs are not all (parent, child).
BONES = [
    ("SPINE_CHEST", "SPINE_NAVAL"), ("SPINE_NAVAL", "PELVIS"), ("SPINE_CHEST", "NECK"), ("NECK", "HEAD"),
    ("HEAD", "NOSE"), ("SPINE_CHEST", "CLAVICLE_LEFT"), ("CLAVICLE_LEFT", "SHOULDER_LEFT"),
    ("SHOULDER_LEFT", "ELBOW_LEFT"), ("ELBOW_LEFT", "WRIST_LEFT"), ("WRIST_LEFT", "HAND_LEFT"),
    ("HAND_LEFT", "HANDTIP_LEFT"), ("WRIST_LEFT", "THUMB_LEFT"), ("PELVIS", "HIP_LEFT"), ("HIP_LEFT", "KNEE_LEFT"),
    ("KNEE_LEFT", "ANKLE_LEFT"), ("ANKLE_LEFT", "FOOT_LEFT"), ("NOSE", "EYE_LEFT"), ("EYE_LEFT", "EAR_LEFT"),
    ("SPINE_CHEST", "CLAVICLE_RIGHT"), ("CLAVICLE_RIGHT", "SHOULDER_RIGHT"), ("SHOULDER_RIGHT", "ELBOW_RIGHT"),
    ("ELBOW_RIGHT", "WRIST_RIGHT"), ("WRIST_RIGHT", "HAND_RIGHT"), ("HAND_RIGHT", "HANDTIP_RIGHT"),
    ("WRIST_RIGHT", "THUMB_RIGHT"), ("PELVIS", "HIP_RIGHT"), ("HIP_RIGHT", "KNEE_RIGHT"),
    ("KNEE_RIGHT", "ANKLE_RIGHT"), ("ANKLE_RIGHT", "FOOT_RIGHT"), ("NOSE", "EYE_RIGHT"), ("EYE_RIGHT", "EAR_RIGHT"),
]  # fmt: skip
T0 = 1_234_567  # first device timestamp, microseconds

AXES = np.array([-1.0, -1.0, 1.0])  # Azure (x right, y down) -> Kinect v2 (x left, y up)


def make_body(rng: np.random.Generator, body_id, n_joints: int = 32) -> tuple[dict, np.ndarray, np.ndarray]:
    """A body entry and its positions [J, 3] mm and quaternions [J, 4] (w, x, y, z)."""
    pos = np.round(rng.uniform(-2000, 4000, (n_joints, 3)), 3)
    q = rng.normal(size=(n_joints, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    entry = {"body_id": body_id, "joint_positions": pos.tolist(), "joint_orientations": q.tolist()}
    return entry, pos, q


def make_doc(frames: list[tuple[int, list[dict]]], names=NAMES, bones=BONES) -> dict:
    return {
        "k4abt_sdk_version": "1.1.2",
        "source_file": "C:/recordings/dance.mkv",
        "joint_names": list(names),
        "bone_list": [list(b) for b in bones],
        "frames": [
            {"timestamp_usec": t, "frame_id": i, "num_bodies": len(bodies), "bodies": bodies}
            for i, (t, bodies) in enumerate(frames)
        ],
    }


def write(tmp_path, doc, name: str = "dance.json"):
    path = tmp_path / name
    # nlohmann::json, as the offline processor uses it, sorts keys and indents by 4
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc, indent=4, sort_keys=True))
    return path


@pytest.fixture
def two_bodies():
    """Six frames: body 1 in frames 0, 1, 5; body 2 in frames 1, 2, 4, 5; nobody in frame 3."""
    rng = np.random.default_rng(7)
    t = [T0 + k * 33_344 for k in range(6)]
    b1 = [make_body(rng, 1) for _ in range(6)]
    b2 = [make_body(rng, 2) for _ in range(6)]
    frames = [
        (t[0], [b1[0][0]]),
        (t[1], [b1[1][0], b2[1][0]]),
        (t[2], [b2[2][0]]),
        (t[3], []),  # nobody
        (t[4], [b2[4][0]]),
        (t[5], [b2[5][0], b1[5][0]]),
    ]
    return make_doc(frames), t, b1, b2


def test_values(tmp_path, two_bodies):
    doc, t, b1, b2 = two_bodies
    m = read_azure_json(write(tmp_path, doc))

    assert m.joint_set is load_joint_set("azure_kinect")  # SPINE_NAVAL matched through the alias
    assert m.metadata["body"] == "2"  # 4 frames against 3
    assert m.metadata["bodies"] == {"1": 3, "2": 4}
    np.testing.assert_allclose(m.times, (np.array(t) - T0) / 1e6, rtol=0, atol=1e-12)
    assert m.times[0] == 0.0
    assert m.metadata["time_origin"] == {"value": T0, "unit": "us"}
    assert m.metadata["k4abt_sdk_version"] == "1.1.2"
    assert m.metadata["source_file"] == "C:/recordings/dance.mkv"
    assert m.metadata["format"] == "azure_json"

    present = np.array([False, True, True, False, True, True])
    assert (m.position_mask.all(axis=1) == present).all() and not m.position_mask[~present].any()
    assert (m.confidence[present] == 1.0).all() and (m.confidence[~present] == 0.0).all()
    assert np.isnan(m.positions[~present]).all() and not m.orientation_mask[~present].any()
    for f in np.flatnonzero(present):
        _, pos, q = b2[f]
        np.testing.assert_allclose(m.positions[f], pos / 1000.0 * AXES, rtol=1e-15)
        # orientation in Kinect v2 axes: the file's rotation (w, x, y, z) turned 180 deg about z
        expected = np.diag(AXES) @ Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()
        np.testing.assert_allclose(Rotation.from_quat(m.orientations[f]).as_matrix(), expected, atol=1e-12)

    m1 = read_azure_json(write(tmp_path, doc), body="1")
    assert m1.metadata["body"] == "1"
    assert list(m1.position_mask.all(axis=1)) == [True, True, False, False, False, True]
    np.testing.assert_allclose(m1.positions[5], b1[5][1] / 1000.0 * AXES, rtol=1e-15)  # second entry of its frame


def test_tie_goes_to_first_and_zero_quaternion_masked(tmp_path):
    rng = np.random.default_rng(8)
    a, pa, _ = make_body(rng, 5)
    b, _, _ = make_body(rng, 3)
    a["joint_orientations"][9] = [0, 0, 0, 0]
    m = read_azure_json(write(tmp_path, make_doc([(100, [b]), (200, [a])])))
    assert m.metadata["body"] == "3"
    m = read_azure_json(write(tmp_path, make_doc([(100, [b]), (200, [a])])), body="5")
    assert not m.orientation_mask[1, 9] and m.orientation_mask[1, :9].all()
    np.testing.assert_allclose(m.positions[1, 9], pa[9] / 1000.0 * AXES)


def test_custom_joint_set_from_bone_list(tmp_path):
    rng = np.random.default_rng(9)
    names = ["PELVIS", "SPINE", "HEAD", "HAND"]
    bones = [("SPINE", "PELVIS"), ("SPINE", "HEAD"), ("HAND", "SPINE")]  # directions mixed on purpose
    entry, pos, _ = make_body(rng, 0, n_joints=4)
    m = read_azure_json(write(tmp_path, make_doc([(0, [entry])], names, bones)))
    assert m.joint_set.name == "azure_kinect_4"
    assert m.joint_set.names == tuple(names)
    assert m.joint_set.parents == (-1, 0, 1, 1)
    np.testing.assert_allclose(m.positions[0], pos / 1000.0 * AXES)


def test_read_motion_detects_by_content(tmp_path, two_bodies):
    doc = two_bodies[0]
    path = write(tmp_path, doc, name="take1.json")
    head = path.read_bytes()[:4096]
    assert b'"joint_names"' not in head and b'"k4abt_sdk_version"' not in head  # sorted keys put them last
    assert detect_format(path) == "azure_json"
    m = read_motion(path, body="1")
    assert m.metadata["format"] == "azure_json" and m.metadata["body"] == "1"
    assert _sniff(path, json.dumps(doc).encode()[:4096])  # insertion order, no indentation
    assert not _sniff(path, b'{"version": 1.3, "people": [{"pose_keypoints_2d": [1, 2, 0.5]}]}')
    assert not _sniff(path, b"0\n1\n")


# -- bad input -------------------------------------------------------------------------------------


def check(path, *words: str, frame: int | None = None, line: int | None = None, body=None) -> FormatError:
    with pytest.raises(FormatError) as info:
        read_azure_json(path, body=body)
    msg = str(info.value)
    assert path.name in msg
    assert info.value.frame == frame and info.value.line == line
    if frame is not None:
        assert f"frame {frame}" in msg
    if line is not None:
        assert f"line {line}" in msg
    for w in words:
        assert re.search(w, msg), (w, msg)
    return info.value


def test_empty_file(tmp_path):
    check(write(tmp_path, ""), "empty", line=1)


def test_json_syntax_error(tmp_path, two_bodies):
    text = json.dumps(two_bodies[0], indent=4, sort_keys=True).splitlines()
    cut = next(i for i in range(len(text) // 2, len(text)) if text[i].endswith(","))
    text[cut] = text[cut][:-1]  # drop a comma
    line = cut + 2  # the decoder stops at the next value
    check(write(tmp_path, "\n".join(text)), "invalid JSON", line=line)
    check(write(tmp_path, json.dumps(two_bodies[0])[:-200]), "invalid JSON", line=1)  # truncated


def test_not_an_object(tmp_path):
    check(write(tmp_path, "[1, 2]"), "top level must be a JSON object")


@pytest.mark.parametrize("key", ["joint_names", "frames"])
def test_missing_top_level_key(tmp_path, two_bodies, key):
    doc = two_bodies[0]
    del doc[key]
    check(write(tmp_path, doc), f"missing top-level key '{key}'")


@pytest.mark.parametrize("key", ["timestamp_usec", "num_bodies", "bodies"])
def test_missing_frame_key(tmp_path, two_bodies, key):
    doc = two_bodies[0]
    del doc["frames"][2][key]
    check(write(tmp_path, doc), f"missing key '{key}'", frame=2)


@pytest.mark.parametrize("key", ["body_id", "joint_positions", "joint_orientations"])
def test_missing_body_key(tmp_path, two_bodies, key):
    doc = two_bodies[0]
    del doc["frames"][1]["bodies"][1][key]
    check(write(tmp_path, doc), rf"bodies\[1\] has no '{key}'", frame=1)


@pytest.mark.parametrize("delta", [0, -5])
def test_timestamps_not_increasing(tmp_path, two_bodies, delta):
    doc, t = two_bodies[0], two_bodies[1]
    doc["frames"][4]["timestamp_usec"] = t[3] + delta
    check(write(tmp_path, doc), f"timestamp_usec {t[3] + delta} is not after the previous frame's {t[3]}", frame=4)


def test_bad_timestamp_type(tmp_path, two_bodies):
    doc = two_bodies[0]
    doc["frames"][0]["timestamp_usec"] = "12:00"
    check(write(tmp_path, doc), "timestamp_usec must be a number", frame=0)


def test_wrong_joint_list_length(tmp_path, two_bodies):
    doc = two_bodies[0]
    doc["frames"][5]["bodies"][1]["joint_positions"].pop()
    check(write(tmp_path, doc), r"bodies\[1\]\.joint_positions must list 32 joints", "found 31", frame=5)


def test_wrong_vector_length(tmp_path, two_bodies):
    doc = two_bodies[0]
    doc["frames"][2]["bodies"][0]["joint_orientations"][7] = [1.0, 0.0, 0.0]
    check(write(tmp_path, doc), r"bodies\[0\]\.joint_orientations\[7\] \(WRIST_LEFT\) must be 4", frame=2)


@pytest.mark.parametrize("value", ["NaN", "Infinity", "null", '"abc"'])
def test_bad_numbers(tmp_path, two_bodies, value):
    doc = two_bodies[0]
    doc["frames"][4]["bodies"][0]["joint_positions"][3][1] = "@@"
    text = json.dumps(doc, indent=4, sort_keys=True).replace('"@@"', value)
    check(write(tmp_path, text), r"bodies\[0\]\.joint_positions\[3\] \(NECK\)", frame=4)


def test_num_bodies_mismatch(tmp_path, two_bodies):
    doc = two_bodies[0]
    doc["frames"][1]["num_bodies"] = 3
    check(write(tmp_path, doc), "num_bodies 3 does not match the 2 entries", frame=1)


def test_duplicate_body_in_frame(tmp_path, two_bodies):
    doc = two_bodies[0]
    doc["frames"][1]["bodies"][1]["body_id"] = 1
    check(write(tmp_path, doc), "body_id 1 appears twice", frame=1)


def test_unknown_body(tmp_path, two_bodies):
    check(write(tmp_path, two_bodies[0]), "no body with id '9'", r"1 \(3 frames\), 2 \(4 frames\)", body="9")


def test_no_frames_or_no_bodies(tmp_path):
    check(write(tmp_path, make_doc([])), "no frames")
    check(write(tmp_path, make_doc([(1, []), (2, [])])), "no body appears in any of the 2 frames")


def test_bad_quaternion_norm(tmp_path, two_bodies):
    doc = two_bodies[0]
    doc["frames"][2]["bodies"][0]["joint_orientations"][0] = [0.5, 0.5, 0.5, 0.2]
    check(write(tmp_path, doc), r"joint_orientations\[0\] \(PELVIS\) has norm", frame=2)


def test_bad_joint_names_and_bones(tmp_path):
    rng = np.random.default_rng(10)
    entry = make_body(rng, 0, n_joints=3)[0]
    check(write(tmp_path, make_doc([(0, [entry])], ["A", "B", "A"], [])), "'A' twice")
    check(write(tmp_path, make_doc([(0, [entry])], ["A", "B", "C"], [("A", "Z")])), r"bone_list\[0\]", "'Z'")
    bones = [("A", "B"), ("B", "C"), ("C", "A")]
    check(write(tmp_path, make_doc([(0, [entry])], ["A", "B", "C"], bones)), "cycle")
