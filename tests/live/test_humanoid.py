"""The humanoid derived from a joint set (kinectdata.live.humanoid): which joints each Unity bone
runs between, checked against what a rigger would pick by hand, and the rotations a BVH in T-pose
gets (none: every bone already lies along its rest direction)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import JointSet, load_joint_set
from kinectdata.formats import read_motion
from kinectdata.live.humanoid import MappingError, humanoid_mapping, side_of
from kinectdata.live.vmc import HUMAN_BODY_BONES, TO_UNITY, VmcRig

TOP = ("UpperChest", "Chest", "Spine", "Hips")
UNITY_PARENTS = {
    "Hips": None, "Spine": "Hips", "Chest": "Spine", "UpperChest": "Chest", "Neck": TOP, "LeftShoulder": TOP,
    "LeftUpperArm": ("LeftShoulder",), "LeftLowerArm": "LeftUpperArm", "LeftHand": "LeftLowerArm",
    "LeftUpperLeg": "Hips", "LeftLowerLeg": "LeftUpperLeg", "LeftFoot": "LeftLowerLeg", "LeftToes": "LeftFoot",
}  # fmt: skip
"""Unity's humanoid hierarchy (the left side; the right mirrors it): a bone's parent, or the bones
one of which is its parent when the ones between are absent."""


def _unity_parent_ok(bone: str, parent: str | None) -> bool:
    allowed = UNITY_PARENTS[bone.replace("Right", "Left")]
    allowed = allowed if isinstance(allowed, tuple) else (allowed,)
    return (parent.replace("Right", "Left") if parent else None) in allowed


# what a rigger would pick by hand: (bone, joint, aim) for each shipped 3-D set
BY_HAND = {
    "tang2018": [("Hips", "pelvis", "spine"), ("LeftUpperArm", "left_shoulder", "left_elbow"),
                 ("LeftHand", "left_wrist", "left_hand"), ("RightLowerLeg", "right_knee", "right_ankle"),
                 ("RightFoot", "right_ankle", "right_toe")],
    "smpl24": [("Hips", "pelvis", "spine1"), ("Chest", "spine2", "spine3"), ("UpperChest", "spine3", "neck"),
               ("Neck", "neck", "head"), ("LeftShoulder", "left_collar", "left_shoulder"),
               ("RightFoot", "right_ankle", "right_foot")],
    "nite": [("Hips", "TORSO", "NECK"), ("LeftLowerArm", "LEFT_ELBOW", "LEFT_HAND"),
             ("RightLowerLeg", "RIGHT_KNEE", "RIGHT_FOOT")],
    "azure_kinect": [("Spine", "SPINE_NAVEL", "SPINE_CHEST"), ("LeftShoulder", "CLAVICLE_LEFT", "SHOULDER_LEFT"),
                     ("LeftHand", "WRIST_LEFT", "HAND_LEFT"), ("LeftFoot", "ANKLE_LEFT", "FOOT_LEFT")],
    "smplh52": [("LeftHand", "left_wrist", "left_middle1")],
    "kinect_v2": [("LeftShoulder", "SpineShoulder", "ShoulderLeft"), ("LeftFoot", "AnkleLeft", "FootLeft"),
                  ("RightHand", "WristRight", "HandRight")],
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(BY_HAND))
def test_each_shipped_set_becomes_the_humanoid_a_rigger_would_map(name):
    joint_set = load_joint_set(name)
    doc = humanoid_mapping(joint_set)
    bones = {b["bone"]: b for b in doc["bones"]}
    for bone, joint, aim in BY_HAND[name]:
        assert (bones[bone]["joint"], bones[bone]["aim"]) == (joint, aim), bone
    assert doc["bones"][0]["bone"] == "Hips" and doc["bones"][0]["parent"] is None
    for b in doc["bones"]:
        assert b["bone"] in HUMAN_BODY_BONES and _unity_parent_ok(b["bone"], b["parent"]), b
    limbs = {"LeftUpperArm", "LeftLowerArm", "RightUpperArm", "RightLowerArm"}
    limbs |= {f"{s}{p}" for s in ("Left", "Right") for p in ("UpperLeg", "LowerLeg")}
    assert limbs <= set(bones)
    assert side_of(doc["left_hip"]) == "Left" and side_of(doc["right_hip"]) == "Right"


MIXAMO = [  # name, parent, offset in cm: a Mixamo-named skeleton standing in T-pose, facing +z
    ("Hips", None, (0, 100, 0)), ("Spine", "Hips", (0, 10, 0)), ("Spine1", "Spine", (0, 10, 0)),
    ("Spine2", "Spine1", (0, 10, 0)), ("Neck", "Spine2", (0, 15, 0)), ("Head", "Neck", (0, 10, 0)),
    ("LeftShoulder", "Spine2", (5, 10, 0)), ("LeftArm", "LeftShoulder", (10, 0, 0)),
    ("LeftForeArm", "LeftArm", (25, 0, 0)), ("LeftHand", "LeftForeArm", (25, 0, 0)),
    ("LeftHandThumb1", "LeftHand", (3, 0, 3)), ("LeftHandMiddle1", "LeftHand", (8, 0, 0)),
    ("RightShoulder", "Spine2", (-5, 10, 0)), ("RightArm", "RightShoulder", (-10, 0, 0)),
    ("RightForeArm", "RightArm", (-25, 0, 0)), ("RightHand", "RightForeArm", (-25, 0, 0)),
    ("LeftUpLeg", "Hips", (10, -5, 0)), ("LeftLeg", "LeftUpLeg", (0, -45, 0)), ("LeftFoot", "LeftLeg", (0, -45, 0)),
    ("LeftToeBase", "LeftFoot", (0, 0, 12)), ("RightUpLeg", "Hips", (-10, -5, 0)),
    ("RightLeg", "RightUpLeg", (0, -45, 0)), ("RightFoot", "RightLeg", (0, -45, 0)),
    ("RightToeBase", "RightFoot", (0, 0, 12)),
]  # fmt: skip


def _bvh(joints, frames: int = 2) -> str:
    """A BVH of ``joints`` (name, parent, offset), every channel zero: the rest pose in every frame;
    each leaf's End Site 5 cm on along its bone."""
    kids = {name: [j for j in joints if j[1] == name] for name, _, _ in joints}
    lines = ["HIERARCHY"]

    def write(joint, depth):
        name, parent, offset = joint
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parent is None else 'JOINT'} {name}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {' '.join(str(v) for v in offset)}")
        channels = "6 Xposition Yposition Zposition" if parent is None else "3"
        lines.append(f"{pad}  CHANNELS {channels} Zrotation Xrotation Yrotation")
        for child in kids[name]:
            write(child, depth + 1)
        if not kids[name]:
            end = 5 * np.asarray(offset) / np.linalg.norm(offset)  # on along the joint's own bone
            at = " ".join(f"{v:g}" for v in end)
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET {at}", pad + "  }"])
        lines.append(pad + "}")

    write(joints[0], 0)
    values = " ".join(["0"] * (6 + 3 * (len(joints) - 1)))
    lines += ["MOTION", f"Frames: {frames}", "Frame Time: 0.0333333", *[values] * frames]
    return "\n".join(lines) + "\n"


def test_a_bvh_in_t_pose_drives_the_avatar_without_turning_a_bone(tmp_path):
    path = tmp_path / "mixamo.bvh"
    path.write_text(_bvh(MIXAMO))
    motion = read_motion(path)
    rig = VmcRig(motion.joint_set)  # no mapping file: derived
    bones = {b["bone"]: (b["joint"], b["aim"]) for b in rig.mapping["bones"]}
    assert bones["LeftShoulder"] == ("LeftShoulder", "LeftArm")  # a BVH's LeftShoulder is the collarbone
    assert bones["LeftUpperArm"] == ("LeftArm", "LeftForeArm") and bones["LeftHand"] == ("LeftHand", "LeftHandMiddle1")
    assert bones["LeftLowerLeg"] == ("LeftLeg", "LeftFoot") and bones["LeftFoot"] == ("LeftFoot", "LeftToeBase")
    assert bones["UpperChest"] == ("Spine2", "Neck") and bones["Neck"] == ("Neck", "Head")
    root, facing, sent = rig.solve(motion.positions[0])
    np.testing.assert_allclose(root, motion.positions[0, motion.joint_set.index("Hips")] * TO_UNITY, atol=1e-12)
    assert Rotation.from_quat(facing).magnitude() < 1e-9  # hips across x, facing +z: Unity's own facing
    for name, _offset, q in sent:
        assert Rotation.from_quat(q).magnitude() < 1e-6, name  # every bone already on its rest direction
    assert len(sent) == len(rig.bones) == len(bones)


@pytest.mark.parametrize("name", ["tang2018", "smpl24", "nite", "azure_kinect"])
def test_derived_rotations_turn_the_rest_directions_onto_the_bones(name):
    """As tests/live/test_live.py checks the shipped Kinect mapping, for derived ones: the local
    rotations composed from the root turn each bone's T-pose direction onto its direction in the
    frame, for random poses."""
    joint_set = load_joint_set(name)
    rig = VmcRig(joint_set)
    rng = np.random.default_rng(1)
    for _ in range(4):
        positions = rng.normal(0, 0.5, (len(joint_set), 3))
        _, facing, sent = rig.solve(positions)
        p = positions * TO_UNITY
        globals_ = {}
        for bone_name, _offset, q in sent:
            bone = next(b for b in rig.bones if b.name == bone_name)
            assert np.linalg.norm(q) == pytest.approx(1.0)
            parent = globals_.get(bone.parent, Rotation.from_quat(facing))
            own = parent * Rotation.from_quat(q)
            globals_[bone_name] = own
            d = p[bone.aim] - p[bone.joint]
            np.testing.assert_allclose(own.apply(bone.rest), d / np.linalg.norm(d), atol=1e-6)
        assert len(sent) == len(rig.bones)


def test_what_has_no_humanoid_says_so_in_one_line(tmp_path):
    with pytest.raises(KinectDataError, match="openpose_mpi is 2-D .* 3-D joints"):
        VmcRig(load_joint_set("openpose_mpi"))
    arms_only = JointSet.custom("arms", ["chest", "l_shoulder", "l_elbow", "r_shoulder", "r_elbow"],
                                [None, "chest", "l_shoulder", "chest", "r_shoulder"])  # fmt: skip
    with pytest.raises(MappingError, match=r"joint set arms: no knee \(a joint named knee, .* on the left\)"):
        humanoid_mapping(arms_only)
    written = tmp_path / "tang.json"  # a derived mapping is a mapping file a user can edit and give back
    written.write_text(json.dumps(humanoid_mapping(load_joint_set("tang2018"))))
    assert VmcRig(load_joint_set("tang2018"), written).mapping == VmcRig(load_joint_set("tang2018")).mapping


def test_a_cmu_skeleton_with_its_anatomical_names_is_mapped():
    # the CMU motion-capture skeleton (its ASF names: a side's letter run into the bone's name)
    tree = [("root", None), ("lowerback", "root"), ("upperback", "lowerback"), ("thorax", "upperback"),
            ("lowerneck", "thorax"), ("upperneck", "lowerneck"), ("head", "upperneck")]  # fmt: skip
    for s in "lr":
        tree += [(f"{s}hipjoint", "root"), (f"{s}femur", f"{s}hipjoint"), (f"{s}tibia", f"{s}femur"),
                 (f"{s}foot", f"{s}tibia"), (f"{s}toes", f"{s}foot"), (f"{s}clavicle", "thorax"),
                 (f"{s}humerus", f"{s}clavicle"), (f"{s}radius", f"{s}humerus"), (f"{s}wrist", f"{s}radius"),
                 (f"{s}hand", f"{s}wrist")]  # fmt: skip
    names, parents = zip(*tree)
    doc = humanoid_mapping(JointSet.custom("cmu_asf", names, parents))
    bones = {b["bone"]: (b["joint"], b["aim"]) for b in doc["bones"]}
    assert (doc["left_hip"], doc["right_hip"]) == ("lfemur", "rfemur")
    assert bones["LeftUpperLeg"] == ("lfemur", "ltibia") and bones["RightFoot"] == ("rfoot", "rtoes")
    assert bones["LeftShoulder"] == ("lclavicle", "lhumerus") and bones["LeftLowerArm"] == ("lradius", "lwrist")
    assert bones["Hips"] == ("root", "lowerback") and bones["UpperChest"] == ("thorax", "lowerneck")
    assert bones["Neck"] == ("lowerneck", "head")
