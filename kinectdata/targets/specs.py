"""Pose targets: the vector a music-to-dance model regresses, one per motion frame.

A target spec (``schemas/targets/*.json``, validated against ``schemas/target.schema.json``)
lists the joints whose positions, orientations and limb lengths make the vector. Layout of a vector
of ``D = C * len(positions) + 4 * len(orientations) + len(limbs)`` values, ``C`` the joint set's
dimensions (3 for sensor skeletons, 2 for image-plane ones such as ``openpose_mpi``):

- ``[0, CP)``: positions, ``x, y(, z)`` per joint, in the listed order (metres, camera space; or
  pixels for 2-D joint sets, or 0..1 with ``position_scale: recording_minmax``);
- then orientations, unit quaternions ``qx, qy, qz, qw`` per joint, in the listed order (3-D only);
- then limb lengths: for each listed joint, the distance from it to its parent joint, in the units
  of the positions (after scaling).

``position_scale`` (default ``none``): ``recording_minmax`` maps each coordinate axis of the
positions into 0..1 by its minimum and maximum over all listed joints and all valid frames of
the recording ("coordinates are min-max normalised per video", Lee et al. 2018); x and y are
scaled separately, so the image's aspect ratio is not kept.

Shipped specs: ``yalta65`` (Yalta et al. 2016, 3 positions + 14 quaternions), ``listen_to_dance``
(Lee et al. 2018: 15 OpenPose MPI joints' x, y + 14 limb lengths = 44), ``kinect_v2_full``,
``nite_full`` and ``azure_kinect_full``. A user adds another by writing a spec file, with no code.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError, KinectDataError, SchemaError
from kinectdata.core.jointsets import (
    JointSet,
    joint_set_from_dict,
    load_joint_set,
    load_joint_set_named_in,
    shipped_joint_sets,
)
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import make_continuous
from kinectdata.core.resources import load_json, resolve_resource, shipped_names, shipped_path, validate

POSITION_AXES = ("x", "y", "z")
POSITION_SCALES = ("none", "recording_minmax")
QUATERNION_AXES = ("qx", "qy", "qz", "qw")


@dataclass(frozen=True)
class TargetSpec:
    """A validated target spec (build one with :func:`load_target_spec` or :meth:`from_dict`).

    Attributes:
        name: identifier, e.g. ``"yalta65"``.
        joint_set: name of the joint set a motion must use (``kinect_v2``...).
        joint_set_document: for a joint set kinectdata does not ship, its joint-set document as
            JSON text (so that the spec carries it into manifests and runs, and stays hashable);
            None for a shipped one. :attr:`joints` gives the JointSet either way.
        positions: joints whose positions are components, in vector order.
        orientations: joints whose orientations are components, after all positions.
        limbs: joints whose distance to their parent joint is a component, after all orientations.
        dimensions: coordinates per position (the joint set's: 3, or 2 for image-plane joints).
        position_scale: ``"none"`` or ``"recording_minmax"`` (see the module docstring).
        root: joint used by root-centring (the joint set's ``root`` role unless the file names
            another), or None when there is none.
        description: free text (why these joints).
    """

    name: str
    joint_set: str
    positions: tuple[str, ...]
    orientations: tuple[str, ...]
    root: str | None = None
    description: str = ""
    limbs: tuple[str, ...] = ()
    dimensions: int = 3
    position_scale: str = "none"
    joint_set_document: str | None = None

    @property
    def joints(self) -> JointSet:
        """The joint set a motion must use: the shipped one of that name, or the spec's own."""
        if self.joint_set_document is None:
            return load_joint_set(self.joint_set)
        return _document_joint_set(self.joint_set_document)

    @property
    def dim(self) -> int:
        """Number of components D."""
        return self.dimensions * len(self.positions) + 4 * len(self.orientations) + len(self.limbs)

    @property
    def position_axes(self) -> tuple[str, ...]:
        """``("x", "y", "z")``, or ``("x", "y")`` for a 2-D joint set."""
        return POSITION_AXES[: self.dimensions]

    @property
    def position_slice(self) -> slice:
        """Columns of all positions: ``[0, CP)``."""
        return slice(0, self.dimensions * len(self.positions))

    @property
    def orientation_slice(self) -> slice:
        """Columns of all quaternions, after the positions."""
        start = self.position_slice.stop
        return slice(start, start + 4 * len(self.orientations))

    @property
    def limb_slice(self) -> slice:
        """Columns of all limb lengths: the last ``len(limbs)``."""
        return slice(self.orientation_slice.stop, self.dim)

    @property
    def quaternion_slices(self) -> tuple[slice, ...]:
        """Columns ``qx..qw`` of each orientation joint, in the order of :attr:`orientations`."""
        start = self.orientation_slice.start
        return tuple(slice(start + 4 * k, start + 4 * k + 4) for k in range(len(self.orientations)))

    def columns(self, joint: str, kind: str = "position") -> slice:
        """Columns of one joint's position (``kind="position"``), quaternion (``"orientation"``)
        or limb length (``"limb"``, a one-column slice)."""
        if kind == "position":
            k, c = self.positions.index(joint), self.dimensions
            return slice(c * k, c * k + c)
        if kind == "orientation":
            return self.quaternion_slices[self.orientations.index(joint)]
        if kind == "limb":
            k = self.limb_slice.start + self.limbs.index(joint)
            return slice(k, k + 1)
        raise ConfigError(f"kind must be 'position', 'orientation' or 'limb', not {kind!r}")

    def position_bones(self, root_centred: bool = False) -> list[tuple[int, int]]:
        """(joint, parent) index pairs into :attr:`positions` of the joint set's bones whose two ends
        are both positioned; with ``root_centred``, without the bones at the root (its position is
        then its travel, not an offset from itself)."""
        js, where = self.joints, {j: i for i, j in enumerate(self.positions)}
        pairs = []
        for j in self.positions:
            parent = js.parents[js.index(j)]
            if parent < 0 or js.names[parent] not in where:
                continue
            if root_centred and self.root in (j, js.names[parent]):
                continue
            pairs.append((where[j], where[js.names[parent]]))
        return pairs

    def limb_pairs(self) -> list[tuple[str, str]]:
        """(joint, parent) of each limb, in the order of :attr:`limbs`."""
        js = self.joints
        return [(j, js.names[js.parents[js.index(j)]]) for j in self.limbs]

    def mirror_columns(self) -> tuple[np.ndarray, np.ndarray]:
        """The target's components in the motion's mirror image (the body reflected across the plane
        x = 0, its left and right swapped: :meth:`JointSet.mirror_image`): ``mirrored = sign *
        components[..., source]``, ``source`` [D] int and ``sign`` [D] (-1 on the x columns).

        Raises:
            ConfigError: the target has orientations (not mirrored here), scales positions per
                recording, or positions (or measures) a joint without its mirror image.
        """
        if self.orientations:
            raise ConfigError(
                f"target {self.name!r}: only positions and limb lengths can be mirrored, not orientations"
            )
        if self.position_scale != "none":
            raise ConfigError(f"target {self.name!r}: positions scaled per recording cannot be mirrored")
        js = self.joints
        image = js.mirror_image()
        source, sign = np.arange(self.dim), np.ones(self.dim)
        for kind, joints in (("position", self.positions), ("limb", self.limbs)):
            for joint in joints:
                other = js.names[image[js.index(joint)]]
                if other not in joints:
                    raise ConfigError(
                        f"target {self.name!r}: its {kind}s hold {joint!r} but not its mirror image {other!r}"
                    )
                source[self.columns(joint, kind)] = np.arange(self.dim)[self.columns(other, kind)]
                if kind == "position":
                    sign[self.columns(joint, kind).start] = -1.0
        return source, sign

    def component_names(self) -> list[str]:
        """One name per component: ``["SpineBase.x", ..., "SpineBase.qx", ..., "RElbow-RShoulder.length"]``."""
        return (
            [f"{j}.{a}" for j in self.positions for a in self.position_axes]
            + [f"{j}.{a}" for j in self.orientations for a in QUATERNION_AXES]
            + [f"{j}-{p}.length" for j, p in self.limb_pairs()]
        )

    def to_dict(self) -> dict[str, Any]:
        """The spec as a JSON-able dict in the spec-file format (``from_dict`` reads it back)."""
        d = {
            "name": self.name,
            "description": self.description,
            "joint_set": self.joint_set if self.joint_set_document is None else json.loads(self.joint_set_document),
            "positions": list(self.positions),
            "orientations": list(self.orientations),
            "root": self.root,
        }
        if self.limbs or self.position_scale != "none":  # the 3-D specs' dicts stay as they were
            d["limbs"], d["position_scale"] = list(self.limbs), self.position_scale
        return d

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], source: str | Path | None = None) -> TargetSpec:
        """A spec from a parsed spec document, validated like a file (SchemaError names ``source``)."""
        return _from_document(dict(doc), source if source is not None else "<target spec>")


def _from_document(doc: dict[str, Any], path: str | Path) -> TargetSpec:
    validate(doc, "target.schema.json", path)
    js, document = _joint_set(doc["joint_set"], path)
    positions = _joint_list(doc, "positions", js, path)
    orientations = _joint_list(doc, "orientations", js, path)
    for j in orientations:
        if not js.has_orientation[js.index(j)]:
            with_q = ", ".join(n for n, h in zip(js.names, js.has_orientation) if h)
            raise SchemaError(
                path, f"orientations: {j!r} carries no orientation in {js.name} (joints that do: {with_q})"
            )
    limbs = _joint_list(doc, "limbs", js, path) if "limbs" in doc else ()
    for j in limbs:
        parent = js.parents[js.index(j)]
        if parent < 0:
            raise SchemaError(path, f"limbs: {j!r} is the root of {js.name}: it has no parent, so no limb")
        for end in (j, js.names[parent]):
            if end not in positions:
                raise SchemaError(path, f"limbs: the limb {j}-{js.names[parent]} needs {end!r} under positions")
    if not positions and not orientations and not limbs:
        raise SchemaError(path, "positions, orientations and limbs are all empty: the target would have no component")
    scale = doc.get("position_scale", "none")
    root = doc["root"] if "root" in doc else js.roles.get("root")
    if root is not None:
        root = _canonical(js, root, "root", path)
    return TargetSpec(
        name=doc["name"],
        joint_set=js.name,
        positions=positions,
        orientations=orientations,
        root=root,
        description=doc.get("description", ""),
        limbs=limbs,
        dimensions=js.dimensions,
        position_scale=scale,
        joint_set_document=document,
    )


def _joint_set(value: str | dict, path: str | Path) -> tuple[JointSet, str | None]:
    """The joint set a spec's ``joint_set`` names, and its document as JSON text unless shipped:
    a shipped name, a joint-set file (a relative path from the spec file's folder) or the document."""
    js = (
        joint_set_from_dict(value, f"{path}: joint_set")
        if isinstance(value, dict)
        else load_joint_set_named_in(value, path)
    )
    if js.name in shipped_joint_sets():
        shipped = load_joint_set(js.name)
        if (shipped.names, shipped.parents) != (js.names, js.parents):
            raise SchemaError(
                path, f"joint_set: {js.name!r} is a shipped joint set's name, with other joints: rename it"
            )
        return shipped, None
    return js, json.dumps(js.to_dict(), sort_keys=True)


@cache
def _document_joint_set(text: str) -> JointSet:
    return joint_set_from_dict(json.loads(text), "the target spec's joint_set")


def _canonical(js: JointSet, joint: str, field: str, path: str | Path) -> str:
    try:
        return js.names[js.index(joint)]
    except KeyError:
        raise SchemaError(path, f"{field}: {joint!r} is not a joint of {js.name} ({', '.join(js.names)})") from None


def _joint_list(doc: dict[str, Any], field: str, js: JointSet, path: str | Path) -> tuple[str, ...]:
    names = tuple(_canonical(js, j, field, path) for j in doc[field])
    seen: set[str] = set()
    for j in names:
        if j in seen:
            raise SchemaError(path, f"{field}: joint {j!r} is listed twice")
        seen.add(j)
    return names


GENERIC_TARGETS = {
    "positions": "every joint's position, of whatever joint set the recordings use",
    "full": "every joint's position and the orientation of every joint that carries one",
}
"""Targets asked for by kind rather than by a spec file: the spec is made for the recordings' joint
set when a build reads them (:func:`generic_target`), so a new joint set needs no spec file."""


@dataclass(frozen=True)
class GenericTarget:
    """A target of one of the :data:`GENERIC_TARGETS` kinds, its joint set not known yet."""

    kind: str

    def __post_init__(self) -> None:
        if self.kind not in GENERIC_TARGETS:
            raise ConfigError(f"a generic target is one of {', '.join(GENERIC_TARGETS)}, not {self.kind!r}")

    @property
    def name(self) -> str:
        return self.kind

    def to_dict(self) -> dict[str, Any]:
        return {"generic": self.kind}

    def resolve(self, joint_set: JointSet) -> TargetSpec:
        """The spec of this kind for ``joint_set``."""
        return generic_target(self.kind, joint_set)


def generic_target(kind: str, joint_set: JointSet) -> TargetSpec:
    """The target of a :data:`GENERIC_TARGETS` kind for ``joint_set``, named ``<joint set>_<kind>``:
    ``positions``, all its joints' positions in joint-set order; ``full``, those and then the
    orientations of every joint that can carry one (3-D sets; a 2-D set has positions only)."""
    GenericTarget(kind)  # checks the kind
    orientations = [n for n, has in zip(joint_set.names, joint_set.has_orientation) if has]
    doc = {
        "name": f"{joint_set.name}_{kind}",
        "description": f"{GENERIC_TARGETS[kind]} ({joint_set.name})",
        "joint_set": joint_set.to_dict(),
        "positions": list(joint_set.names),
        "orientations": orientations if kind == "full" and joint_set.dimensions == 3 else [],
    }
    return _from_document(doc, f"the generic {kind!r} target for joint set {joint_set.name!r}")


@cache
def _shipped(name: str) -> TargetSpec:
    path = shipped_path("targets", name)
    return _from_document(load_json(path), path)


def shipped_target_specs() -> list[str]:
    """Names of the target specs shipped with kinectdata."""
    return shipped_names("targets")


def load_target_spec(name_or_path: str | Path | TargetSpec) -> TargetSpec:
    """A shipped target spec by name (``yalta65``...) or a spec file by path; SchemaError if invalid."""
    if isinstance(name_or_path, TargetSpec):
        return name_or_path
    name, path = resolve_resource("targets", name_or_path, "target spec")
    return _shipped(name) if name else _from_document(load_json(path), path)


# -- extraction ---------------------------------------------------------------------------------


def extract_targets(motion: Motion, spec: TargetSpec, *, root_centre: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The target vectors of every frame of a motion.

    Quaternions: each joint's series is made sign-continuous over time
    (:func:`~kinectdata.core.quaternions.make_continuous`, across masked gaps); its first valid
    quaternion keeps the source's sign. A dataset build then puts every recording's track of a
    joint in one hemisphere (:mod:`kinectdata.targets.hemispheres`).

    Limb lengths: the distance between each listed joint and its parent at the same frame, in the
    units of the positions after ``position_scale`` (each axis divided by its scale); computed
    before root-centring (which moves the root into another frame of reference than its
    children); invalid where either joint is.

    Root-centring (``root_centre=True``): each listed position becomes its offset from the spec's
    root joint at the same frame; the root's own position (when listed) becomes its offset from
    its mean over the recording's first second (the first ``round(fps)`` frames where the root is
    valid, ``fps = 1 / median(diff(times))``), so the dancer's travel is kept but not where the
    sensor stood (as the authors' later motion_dance code did). Where the root is invalid, every
    centred position is invalid.

    Args:
        motion: a Motion whose joint set is ``spec.joint_set``.
        spec: the target spec.
        root_centre: centre positions on the root joint as above.

    Returns:
        ``(values, mask)``: values [T, D] float64 (position units, quaternion components, limb
        lengths), with 0.0 wherever the mask is False; mask [T, D] bool, True where the component's joint position
        or orientation is valid.

    Raises:
        KinectDataError: the motion uses another joint set, or the spec needs orientations the
            motion does not have, or root-centring is asked of a spec without a root.
    """
    js = motion.joint_set
    if js.name != spec.joint_set or js.names != spec.joints.names or js.parents != spec.joints.parents:
        raise KinectDataError(
            f"{_source(motion)}: target spec {spec.name!r} is for joint set {spec.joint_set!r}, "
            f"but the recording's joint set is {js.name!r}; choose a spec for {js.name!r}, or a generic target "
            "(--target positions: every joint's position; full: and every orientation)"
        )
    T = motion.n_frames
    pidx = [js.index(j) for j in spec.positions]
    raw, raw_mask = motion.positions[:, pidx], motion.position_mask[:, pidx]
    pos, pmask = _root_centred(motion, spec, raw, raw_mask) if root_centre else (raw, raw_mask)
    span = np.ones(spec.dimensions)
    if spec.position_scale == "recording_minmax":
        pos, span = _minmax_scaled(pos, pmask)

    q = np.zeros((T, 0, 4))
    qmask = np.zeros((T, 0), bool)
    if spec.orientations:
        if motion.orientations is None:
            raise KinectDataError(
                f"{_source(motion)}: target spec {spec.name!r} needs the orientations of "
                f"{len(spec.orientations)} joints, but the recording has positions only; use a positions-only "
                'target spec (e.g. kinect_v2_positions, or a spec file with "orientations": [])'
            )
        oidx = [js.index(j) for j in spec.orientations]
        qmask = motion.orientation_mask[:, oidx]
        q = make_continuous(motion.orientations[:, oidx], qmask)

    lengths, lmask = _limb_lengths(spec, raw / span, raw_mask)
    values = np.concatenate([pos.reshape(T, -1), q.reshape(T, -1), lengths], axis=1)
    mask = np.concatenate([np.repeat(pmask, spec.dimensions, axis=1), np.repeat(qmask, 4, axis=1), lmask], axis=1)
    values[~mask] = 0.0
    return values, mask


def _minmax_scaled(pos: np.ndarray, pmask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions [T, P, C] with each axis mapped into 0..1 by its min and max over the valid ones
    (an axis with no spread maps to 0), and the [C] spans divided by."""
    valid = pos[pmask]  # [N, C]
    if not valid.size:
        return pos, np.ones(pos.shape[-1])
    lo, hi = valid.min(axis=0), valid.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    return (pos - lo) / span, span


def _limb_lengths(spec: TargetSpec, pos: np.ndarray, pmask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """([T, L] lengths, [T, L] mask) of the spec's limbs from positions [T, P, C] of its joints."""
    T = pos.shape[0]
    if not spec.limbs:
        return np.zeros((T, 0)), np.zeros((T, 0), bool)
    k = {j: i for i, j in enumerate(spec.positions)}
    child = np.array([k[j] for j, _ in spec.limb_pairs()])
    parent = np.array([k[p] for _, p in spec.limb_pairs()])
    lengths = np.linalg.norm(pos[:, child] - pos[:, parent], axis=-1)
    return lengths, pmask[:, child] & pmask[:, parent]


def _source(motion: Motion) -> str:
    """``PATH (format 'csv', CSV dialect 'x')``: the recording, for error messages."""
    meta = motion.metadata
    fmt = meta.get("format", "unknown format")
    dialect = meta.get("schema")
    kind = "CSV dialect" if fmt == "csv" else "schema"
    described = f"format {fmt!r}" + (f", {kind} {dialect!r}" if dialect else "")
    return f"{meta.get('source', 'the recording')} ({described})"


def _root_centred(
    motion: Motion, spec: TargetSpec, pos: np.ndarray, pmask: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Positions [T, P, 3] and their mask [T, P] centred as :func:`extract_targets` documents."""
    if spec.root is None:
        raise KinectDataError(f"target spec {spec.name!r} names no root joint, so it cannot be root-centred")
    r = motion.joint_set.index(spec.root)
    root = motion.positions[:, r]
    root_ok = motion.position_mask[:, r]
    centred = pos - root[:, None]
    cmask = pmask & root_ok[:, None]
    if spec.root in spec.positions:
        k = spec.positions.index(spec.root)
        centred[:, k] = root - root_anchor(motion, spec)
        cmask[:, k] = root_ok
    return centred, cmask


def root_anchor(motion: Motion, spec: TargetSpec) -> np.ndarray:
    """[C] where a root-centred recording stands (metres): its root joint's mean position over its
    first second (the first ``round(fps)`` frames where the root is valid, ``fps = 1 / median(diff(times))``),
    from which root-centred targets measure the root's travel (:func:`extract_targets`); NaN when
    the root is never valid. Adding it to positions rebuilt from the targets puts them back in the world."""
    if spec.root is None:
        raise KinectDataError(f"target spec {spec.name!r} names no root joint, so it cannot be root-centred")
    r = motion.joint_set.index(spec.root)
    valid = np.flatnonzero(motion.position_mask[:, r])
    n = 1
    if motion.n_frames > 1:
        n = max(1, round(1.0 / float(np.median(np.diff(motion.times)))))
    if not valid.size:
        return np.full(spec.dimensions, np.nan)
    return motion.positions[valid[:n], r].mean(axis=0)
