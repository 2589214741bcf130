"""Pose targets: the vector a music-to-dance model regresses, one per motion frame.

A target spec (``schemas/targets/*.json``, validated against ``schemas/target.schema.json``)
lists the joints whose positions and the joints whose orientations make the vector. Layout of a
vector of ``D = 3 * len(positions) + 4 * len(orientations)`` values:

- ``[0, 3P)``: positions, ``x, y, z`` per joint (metres, camera space), in the listed order;
- ``[3P, D)``: orientations, unit quaternions ``qx, qy, qz, qw`` per joint, in the listed order.

Shipped specs: ``yalta65`` (Yalta et al. 2016, 3 positions + 14 quaternions), ``kinect_v2_full``,
``nite_full`` and ``azure_kinect_full``. A user adds another by writing a spec file, with no code.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from .errors import KinectDataError, SchemaError
from .jointsets import JointSet, load_joint_set, shipped_joint_sets
from .motion import Motion
from .quaternions import make_continuous
from .resources import load_json, shipped_names, shipped_path, validate

POSITION_AXES = ("x", "y", "z")
QUATERNION_AXES = ("qx", "qy", "qz", "qw")


@dataclass(frozen=True)
class TargetSpec:
    """A validated target spec (build one with :func:`load_target_spec` or :meth:`from_dict`).

    Attributes:
        name: identifier, e.g. ``"yalta65"``.
        joint_set: name of the joint set a motion must use (``kinect_v2``...).
        positions: joints whose positions are components, in vector order.
        orientations: joints whose orientations are components, after all positions.
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

    @property
    def dim(self) -> int:
        """Number of components D."""
        return 3 * len(self.positions) + 4 * len(self.orientations)

    @property
    def position_slice(self) -> slice:
        """Columns of all positions: ``[0, 3P)``."""
        return slice(0, 3 * len(self.positions))

    @property
    def orientation_slice(self) -> slice:
        """Columns of all quaternions: ``[3P, D)``."""
        return slice(3 * len(self.positions), self.dim)

    @property
    def quaternion_slices(self) -> tuple[slice, ...]:
        """Columns ``qx..qw`` of each orientation joint, in the order of :attr:`orientations`."""
        start = 3 * len(self.positions)
        return tuple(slice(start + 4 * k, start + 4 * k + 4) for k in range(len(self.orientations)))

    def columns(self, joint: str, kind: str = "position") -> slice:
        """Columns of one joint's position (``kind="position"``) or quaternion (``"orientation"``)."""
        if kind == "position":
            k = self.positions.index(joint)
            return slice(3 * k, 3 * k + 3)
        if kind == "orientation":
            return self.quaternion_slices[self.orientations.index(joint)]
        raise ValueError(f"kind must be 'position' or 'orientation', not {kind!r}")

    def component_names(self) -> list[str]:
        """One name per component: ``["SpineBase.x", ..., "SpineBase.qx", ..., "KneeRight.qw"]``."""
        return [f"{j}.{a}" for j in self.positions for a in POSITION_AXES] + [
            f"{j}.{a}" for j in self.orientations for a in QUATERNION_AXES
        ]

    def to_dict(self) -> dict[str, Any]:
        """The spec as a JSON-able dict in the spec-file format (``from_dict`` reads it back)."""
        return {
            "name": self.name,
            "description": self.description,
            "joint_set": self.joint_set,
            "positions": list(self.positions),
            "orientations": list(self.orientations),
            "root": self.root,
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], source: str | Path | None = None) -> TargetSpec:
        """A spec from a parsed spec document, validated like a file (SchemaError names ``source``)."""
        return _from_document(dict(doc), source if source is not None else "<target spec>")


def _from_document(doc: dict[str, Any], path: str | Path) -> TargetSpec:
    validate(doc, "target.schema.json", path)
    js = _joint_set(doc["joint_set"], path)
    positions = _joint_list(doc, "positions", js, path)
    orientations = _joint_list(doc, "orientations", js, path)
    for j in orientations:
        if not js.has_orientation[js.index(j)]:
            with_q = ", ".join(n for n, h in zip(js.names, js.has_orientation) if h)
            raise SchemaError(
                path, f"orientations: {j!r} carries no orientation in {js.name} (joints that do: {with_q})"
            )
    if not positions and not orientations:
        raise SchemaError(path, "positions and orientations are both empty: the target would have no component")
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
    )


def _joint_set(name: str, path: str | Path) -> JointSet:
    if name not in shipped_joint_sets():
        raise SchemaError(
            path, f"joint_set: {name!r} is not a shipped joint set (shipped: {', '.join(shipped_joint_sets())})"
        )
    js = load_joint_set(name)
    if js.dimensions != 3:
        raise SchemaError(path, f"joint_set: {name!r} is {js.dimensions}-D; target specs need 3-D joint positions")
    return js


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
    text = str(name_or_path)
    if text in shipped_target_specs():
        return _shipped(text)
    path = Path(text)
    if path.exists():
        return _from_document(load_json(path), path)
    if path.suffix.lower() == ".json" or "/" in text:
        raise SchemaError(path, "target spec file not found")
    raise SchemaError(
        None,
        f"unknown target spec {text!r}: no such file, and no shipped spec has that name "
        f"(shipped: {', '.join(shipped_target_specs())})",
    )


# -- extraction ---------------------------------------------------------------------------------


def extract_targets(motion: Motion, spec: TargetSpec, *, root_centre: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The target vectors of every frame of a motion.

    Quaternions: each joint's series is made sign-continuous over time
    (:func:`~kinectdata.quaternions.make_continuous`, across masked gaps); its first valid
    quaternion keeps the source's sign. A dataset build then puts every recording's track of a
    joint in one hemisphere (:mod:`kinectdata.dataset.hemispheres`).

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
        ``(values, mask)``: values [T, D] float64 (metres, quaternion components), with 0.0
        wherever the mask is False; mask [T, D] bool, True where the component's joint position
        or orientation is valid.

    Raises:
        KinectDataError: the motion uses another joint set, or the spec needs orientations the
            motion does not have, or root-centring is asked of a spec without a root.
    """
    js = motion.joint_set
    if js.name != spec.joint_set:
        raise KinectDataError(
            f"{_source(motion)}: target spec {spec.name!r} is for joint set {spec.joint_set!r}, "
            f"but the recording's joint set is {js.name!r}; choose a spec for {js.name!r}"
        )
    T = motion.n_frames
    pidx = [js.index(j) for j in spec.positions]
    pos = motion.positions[:, pidx]
    pmask = motion.position_mask[:, pidx]
    if root_centre:
        pos, pmask = _root_centred(motion, spec, pos, pmask)

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

    values = np.concatenate([pos.reshape(T, -1), q.reshape(T, -1)], axis=1)
    mask = np.concatenate([np.repeat(pmask, 3, axis=1), np.repeat(qmask, 4, axis=1)], axis=1)
    values[~mask] = 0.0
    return values, mask


def _source(motion: Motion) -> str:
    """``PATH (format 'csv', CSV dialect 'x')``: the recording, for error messages."""
    meta = motion.metadata
    fmt = meta.get("format", "unknown format")
    dialect = meta.get("schema")
    described = f"format {fmt!r}" + (f", CSV dialect {dialect!r}" if dialect else "")
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
        valid = np.flatnonzero(root_ok)
        n = 1
        if motion.n_frames > 1:
            n = max(1, round(1.0 / float(np.median(np.diff(motion.times)))))
        start = root[valid[:n]].mean(axis=0) if valid.size else np.full(3, np.nan)
        centred[:, k] = root - start
        cmask[:, k] = root_ok
    return centred, cmask
