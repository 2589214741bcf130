"""Live poses for avatar tools over the VMC protocol (Virtual Motion Capture: VSeeFace, VMC4UE,
the EVMC4U receiver in Unity...).

The protocol speaks of a Unity humanoid: bones by their ``HumanBodyBones`` names, each with a
position and a rotation local to its parent bone, in Unity's axes (left-handed: x to the avatar's
right, y up, z forward). A run's joints become those bones by a mapping, data not code: ``--vmc-map FILE``, else the
file shipped for the joint set (``schemas/vmc/<joint set>.json``, for ``kinect_v2``), else one
derived from the set's tree, roles and names (:mod:`kinectdata.live.humanoid`). Each bone starts at
a joint and points at another (its aim), with its direction in the avatar's T-pose (rest); the two
hip joints give the avatar's facing.

Rotations are solved from positions (:class:`VmcRig`): kinectdata's right-handed axes become
Unity's by mirroring x; the avatar's facing turns about y so that its hips lie along the dancer's;
each bone's global rotation is the smallest rotation taking its rest direction, turned with the
facing, onto the bone's direction in the frame (a bone's twist about itself is not seen by
positions, and stays the facing's); its local rotation is its parent's global inverse times its
own. A bone whose joints are not placed in a frame turns with its parent and is not sent.

Each frame is one bundle (docs/live.md): ``/VMC/Ext/Root/Pos`` ("root", the hips' position, the
facing), ``/VMC/Ext/Bone/Pos`` per bone (name, local position in metres, local rotation x, y, z,
w), ``/VMC/Ext/OK`` (1: loaded) and ``/VMC/Ext/T`` (seconds).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinectdata.core.errors import KinectDataError, SchemaError
from kinectdata.core.jointsets import JointSet
from kinectdata.core.resources import load_json, schemas_dir, validate
from kinectdata.live.humanoid import humanoid_mapping
from kinectdata.live.sinks import LivePose, UdpSink

HUMAN_BODY_BONES = (
    "Hips Spine Chest UpperChest Neck Head Jaw LeftEye RightEye "
    "LeftShoulder LeftUpperArm LeftLowerArm LeftHand RightShoulder RightUpperArm RightLowerArm RightHand "
    "LeftUpperLeg LeftLowerLeg LeftFoot LeftToes RightUpperLeg RightLowerLeg RightFoot RightToes".split()
    + [
        f"{side}{finger}{part}"
        for side in ("Left", "Right")
        for finger in ("Thumb", "Index", "Middle", "Ring", "Little")
        for part in ("Proximal", "Intermediate", "Distal")
    ]  # fmt: skip
)
"""Unity's ``HumanBodyBones`` names, the bones a VMC receiver knows."""
TO_UNITY = np.array([-1.0, 1.0, 1.0])
"""kinectdata's right-handed axes -> Unity's left-handed ones: x mirrored."""


@dataclass(frozen=True)
class VmcBone:
    """One humanoid bone: its Unity name, its parent bone (None: the hips), the joint it starts
    at and the joint it points at (indices in the run's joint set), its T-pose direction."""

    name: str
    parent: str | None
    joint: int
    aim: int
    rest: np.ndarray


class VmcRig:
    """A run's joint set as Unity humanoid bones (module docstring).

    Args:
        joint_set: the run's.
        mapping: a mapping file; None: the one shipped for ``joint_set`` (SchemaError if none).
    """

    def __init__(self, joint_set: JointSet, mapping: str | Path | None = None):
        if joint_set.dimensions != 3:
            raise KinectDataError(
                f"joint set {joint_set.name} is {joint_set.dimensions}-D (image points): an avatar's bones need "
                "3-D joints"
            )
        path = Path(mapping) if mapping is not None else schemas_dir() / "vmc" / f"{joint_set.name}.json"
        if mapping is None and not path.is_file():
            doc, path = humanoid_mapping(joint_set), None  # derived from the set's tree, roles and names
        else:
            if not path.is_file():
                raise SchemaError(path, "no such VMC mapping file")
            doc = load_json(path)
        validate(doc, "vmc-mapping.schema.json", path)
        self.mapping = doc
        if doc["joint_set"] != joint_set.name:
            raise SchemaError(
                path, f"joint_set: the mapping is for {doc['joint_set']!r}, the run's joints are {joint_set.name!r}"
            )

        def index(name: str, where: str) -> int:
            try:
                return joint_set.index(name)
            except (KeyError, ValueError):
                raise SchemaError(path, f"{where}: {name!r} is not a joint of {joint_set.name}") from None

        self.left_hip, self.right_hip = index(doc["left_hip"], "left_hip"), index(doc["right_hip"], "right_hip")
        self.bones: list[VmcBone] = []
        seen: set[str] = set()
        for k, b in enumerate(doc["bones"]):
            where = f"bones[{k}]"
            if b["bone"] not in HUMAN_BODY_BONES:
                raise SchemaError(path, f"{where}: {b['bone']!r} is not a Unity humanoid bone")
            if (b["parent"] is None) != (k == 0) or (b["parent"] is not None and b["parent"] not in seen):
                raise SchemaError(
                    path, f"{where}: the first bone is the root (parent null); a parent comes before its bones"
                )
            rest = np.asarray(b["rest"], np.float64)
            if not np.linalg.norm(rest) > 0:
                raise SchemaError(path, f"{where}: rest is no direction (all zeros)")
            self.bones.append(VmcBone(b["bone"], b["parent"], index(b["joint"], where), index(b["aim"], where),
                                      rest / np.linalg.norm(rest)))  # fmt: skip
            seen.add(b["bone"])

    def solve(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[tuple[str, np.ndarray, np.ndarray]]]:
        """For positions [J, 3] (metres, kinectdata's axes): the root's position and rotation (x, y,
        z, w) and, per bone placed in this frame, (name, local position, local rotation), in Unity's
        axes."""
        from scipy.spatial.transform import Rotation

        p = positions * TO_UNITY
        left = p[self.left_hip] - p[self.right_hip]
        right = -np.array([left[0], 0.0, left[2]])
        if not np.isfinite(right).all() or np.linalg.norm(right) < 1e-9:
            right = np.array([1.0, 0.0, 0.0])  # hips not seen: the avatar keeps facing forward
        right /= np.linalg.norm(right)
        up = np.array([0.0, 1.0, 0.0])
        facing = Rotation.from_matrix(np.column_stack([right, up, np.cross(right, up)]))
        hips = p[self.bones[0].joint]
        globals_: dict[str, Rotation] = {}
        sent = []
        for bone in self.bones:
            parent = globals_.get(bone.parent, facing) if bone.parent is not None else facing
            d = p[bone.aim] - p[bone.joint]
            if not np.isfinite(d).all() or np.linalg.norm(d) < 1e-9:
                globals_[bone.name] = parent  # not placed in this frame: turns with its parent, not sent
                continue
            swing, _ = Rotation.align_vectors(d[None], facing.apply(bone.rest)[None])
            own = swing * facing
            globals_[bone.name] = own
            if bone.parent is None:
                offset = np.zeros(3)
            else:
                start = next(b.joint for b in self.bones if b.name == bone.parent)
                offset = parent.inv().apply(p[bone.joint] - p[start])
            sent.append((bone.name, offset, (parent.inv() * own).as_quat()))
        return hips, facing.as_quat(), sent


class VmcSink(UdpSink):
    """Sends each frame to a VMC receiver at ``host:port`` as one OSC bundle (module docstring)."""

    label = "VMC"

    def __init__(self, address: str, joint_set: JointSet, mapping: str | Path | None = None):
        try:
            from pythonosc.parsing import osc_types
        except ImportError:
            raise KinectDataError("--vmc needs python-osc: pip install 'kinectdata[live]'") from None
        self.types = osc_types
        self.rig = VmcRig(joint_set, mapping)
        super().__init__(address)

    def bundle(self, pose: LivePose) -> bytes:
        t = self.types
        root, facing, bones = self.rig.solve(pose.positions)
        parts = [self._message("/VMC/Ext/Root/Pos", "root", root, facing)]
        parts += [self._message("/VMC/Ext/Bone/Pos", name, offset, q) for name, offset, q in bones]
        parts.append(t.write_string("/VMC/Ext/OK") + t.write_string(",i") + t.write_int(1))
        parts.append(t.write_string("/VMC/Ext/T") + t.write_string(",f") + t.write_float(pose.time_s))
        head = t.write_string("#bundle") + (1).to_bytes(8, "big")
        return head + b"".join(len(m).to_bytes(4, "big") + m for m in parts)

    def _message(self, address: str, name: str, position: np.ndarray, rotation: np.ndarray) -> bytes:
        t = self.types
        values = np.concatenate([position, rotation]).astype(">f4").tobytes()
        return t.write_string(address) + t.write_string(",sfffffff") + t.write_string(name) + values
