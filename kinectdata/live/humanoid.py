"""A Unity humanoid derived from a joint set's tree, roles and names: the VMC mapping a set gets
when none is shipped or given (:class:`kinectdata.live.vmc.VmcRig`).

The limbs are found by their middle joints, whose names the field agrees on more than on the
others (a BVH's ``LeftShoulder`` is a collarbone, a Kinect's ``ShoulderLeft`` the shoulder itself):

- each side's **elbow** (``elbow``, ``forearm``, ``lowerarm``, ``radius``, ``ulna``) and **knee**
  (``knee``, ``shin``, ``calf``, ``tibia``, ``lowerleg``, or ``leg`` without ``up``/``upper``: a
  BVH's ``LeftLeg``), the side from a
  ``left``/``right`` word or an ``L``/``R`` prefix (``LHip``, ``lShldr``, ``HIP_LEFT``);
- the upper arm and upper leg start at their parents; the lower ones end at their children (where a
  joint has several, the one named as the chain goes on: ``wrist``/``hand``, then a middle
  finger, before a thumb; ``ankle``/``foot``/``toe`` before a heel); the hand and foot bones run
  on to the next joint, the toes to the one after; a collarbone (Unity's ``Shoulder``) runs from
  the shoulder's parent to the shoulder;
- the spine is the tree's path from the root (the ``root`` role, else the tree's root) to the
  neck (the ``neck`` role, else a joint named ``neck``, else ``thorax``, else the arms' common
  ancestor):
  its first segment is ``Hips``, the next up to three ``Spine``, ``Chest``, ``UpperChest`` (more
  are merged into the last); ``Neck`` runs from the neck to the head (the ``head`` role, else the
  nearest joint named ``head`` below the neck).

Rest directions are Unity's T-pose (y up, the avatar's left arm along -x, feet forward along z);
bones hang from Unity's hierarchy (legs from ``Hips``, neck and collarbones from the highest spine
bone), not from the joint tree. What cannot be found raises one :class:`MappingError` line.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import JointSet, joint_side, joint_words

SPINE_BONES = ("Spine", "Chest", "UpperChest")
UP, DOWN, FORWARD = [0, 1, 0], [0, -1, 0], [0, 0, 1]
OUT = {"Left": [-1, 0, 0], "Right": [1, 0, 0]}
"""T-pose directions in Unity's axes (x to the avatar's right, y up, z forward)."""

ELBOW = re.compile(r"elbow|forearm|lowerarm|radius|ulna")
KNEE = re.compile(r"knee|shin|calf|tibia|lowerleg|^(?!.*up(per)?leg).*leg")
FINGER = r"thumb|index|middle|ring|pinky|little|finger|tip"
ARM_ON = (re.compile(rf"^(?!.*({FINGER})).*(wrist|hand|palm)"), re.compile(r"middle"))
LEG_ON = (re.compile(r"ankle|foot|toe|ball"),)
"""Which child a limb goes on to where a joint has several, in order of preference (then the first)."""
NECK = (re.compile(r"neck"), re.compile(r"thorax"))
HEAD = re.compile(r"head")


class MappingError(KinectDataError):
    """A joint set in which no humanoid can be found (its one line says what is missing)."""


def side_of(name: str) -> str | None:
    """``Left``, ``Right`` or None (Unity's spelling of :func:`~kinectdata.core.jointsets.joint_side`)."""
    side = joint_side(name)
    return None if side == "centre" else side.capitalize()


def _part(name: str) -> str:
    """The name's words without its side, run together: ``LeftUpLeg`` -> upleg."""
    return "".join(w for w in joint_words(name) if w not in ("left", "right", "l", "r") and not w.isdigit())


def humanoid_mapping(joint_set: JointSet) -> dict:
    """The VMC mapping document (``schemas/vmc-mapping.schema.json``) of a 3-D joint set, derived as
    the module docstring says. Raises MappingError naming what is missing."""
    names, parents = list(joint_set.names), list(joint_set.parents)
    where = f"joint set {joint_set.name}"
    if joint_set.dimensions != 3:
        raise MappingError(f"{where} is {joint_set.dimensions}-D (image points): an avatar's bones need 3-D joints")
    children = [[c for c, p in enumerate(parents) if p == j] for j in range(len(names))]

    def find(pattern: re.Pattern, side: str | None, what: str) -> int:
        found = [j for j, n in enumerate(names) if side_of(n) == side and pattern.search(_part(n))]
        if not found:
            on = "" if side is None else " on the " + side.lower()
            named = pattern.pattern.replace("|", ", ")
            raise MappingError(f"{where}: no {what} (a joint named {named}{on}): no humanoid to drive")
        return min(found, key=lambda j: _depth(parents, j))

    def next_on(joint: int, prefer: Sequence[re.Pattern]) -> int | None:
        options = children[joint]
        for pattern in prefer:
            named = [c for c in options if pattern.search(_part(names[c]))]
            if named:
                return named[0]
        return options[0] if options else None

    root = joint_set.role("root")
    root = root if root is not None else parents.index(-1)
    bones: list[dict] = []
    limbs: dict[str, dict[str, int | None]] = {}
    for side in ("Left", "Right"):
        elbow, knee = find(ELBOW, side, "elbow"), find(KNEE, side, "knee")
        shoulder, hip = parents[elbow], parents[knee]
        if shoulder < 0 or hip < 0:
            raise MappingError(f"{where}: the {side.lower()} {'elbow' if shoulder < 0 else 'knee'} has no parent joint")
        wrist, ankle = next_on(elbow, ARM_ON), next_on(knee, LEG_ON)
        hand = None if wrist is None else next_on(wrist, ARM_ON)
        toe = None if ankle is None else next_on(ankle, LEG_ON)
        limbs[side] = {"collar": parents[shoulder], "shoulder": shoulder, "elbow": elbow, "wrist": wrist,
                       "hand": hand, "hip": hip, "knee": knee, "ankle": ankle, "toe": toe,
                       "toe_end": None if toe is None else next_on(toe, LEG_ON)}  # fmt: skip

    neck = joint_set.role("neck")
    for pattern in NECK if neck is None else ():  # a neck by name before a thorax
        try:
            neck = find(pattern, None, "neck")
            break
        except MappingError:
            continue
    if neck is None:
        neck = _common_ancestor(parents, limbs["Left"]["shoulder"], limbs["Right"]["shoulder"])
    spine = _path(parents, root, neck)
    if spine is None or len(spine) < 2:
        raise MappingError(f"{where}: no spine from the root {names[root]!r} up to the neck {names[neck]!r}")
    bones.append(_bone("Hips", None, spine[0], spine[1], UP, names))
    upper = spine[1:]
    segments = list(zip(upper[:-1], upper[1:]))
    if len(segments) > len(SPINE_BONES):  # merge the top ones into the last
        segments = segments[: len(SPINE_BONES) - 1] + [(segments[len(SPINE_BONES) - 1][0], upper[-1])]
    top = "Hips"
    for bone, (start, end) in zip(SPINE_BONES, segments):
        bones.append(_bone(bone, top, start, end, UP, names))
        top = bone
    head = joint_set.role("head")
    if head is None:  # the nearest joint named head below the neck (a BVH may put a second neck joint between)
        below = [j for j, n in enumerate(names) if HEAD.search(_part(n)) and neck in _ancestors(parents, j)[1:]]
        head = min(below, key=lambda j: _depth(parents, j), default=None)
    if head is not None and head != neck:
        bones.append(_bone("Neck", top, neck, head, UP, names))
    for side, limb in limbs.items():
        out = OUT[side]
        arm_parent = top
        if limb["collar"] >= 0 and limb["collar"] != limb["shoulder"]:
            bones.append(_bone(f"{side}Shoulder", top, limb["collar"], limb["shoulder"], out, names))
            arm_parent = f"{side}Shoulder"
        chain = [(f"{side}UpperArm", arm_parent, "shoulder", "elbow", out),
                 (f"{side}LowerArm", f"{side}UpperArm", "elbow", "wrist", out),
                 (f"{side}Hand", f"{side}LowerArm", "wrist", "hand", out),
                 (f"{side}UpperLeg", "Hips", "hip", "knee", DOWN),
                 (f"{side}LowerLeg", f"{side}UpperLeg", "knee", "ankle", DOWN),
                 (f"{side}Foot", f"{side}LowerLeg", "ankle", "toe", FORWARD),
                 (f"{side}Toes", f"{side}Foot", "toe", "toe_end", FORWARD)]  # fmt: skip
        made = {b["bone"] for b in bones}
        for bone, parent, start, end, rest in chain:
            if parent in made and limb[start] is not None and limb[end] is not None:
                bones.append(_bone(bone, parent, limb[start], limb[end], rest, names))
                made.add(bone)
    return {
        "joint_set": joint_set.name,
        "description": f"derived from {joint_set.name}'s tree, roles and names (kinectdata.live.humanoid)",
        "left_hip": names[limbs["Left"]["hip"]],
        "right_hip": names[limbs["Right"]["hip"]],
        "bones": bones,
    }


def _bone(bone: str, parent: str | None, joint: int, aim: int, rest: list[int], names: Sequence[str]) -> dict:
    return {"bone": bone, "parent": parent, "joint": names[joint], "aim": names[aim], "rest": list(rest)}


def _depth(parents: Sequence[int], joint: int) -> int:
    depth = 0
    while parents[joint] >= 0:
        joint, depth = parents[joint], depth + 1
    return depth


def _ancestors(parents: Sequence[int], joint: int) -> list[int]:
    """``joint`` and its ancestors up to the tree's root, in that order."""
    out = [joint]
    while parents[out[-1]] >= 0:
        out.append(parents[out[-1]])
    return out


def _common_ancestor(parents: Sequence[int], a: int, b: int) -> int:
    up = set(_ancestors(parents, b))
    return next(j for j in _ancestors(parents, a) if j in up)


def _path(parents: Sequence[int], start: int, end: int) -> list[int] | None:
    """The joints from ``start`` down the tree to ``end`` (None when ``end`` is not below it)."""
    up = _ancestors(parents, end)
    return None if start not in up else up[: up.index(start) + 1][::-1]
