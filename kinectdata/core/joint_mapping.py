"""Joint mappings: how to make the joints of one joint set (SMPL-24, the field's) from another.

A mapping is data (``schemas/jointsets/to_smpl24/<joint set>.json``, following
``schemas/joint-mapping.schema.json``): each target joint is a weighted mean of source joints,
marked ``exact`` (the same anatomical joint) or approximated (interpolated or substituted, with a
note saying how). Shipped: ``kinect_v2`` (also NTU), ``nite`` (Kinect v1), ``azure_kinect``,
``openpose_mpi``, ``htr`` (HTR files with MotionBuilder segment names, as Brekel's tools write
them); a user's file works the same way (HTR files with other segment names need one), and a
joint-set file of the user's own may carry its mapping as ``to_smpl24``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinectdata.core.errors import KinectDataError, SchemaError
from kinectdata.core.jointsets import JointSet, load_joint_set
from kinectdata.core.resources import load_json, schemas_dir, shipped_names, validate

SMPL24 = "smpl24"
MAPPINGS_KIND = "jointsets/to_smpl24"


@dataclass(frozen=True)
class JointMapping:
    """Target joints as weighted means of source joints.

    Attributes:
        source: the source joint set's name.
        target: the target joint set.
        weights: [K, J] float64, row k the weights (summing to 1) of the source joints that make
            target joint k.
        exact: [K] bool, True where the target joint is the same anatomical joint as its source.
        notes: [K] how each approximated joint is made ("" when exact or unexplained).
        path: the file it came from, None when built in code.
    """

    source: str
    target: JointSet
    weights: np.ndarray
    exact: tuple[bool, ...]
    notes: tuple[str, ...]
    path: Path | None = None

    def apply(self, positions: np.ndarray, mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Map [T, J, D] source positions to [T, K, D] target positions.

        Args:
            positions: [T, J, D] source positions (NaN where invalid).
            mask: [T, J] bool, True where valid; None: valid where finite.

        Returns:
            ``(positions [T, K, D], mask [T, K])``: a target joint is valid only where all its
            source joints are; invalid values are NaN.
        """
        p = np.asarray(positions, dtype=np.float64)
        if p.ndim != 3 or p.shape[1] != self.weights.shape[1]:
            raise KinectDataError(
                f"the {self.source} mapping needs [T, {self.weights.shape[1]}, D] positions, got shape {p.shape}"
            )
        valid = np.isfinite(p).all(axis=2)
        if mask is not None:
            valid &= np.asarray(mask, dtype=bool)
        used = self.weights > 0
        target_valid = ~((~valid).astype(np.int64) @ used.T.astype(np.int64)).astype(bool)
        mapped = np.einsum("kj,tjd->tkd", self.weights, np.where(valid[..., None], p, 0.0))
        mapped[~target_valid] = np.nan
        return mapped, target_valid

    def describe(self) -> dict:
        """JSON-ready record: source, target, exact and approximated joints with their notes."""
        names = self.target.names
        return {
            "source": self.source,
            "target": self.target.name,
            "file": None if self.path is None else str(self.path),
            "exact": [n for n, e in zip(names, self.exact) if e],
            "approximated": {n: note for n, e, note in zip(names, self.exact, self.notes) if not e},
        }


def identity_mapping(joint_set: JointSet) -> JointMapping:
    """The mapping of a joint set onto itself (every joint exact)."""
    n = len(joint_set)
    return JointMapping(joint_set.name, joint_set, np.eye(n), (True,) * n, ("",) * n)


def load_smpl24_mapping(joint_set: JointSet | str | Path, skeleton: JointSet | None = None) -> JointMapping:
    """The mapping to SMPL-24 of a joint set (shipped mapping by its name) or from a mapping file.

    Args:
        joint_set: a :class:`JointSet` or its name (its shipped mapping is used; ``smpl24`` maps
            onto itself), or the path of a mapping JSON file.
        skeleton: the joint set of the positions the mapping will be applied to, when ``joint_set``
            is a name or file: the weights follow its joint order (an HTR file's own). Default: the
            shipped joint set the mapping names, else the joints the mapping uses, sorted by name.
    """
    if isinstance(joint_set, JointSet):
        if joint_set.name == SMPL24 and len(joint_set) == 24:
            return identity_mapping(joint_set)
        if joint_set.to_smpl24 is not None:  # the set's own file says how
            doc = {"joint_set": joint_set.name, "target": SMPL24, "joints": dict(joint_set.to_smpl24)}
            return _from_document(doc, Path(f"joint set {joint_set.name}, to_smpl24"), joint_set)
        path = _shipped(joint_set.name)
        return _from_document(load_json(path), path, joint_set)
    text = str(joint_set)
    if text == SMPL24:
        return identity_mapping(load_joint_set(SMPL24))
    path = Path(text) if (text.endswith(".json") or "/" in text) else _shipped(text)
    doc = load_json(path)
    validate(doc, "joint-mapping.schema.json", path)
    if skeleton is not None:
        source = skeleton
    elif doc["joint_set"] in shipped_names("jointsets"):
        source = load_joint_set(doc["joint_set"])
    else:  # a joint set that each file brings (HTR): the joints the mapping names, in a fixed order
        used = sorted({j for entry in doc["joints"].values() for j in entry["from"]})
        source = JointSet.custom(doc["joint_set"], used)
    return _from_document(doc, path, source)


def shipped_smpl24_mappings() -> list[str]:
    """Names of the joint sets with a shipped SMPL-24 mapping."""
    return sorted(p.stem for p in (schemas_dir() / MAPPINGS_KIND).glob("*.json"))


def _shipped(name: str) -> Path:
    path = schemas_dir() / MAPPINGS_KIND / f"{name}.json"
    if not path.is_file():
        raise SchemaError(
            None,
            f"joint set {name!r} has no SMPL-24 mapping (shipped: {', '.join(shipped_smpl24_mappings())}); "
            "write one (docs/metrics.md#joint-mappings) and pass it as --mapping FILE",
        )
    return path


def _from_document(doc: dict, path: Path, source: JointSet) -> JointMapping:
    validate(doc, "joint-mapping.schema.json", path)
    if doc["joint_set"] != source.name:
        raise SchemaError(path, f"the mapping is for joint set {doc['joint_set']!r}, the motion has {source.name!r}")
    target = load_joint_set(doc["target"])
    missing = [n for n in target.names if n not in doc["joints"]]
    if missing:
        raise SchemaError(path, f"no entry for target joint(s) {', '.join(missing)}")
    unknown = [n for n in doc["joints"] if n not in target.names]
    if unknown:
        raise SchemaError(path, f"{', '.join(unknown)}: not joints of {target.name}")
    absent = sorted({j for entry in doc["joints"].values() for j in entry["from"] if not _has(source, j)})
    if absent:
        shown = ", ".join(source.names[:12]) + (", ..." if len(source) > 12 else "")
        raise SchemaError(
            path,
            f"the mapping uses joint(s) {', '.join(absent)}, which the {source.name} skeleton does not have "
            f"(it has {shown}); write a mapping for its joints (docs/metrics.md#joint-mappings) and pass it as "
            "--mapping FILE",
        )
    weights = np.zeros((len(target), len(source)))
    for k, name in enumerate(target.names):
        for joint, weight in doc["joints"][name]["from"].items():
            weights[k, source.index(joint)] = weight
    weights /= weights.sum(axis=1, keepdims=True)
    entries = [doc["joints"][n] for n in target.names]
    return JointMapping(
        source=source.name,
        target=target,
        weights=weights,
        exact=tuple(bool(e["exact"]) for e in entries),
        notes=tuple(e.get("note", "") for e in entries),
        path=path,
    )


def _has(joint_set: JointSet, name: str) -> bool:
    try:
        joint_set.index(name)
    except KeyError:
        return False
    return True
