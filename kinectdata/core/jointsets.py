"""Joint sets: the names, hierarchy and roles of a skeleton's joints, read from data files.

Shipped joint sets live in ``kinectdata/schemas/jointsets/*.json`` (``kinect_v2``, ``nite``,
``azure_kinect``, ``openpose_mpi``, and ``smpl24``, the field's) and follow
``schemas/jointset.schema.json``. Formats that bring their own hierarchy (HTR, Azure JSON with
other joint lists) build a JointSet with :meth:`JointSet.custom`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

from kinectdata.core.errors import ConfigError, SchemaError
from kinectdata.core.resources import load_json, resolve_resource, shipped_names, shipped_path, validate


@dataclass(frozen=True)
class JointSet:
    """The joints of a skeleton.

    Attributes:
        name: identifier, e.g. ``"kinect_v2"``.
        names: joint names in storage order; index ``j`` of every [T, J, ...] array is ``names[j]``.
        parents: index of each joint's parent, -1 for a root.
        dimensions: 3 for camera-space skeletons (metres), 2 for image-plane ones (pixels).
        has_orientation: [J] bool, False for joints whose orientation the sensor never gives
            (Kinect v2 leaf joints); their orientation mask is always False.
        roles: semantic names (``left_hand``, ``right_hand``, ``root``...) to joint names, so that
            format-independent code (clap detection, root centring) can find them.
        aliases: other spellings of joint names found in files, mapped to the names used here.
        to_smpl24: for a set kinectdata ships no mapping for, how its joints make the 24 SMPL joints
            (a joint mapping's ``joints``; :func:`kinectdata.core.joint_mapping.load_smpl24_mapping`
            uses it), or None.
        mirror: pairs of joints that are each other's mirror image across the body's midline
            (left and right), for sets whose names do not say it (:meth:`mirror_image`).
    """

    name: str
    names: tuple[str, ...]
    parents: tuple[int, ...]
    dimensions: int = 3
    has_orientation: tuple[bool, ...] = ()
    roles: Mapping[str, str] = field(default_factory=dict)
    aliases: Mapping[str, str] = field(default_factory=dict)
    description: str = ""
    to_smpl24: Mapping[str, dict] | None = None
    mirror: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.has_orientation:
            object.__setattr__(self, "has_orientation", (True,) * len(self.names))
        if not (len(self.names) == len(self.parents) == len(self.has_orientation)):
            raise ConfigError("names, parents and has_orientation must have the same length")
        if len(set(self.names)) != len(self.names):
            raise ConfigError(f"joint set {self.name!r} repeats a joint name")

    @classmethod
    def custom(
        cls,
        name: str,
        names: Sequence[str],
        parents: Sequence[str | None] | None = None,
        dimensions: int = 3,
    ) -> JointSet:
        """A joint set built from names and parent names (None for a root; all roots if omitted)."""
        index = {n: i for i, n in enumerate(names)}
        parent_idx = tuple(-1 if p is None else index[p] for p in (parents or [None] * len(names)))
        return cls(name=name, names=tuple(names), parents=parent_idx, dimensions=dimensions)

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of a joint by name or alias; KeyError if unknown."""
        name = self.aliases.get(name, name)
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(name) from None

    def role(self, role: str) -> int | None:
        """Index of the joint playing a role (``left_hand``...), or None if the set has no such role."""
        joint = self.roles.get(role)
        return None if joint is None else self.index(joint)

    @property
    def orientation_mask(self) -> np.ndarray:
        """[J] bool: joints that can carry an orientation."""
        return np.array(self.has_orientation, dtype=bool)

    def bones(self) -> list[tuple[int, int]]:
        """(parent, child) index pairs, one per non-root joint."""
        return [(p, c) for c, p in enumerate(self.parents) if p >= 0]

    def mirror_image(self) -> np.ndarray:
        """[J] index of each joint's mirror image across the body's midline: the pairs of
        :attr:`mirror`, then the joint whose name has the other side's word (``left`` / ``right`` in
        any case: ``left_hip``, ``HipLeft``, ``HIP_LEFT``; or a leading ``L`` / ``R`` before a
        capital: ``LShoulder``), else the joint itself (on the midline: ``Neck``).

        Raises:
            ConfigError: a joint named for one side has no joint of the other side's name (name
                its image in the joint set's ``mirror``).
        """
        pairs = {**self.mirror, **{b: a for a, b in self.mirror.items()}}
        image = []
        for name in self.names:
            other = pairs.get(name) or _other_side(name)
            if other is None:
                image.append(self.names.index(name))
            elif other in self.names:
                image.append(self.names.index(other))
            else:
                raise ConfigError(
                    f"joint set {self.name!r}: joint {name!r} has no mirror image {other!r}; "
                    'name its image in the joint set\'s "mirror" pairs'
                )
        return np.array(image, dtype=np.int64)

    def to_dict(self) -> dict:
        """The joint set as a joint-set document (``schemas/jointset.schema.json``), which
        :func:`joint_set_from_dict` reads back to an equal JointSet."""
        doc: dict = {"name": self.name}
        if self.description:
            doc["description"] = self.description
        doc["dimensions"] = self.dimensions
        doc["joints"] = [
            {"name": n, "parent": None if p < 0 else self.names[p]} for n, p in zip(self.names, self.parents)
        ]
        no_orientation = [n for n, has in zip(self.names, self.has_orientation) if not has]
        if no_orientation:
            doc["no_orientation"] = no_orientation
        if self.roles:
            doc["roles"] = dict(self.roles)
        if self.aliases:
            doc["aliases"] = dict(self.aliases)
        if self.to_smpl24 is not None:
            doc["to_smpl24"] = dict(self.to_smpl24)
        if self.mirror:
            doc["mirror"] = dict(self.mirror)
        return doc


_SIDE_WORDS = {"left": "right", "right": "left", "Left": "Right", "Right": "Left", "LEFT": "RIGHT", "RIGHT": "LEFT"}
_SIDE_WORD = re.compile("|".join(_SIDE_WORDS))
_SIDE_LETTER = re.compile(r"^([LR])(?=[A-Z])")


def joint_words(name: str) -> list[str]:
    """A joint name's words, lower case: ``mixamorig:LeftForeArm`` -> mixamorig, left, fore, arm;
    ``LHip`` -> l, hip; ``HIP_LEFT`` -> hip, left; ``RElbow`` -> r, elbow."""
    return [w.lower() for w in re.findall(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+", name)]


_BODY_PARTS = frozenset(
    "hip hipjoint thigh femur upleg upperleg leg knee shin calf tibia lowerleg ankle foot heel toe toes ball "
    "clavicle collar shoulder shldr humerus arm uparm upperarm elbow forearm lowerarm radius ulna wrist hand "
    "palm thumb finger fingers handtip eye ear".split()
)
"""Words for a limb's parts, which a side's letter may be run into (a CMU skeleton's ``lhumerus``)."""


def joint_side(name: str) -> str:
    """``"left"``, ``"right"`` or ``"centre"`` from a joint name: a left/right word (``HandRight``,
    ``RIGHT_HAND``, ``left_hip``, ``leftknee``), an L/R before the first word (``RElbow``,
    ``lShldr``; not a vertebra's ``L5``), or an l/r run into a body part's word (``lhumerus``,
    ``LHIP``)."""
    words = joint_words(name)
    for side in ("left", "right"):
        if side in words or (len(words) > 1 and words[0] == side[0] and words[1].isalpha()):
            return side
        for word in words[:1]:
            rest = word[len(side) :] if word.startswith(side) else word[1:] if word[:1] == side[0] else ""
            if rest in _BODY_PARTS or (word.startswith(side) and rest.isalpha()):
                return side
    return "centre"


def _other_side(name: str) -> str | None:
    """The name with its side's word swapped (see :meth:`JointSet.mirror_image`), or None when
    it names no side."""
    if _SIDE_WORD.search(name):
        return _SIDE_WORD.sub(lambda m: _SIDE_WORDS[m.group()], name)
    if _SIDE_LETTER.match(name):
        return _SIDE_LETTER.sub(lambda m: "R" if m.group(1) == "L" else "L", name)
    return None


def _from_document(doc: dict, path: Path) -> JointSet:
    validate(doc, "jointset.schema.json", path)
    names = [j["name"] for j in doc["joints"]]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise SchemaError(path, f"joint name {dup!r} appears twice")
    index = {n: i for i, n in enumerate(names)}
    parents = []
    for j in doc["joints"]:
        p = j["parent"]
        if p is not None and p not in index:
            raise SchemaError(path, f"joint {j['name']!r} has unknown parent {p!r}")
        parents.append(-1 if p is None else index[p])
    cyclic = find_cycle(parents)
    if cyclic is not None:
        raise SchemaError(path, f"the hierarchy has a cycle through joint {names[cyclic]!r}")
    for n in doc.get("no_orientation", []):
        if n not in index:
            raise SchemaError(path, f"no_orientation names unknown joint {n!r}")
    roles = doc.get("roles", {})
    for role, n in roles.items():
        if n not in index:
            raise SchemaError(path, f"role {role!r} names unknown joint {n!r}")
    mirror = doc.get("mirror", {})
    for a, b in mirror.items():
        for n in (a, b):
            if n not in index:
                raise SchemaError(path, f"mirror names unknown joint {n!r}")
    images = [*mirror, *mirror.values()]
    if len(set(images)) != len(images):
        raise SchemaError(path, "mirror names a joint in two pairs")
    no_orientation = set(doc.get("no_orientation", []))
    return JointSet(
        name=doc["name"],
        names=tuple(names),
        parents=tuple(parents),
        dimensions=doc.get("dimensions", 3),
        has_orientation=tuple(n not in no_orientation for n in names),
        roles=dict(roles),
        aliases=dict(doc.get("aliases", {})),
        description=doc.get("description", ""),
        to_smpl24=doc.get("to_smpl24"),
        mirror=dict(mirror),
    )


def joint_set_from_dict(doc: Mapping, source: str | Path = "<joint set>") -> JointSet:
    """A joint set from a joint-set document (as a file holds it, or :meth:`JointSet.to_dict`
    gives it), validated like a file; SchemaError names ``source``."""
    return _from_document(dict(doc), Path(source))


def find_cycle(parents: Sequence[int]) -> int | None:
    """Index of a joint on a cycle of a parent list (-1 marks roots), or None for a forest."""
    for start in range(len(parents)):
        seen, j = set(), start
        while j >= 0:
            if j in seen:
                return j
            seen.add(j)
            j = parents[j]
    return None


def parents_first(parents: Sequence[int]) -> list[int]:
    """The joint indices ordered by their depth in the tree (roots first, then their children...),
    so that a walk in this order meets every joint after its parent; joints of one depth keep their
    order. ``parents`` [J] (-1 marks roots) must hold no cycle (:func:`find_cycle`; a JointSet has none)."""
    depth = []
    for j in range(len(parents)):
        d, k = 0, j
        while parents[k] >= 0:
            d, k = d + 1, parents[k]
        depth.append(d)
    return sorted(range(len(parents)), key=lambda j: depth[j])


@cache
def _load_shipped(name: str) -> JointSet:
    path = shipped_path("jointsets", name)
    return _from_document(load_json(path), path)


def load_joint_set(name_or_path: str | Path) -> JointSet:
    """A shipped joint set by name (``kinect_v2``...) or a joint-set JSON file by path."""
    name, path = resolve_resource("jointsets", name_or_path, "joint set")
    return _load_shipped(name) if name else _from_document(load_json(path), path)


def load_joint_set_named_in(value: str, declared_in: str | Path) -> JointSet:
    """The joint set a declarative file's ``joint_set`` names: a shipped name, or a joint-set file,
    a relative path resolved from the folder of ``declared_in`` (the file naming it); SchemaError
    naming ``declared_in`` when it is neither."""
    if value in shipped_joint_sets():
        return load_joint_set(value)
    file = Path(declared_in).parent / Path(value).expanduser()  # an absolute path stays as it is
    if not file.is_file():
        raise SchemaError(
            declared_in,
            f"joint_set: {value!r} is neither a shipped joint set ({', '.join(shipped_joint_sets())}) nor a "
            f"joint-set file (looked for {file})",
        )
    return load_joint_set(file)


def shipped_joint_sets() -> list[str]:
    """Names of the joint sets shipped with kinectdata."""
    return shipped_names("jointsets")


def find_joint_set(joint_names: Sequence[str]) -> JointSet | None:
    """The smallest shipped joint set that contains every given joint name (or alias), if any."""
    wanted = set(joint_names)
    best: JointSet | None = None
    for name in shipped_joint_sets():
        js = load_joint_set(name)
        known = set(js.names) | set(js.aliases)
        if wanted <= known and (best is None or len(js) < len(best)):
            best = js
    return best


def is_shipped(js: JointSet) -> bool:
    """True when ``js`` is a shipped joint set (its name, joints and hierarchy), so that a file can
    name it rather than describe it."""
    if js.name not in shipped_joint_sets():
        return False
    shipped = load_joint_set(js.name)
    return (shipped.names, shipped.parents) == (js.names, js.parents)


def joint_set_text(js: JointSet) -> str:
    """The joint set as one line of JSON (its document, :meth:`JointSet.to_dict`: joints, bones,
    roles, aliases, SMPL-24 mapping), for a file to carry a joint set kinectdata does not ship;
    :func:`joint_set_from_text` reads it back to an equal JointSet."""
    import json

    return json.dumps(js.to_dict(), separators=(",", ":"), ensure_ascii=True)


def joint_set_from_text(text: str, source: str | Path) -> JointSet:
    """A joint set from the JSON text a file carries (:func:`joint_set_text`), validated like a
    joint-set file. SchemaError naming ``source`` for text that is not JSON, not a joint-set
    document, or that takes a shipped joint set's name with other joints."""
    import json

    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise SchemaError(source, f"its joint set is not JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise SchemaError(source, "its joint set is not a joint-set document (a JSON object)")
    js = joint_set_from_dict(doc, source)
    if js.name in shipped_joint_sets() and not is_shipped(js):
        raise SchemaError(source, f"its joint set takes the shipped name {js.name!r} with other joints")
    return load_joint_set(js.name) if js.name in shipped_joint_sets() else js
