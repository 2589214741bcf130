"""A rest skeleton for a target spec, and the joint positions it gives back from a target's orientations.

A target such as ``yalta65`` holds three positions and fourteen orientations: a model trained on it
generates where the body is and how its bones turn, not where every joint is. To draw or retarget
that, the bones need lengths and directions in their joints' frames. They are measured from the
recordings a dataset is built from (:func:`bone_offsets`, then :func:`merge_bone_offsets` over the
training split; stored in the dataset manifest as ``skeleton``):

- for each joint j with parent p, the offset ``p_j - p_p`` (metres) seen in a frame that turns with the
  body: p's orientation (``"parent"``: Kinect's and the synthetic dancer's convention, where a
  joint's frame points at its child) or j's own (``"self"``: where a joint's orientation describes
  the bone that ends at it), whichever gives the steadier local vector over the recording
  (smaller median distance from the median vector); the offset is that median vector;
- offsets whose spread exceeds a quarter of the bone's length are left out (no frame explains them).

:func:`rebuild_positions` then runs forward kinematics from the target's root position:
``p_j = p_p + R @ offset_j``, R the chosen frame's rotation at that frame, for every joint it can
reach that the target does not position itself; the target's own positions (a model's outputs,
e.g. the hands of ``yalta65``) are kept as they are.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinectdata.core.jointsets import parents_first
from kinectdata.core.motion import Motion
from kinectdata.targets.specs import TargetSpec

MAX_SPREAD = 0.25
"""An offset is kept when its median deviation is under this share of its length."""


def bone_offsets(motion: Motion, spec: TargetSpec) -> dict[str, dict[str, Any]]:
    """Per joint of the motion's joint set that the spec's orientations can place: ``{"frame":
    "parent"|"self", "offset": [x, y, z] metres in that frame, "spread": metres, "count": frames}``."""
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

    if motion.orientations is None or not spec.orientations or spec.dimensions != 3:
        return {}
    js = motion.joint_set
    out = {}
    for j, name in enumerate(js.names):
        p = js.parents[j]
        if p < 0:
            continue
        best = None
        for kind, k in (("parent", p), ("self", j)):
            if js.names[k] not in spec.orientations:
                continue
            ok = motion.position_mask[:, j] & motion.position_mask[:, p] & motion.orientation_mask[:, k]
            if ok.sum() < 3:
                continue
            bone = motion.positions[ok, j] - motion.positions[ok, p]
            local = Rotation.from_quat(motion.orientations[ok, k]).inv().apply(bone)
            centre = np.median(local, axis=0)
            spread = float(np.median(np.linalg.norm(local - centre, axis=1)))
            if best is None or spread < best["spread"]:
                best = {"frame": kind, "offset": centre.tolist(), "spread": spread, "count": int(ok.sum())}
        if best is not None and best["spread"] <= MAX_SPREAD * np.linalg.norm(best["offset"]):
            out[name] = best
    return out


def merge_bone_offsets(per_recording: list[dict[str, dict[str, Any]]]) -> dict[str, dict[str, Any]]:
    """One skeleton from several recordings' :func:`bone_offsets`: per joint the frame most
    recordings chose, and the count-weighted mean of their offsets in it."""
    merged = {}
    names = sorted({n for rec in per_recording for n in rec})
    for name in names:
        entries = [rec[name] for rec in per_recording if name in rec]
        frames = [e["frame"] for e in entries]
        frame = max(("parent", "self"), key=frames.count)
        chosen = [e for e in entries if e["frame"] == frame]
        weights = np.array([e["count"] for e in chosen], float)
        offset = np.average([e["offset"] for e in chosen], axis=0, weights=weights)
        merged[name] = {
            "frame": frame,
            "offset": [float(v) for v in offset],
            "spread": float(np.average([e["spread"] for e in chosen], weights=weights)),
            "count": int(weights.sum()),
        }
    return merged


def rebuild_positions(
    values: np.ndarray,
    spec: TargetSpec,
    skeleton: dict[str, dict[str, Any]],
    *,
    root_centred: bool = False,
    anchor: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions [T, J, 3] (NaN where not placed) and their mask [T, J] from target vectors
    [T, D] in target units (metres, unit quaternions), by forward kinematics from the spec's root.

    ``root_centred``: the targets were root-centred (:func:`kinectdata.targets.specs.extract_targets`):
    the other listed positions are offsets from the root at the same frame, so the root's position
    is added back to them (the root itself stays relative to its first second).

    ``anchor``: [3] metres, where the root-centred motion stands in the world
    (:func:`kinectdata.targets.specs.root_anchor`): added to every position, so that the motion
    is placed as the recording was; a root the targets do not list is held there. None: positions
    stay relative to the root (or to its first second, when the root is listed)."""
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

    js = spec.joints
    T, J = values.shape[0], len(js)
    positions = np.full((T, J, 3), np.nan)
    for name in spec.positions:
        positions[:, js.index(name)] = values[:, spec.columns(name, "position")]
    if root_centred and spec.root in spec.positions:
        root = positions[:, js.index(spec.root)].copy()
        for name in spec.positions:
            if name != spec.root:
                positions[:, js.index(name)] += root
    if root_centred and anchor is not None and spec.root is not None:
        if spec.root not in spec.positions:
            positions[:, js.index(spec.root)] = 0.0  # the root of root-relative positions, held at the anchor
        positions += np.asarray(anchor, np.float64)
    quats = {name: values[:, spec.columns(name, "orientation")] for name in spec.orientations}
    placed = {js.names[j] for j in range(J) if np.isfinite(positions[:, j]).all()}
    chain = []  # (joint, parent, the joint whose orientation turns its bone, the bone), parents first
    for j in parents_first(js.parents):
        name, p = js.names[j], js.parents[j]
        bone = skeleton.get(name)
        if p < 0 or bone is None or name in placed or js.names[p] not in placed:
            continue  # the target's own positions (the model's output) are kept as they are
        frame = js.names[p] if bone["frame"] == "parent" else name
        if frame not in quats:
            continue
        chain.append((j, p, frame, bone["offset"]))
        placed.add(name)
    if chain:  # every bone turned in one call (a live frame is one row), then added down the chain
        q = np.stack([quats[frame] for _, _, frame, _ in chain], axis=1)  # [T, K, 4]
        bones = np.broadcast_to(np.asarray([b for *_, b in chain], np.float64), (T, len(chain), 3))
        ok = np.isfinite(q).all(axis=-1) & (np.linalg.norm(np.nan_to_num(q), axis=-1) > 0)  # masked: zeros or NaN
        rotated = np.full((T, len(chain), 3), np.nan)
        if ok.any():
            rotated[ok] = Rotation.from_quat(q[ok]).apply(bones[ok])
        for k, (j, p, _, _) in enumerate(chain):
            positions[:, j] = positions[:, p] + rotated[:, k]
    return positions, np.isfinite(positions).all(axis=-1)
