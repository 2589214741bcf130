"""Writing a 3-D Motion as BVH, for Blender, MotionBuilder, Unity and the field's tools (the reader: :mod:`.bvh`).

The hierarchy is the joint set's (one root). Each joint is a ``JOINT`` with three rotation channels
``Zrotation Xrotation Yrotation`` (the root also ``Xposition Yposition Zposition`` first); a leaf
joint gets a zero-length ``End Site``, except a leaf without orientation whose name ends in
``_End`` (an End Site read from a BVH file), which is written as that End Site again. Values are
written in ``unit`` (centimetres by default) and degrees; the frame time is the recording's
interval (:func:`~kinectdata.core.motion.frame_clock`): BVH frames are evenly spaced, so write an
aligned recording (30 fps) or a generated one.

The rotations, as :mod:`.bvh` reads them back (``p_child = p_joint + G_joint · offset_child``, G
global):

- from the recording's orientations where it has them: G is a joint's orientation (a joint without
  one turns with its parent), and a child's OFFSET is the median over frames of ``G_parent^-1
  (p_child - p_parent)``, the bone in its parent's frame. Positions the rotations carry come back
  exactly; others come back where the chain puts them: a sensor's noisy joints (its bones change
  length: about 1 cm median on the bundled Kinect recordings), or a generated target's own hand
  positions, which the network gives apart from the wrist's rotation;
- otherwise solved from the positions on a rest skeleton: each OFFSET is the bone's direction in
  the first frame where both joints are valid with its median length, and G is chosen, parents
  first, to turn the rest bones of a joint's children onto their directions in each frame: the
  least-squares rotation (Kabsch) for a joint with several children, the smallest rotation from
  the parent's frame for a joint with one, the parent's own for a leaf.

A masked position is held from the nearest valid frame before it (after it, at the start); a
masked orientation turns with its parent; a joint with no valid position in any frame (a generated
target that does not reach it) is left out, with the joints below it. The local rotations
``G_parent^-1 G_joint`` become intrinsic ZXY Euler angles (scipy's ``as_euler("ZXY")``).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from kinectdata.core.atomic import atomic_output
from kinectdata.core.body_quality import bone_lengths
from kinectdata.core.errors import KinectDataError
from kinectdata.core.motion import Motion, frame_clock, held_from_nearest
from kinectdata.formats.common import UNITS_TO_M
from kinectdata.formats.writers import register_writer

ROTATION_ORDER = "ZXY"


BONE_TOLERANCE_M = 5e-4
"""A bone whose length moves more than this over the frames cannot be kept by a BVH's one OFFSET."""
TIME_TOLERANCE_S = 1e-4
"""Frame times further than this from an even clock cannot be kept by a BVH's one frame time."""


def bvh_loses(motion: Motion) -> list[str]:
    """What of ``motion`` a BVH file cannot carry, each a short phrase (:mod:`.writers`)."""
    lost = []
    js = motion.joint_set
    if js.roles or js.mirror or js.to_smpl24 is not None:
        lost.append(f"the {js.name} joint set's roles, sides and SMPL-24 mapping (a BVH names its joints only)")
    seen = motion.position_mask.any(axis=0)
    if np.any(motion.confidence[motion.position_mask] != 1.0):
        lost.append("the confidences (BVH has none)")
    if np.any(~motion.position_mask[:, seen]):
        lost.append("when each joint was missing (BVH holds every joint in every frame: held from the nearest one)")
    if not seen.all():
        never = ", ".join(n for n, s in zip(motion.joint_set.names, seen) if not s)
        lost.append(f"the joints never placed ({never}) and those below them")
    spread = _bone_spread(motion)
    if spread > BONE_TOLERANCE_M:
        off = f"{100 * spread:.1f} cm"
        lost.append(f"bone lengths that change from frame to frame (BVH keeps one per bone: up to {off} off)")
    if motion.n_frames >= 2:
        interval, numbers = frame_clock(motion.times)
        off = float(np.max(np.abs(motion.times - motion.times[0] - interval * numbers)))
        if off > TIME_TOLERANCE_S or np.any(np.diff(numbers) != 1):
            lost.append(f"the frames' own times (BVH frames are evenly spaced, {interval:.4f} s apart)")
    return lost


def _bone_spread(motion: Motion) -> float:
    """The largest distance, in metres, of a bone's length in a frame from its median length."""
    lengths = bone_lengths(motion.positions, motion.joint_set.parents, motion.position_mask)
    worst = 0.0
    for j in range(lengths.shape[1]):
        length = lengths[np.isfinite(lengths[:, j]), j]
        if length.size >= 2:
            worst = max(worst, float(np.max(np.abs(length - np.median(length)))))
    return worst


@register_writer("bvh", extensions=(".bvh",), loses=bvh_loses, description="Biovision BVH (rest pose, rotations)")
def write_bvh(motion: Motion, path: str | Path, *, unit: str = "cm", decimals: int = 6) -> Path:
    """Write ``motion`` (3-D, one root, at least two frames) as a BVH file at ``path``, atomically.

    Args:
        motion: the recording or generated motion; positions in metres.
        path: the ``.bvh`` file to write.
        unit: ``cm`` (default), ``m``, ``mm`` or ``in`` for the offsets and root positions.
        decimals: digits after the point of every value.

    Returns:
        The path written.

    Raises:
        KinectDataError: a 2-D joint set, several roots, fewer than two frames, a joint never
            valid, or an unknown unit.
    """
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

    path = Path(path)
    js = motion.joint_set
    if unit not in UNITS_TO_M:
        raise KinectDataError(f"{path}: unit {unit!r} is not one of {', '.join(UNITS_TO_M)}")
    if js.dimensions != 3:
        raise KinectDataError(f"{path}: BVH holds 3-D skeletons; joint set {js.name!r} is {js.dimensions}-D")
    roots = [j for j, p in enumerate(js.parents) if p < 0]
    if len(roots) != 1:
        raise KinectDataError(f"{path}: BVH has one root; joint set {js.name!r} has {len(roots)}")
    if motion.n_frames < 2:
        raise KinectDataError(f"{path}: BVH needs at least two frames to give a frame time")
    if not motion.position_mask[:, roots[0]].any():
        raise KinectDataError(f"{path}: the root joint {js.names[roots[0]]!r} has no valid position in any frame")
    interval, _ = frame_clock(motion.times)
    positions = held_from_nearest(motion.positions, motion.position_mask)
    order = [j for j in _parents_first(js.parents, roots[0]) if motion.position_mask[:, j].any()]
    kept = set()
    for j in order:  # a joint never seen is left out, and so are the joints below it
        if js.parents[j] < 0 or js.parents[j] in kept:
            kept.add(j)
    order = [j for j in order if j in kept]
    children = [[c for c, p in enumerate(js.parents) if p == j and c in kept] for j in range(len(js))]
    if motion.has_orientations and motion.orientation_mask.any():
        rotations = _from_orientations(motion, order, Rotation)
        offsets = _offsets_in_parent_frames(positions, rotations, js.parents, order)
    else:
        offsets = _rest_offsets(positions, motion.position_mask, js.parents, order)
        rotations = _solved_rotations(positions, offsets, js.parents, children, order, Rotation)
    angles = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # scipy's gimbal-lock notice: the angles still compose R
        for j in order:
            p = js.parents[j]
            local = rotations[j] if p < 0 else rotations[p].inv() * rotations[j]
            angles[j] = local.as_euler(ROTATION_ORDER, degrees=True)
    scale = 1.0 / UNITS_TO_M[unit]
    end_sites = {
        j for j in range(len(js)) if not children[j] and not js.has_orientation[j] and js.names[j].endswith("_End")
    }
    lines = ["HIERARCHY"]
    columns: list[np.ndarray] = []
    fmt = f"{{:.{decimals}f}}"

    def write_joint(j: int, depth: int) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if js.parents[j] < 0 else 'JOINT'} {js.names[j]}")
        lines.append(pad + "{")
        offset = np.zeros(3) if js.parents[j] < 0 else offsets[j] * scale
        lines.append(f"{pad}  OFFSET {' '.join(fmt.format(v) for v in offset)}")
        rotation_channels = " ".join(f"{a}rotation" for a in ROTATION_ORDER)
        if js.parents[j] < 0:
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rotation_channels}")
            columns.append(positions[:, j] * scale)
        else:
            lines.append(f"{pad}  CHANNELS 3 {rotation_channels}")
        columns.append(angles[j])
        for c in children[j]:
            if c in end_sites:
                lines.extend([f"{pad}  End Site", f"{pad}  {{"])
                lines.append(f"{pad}    OFFSET {' '.join(fmt.format(v) for v in offsets[c] * scale)}")
                lines.append(f"{pad}  }}")
            else:
                write_joint(c, depth + 1)
        if not children[j]:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0 0", f"{pad}  }}"])
        lines.append(pad + "}")

    write_joint(roots[0], 0)
    frames = np.concatenate(columns, axis=1)
    lines += ["MOTION", f"Frames: {motion.n_frames}", f"Frame Time: {interval:.9f}"]
    body = np.char.mod(f"%.{decimals}f", np.round(frames, decimals) + 0.0)  # + 0.0: no "-0.000000"
    lines += [" ".join(row) for row in body]
    with atomic_output(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return path


def _parents_first(parents: tuple[int, ...], root: int) -> list[int]:
    order, stack = [], [root]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(c for c, p in reversed(list(enumerate(parents))) if p == j)
    return order


def _from_orientations(motion: Motion, order: list[int], Rotation):
    """Global rotations per joint: its orientation where valid, else its parent's (identity at a root)."""
    T = motion.n_frames
    rotations: list = [None] * motion.n_joints
    for j in order:
        p = motion.joint_set.parents[j]
        inherited = Rotation.identity(T) if p < 0 else rotations[p]
        valid = motion.orientation_mask[:, j]
        if not valid.any():
            rotations[j] = inherited
            continue
        q = inherited.as_quat()
        q[valid] = motion.orientations[valid, j]
        rotations[j] = Rotation.from_quat(q)
    return rotations


def _offsets_in_parent_frames(positions: np.ndarray, rotations: list, parents: tuple[int, ...], joints: list[int]):
    """[J, 3] metres: each of ``joints``' bones in its parent's frame, median over frames (zero at a root)."""
    offsets = np.zeros((len(parents), 3))
    for j in joints:
        p = parents[j]
        if p >= 0:
            offsets[j] = np.median(rotations[p].inv().apply(positions[:, j] - positions[:, p]), axis=0)
    return offsets


def _rest_offsets(positions: np.ndarray, mask: np.ndarray, parents: tuple[int, ...], joints: list[int]) -> np.ndarray:
    """[J, 3] metres: each of ``joints``' bones, its direction in the first frame where both its
    joints are valid, with its median length over the frames where they are."""
    offsets = np.zeros((len(parents), 3))
    for j in joints:
        p = parents[j]
        if p < 0:
            continue
        both = np.flatnonzero(mask[:, j] & mask[:, p])
        if not both.size:
            continue
        bones = positions[both, j] - positions[both, p]
        lengths = np.linalg.norm(bones, axis=1)
        first = bones[0] / lengths[0] if lengths[0] > 0 else np.array([0.0, 1.0, 0.0])
        offsets[j] = first * np.median(lengths)
    return offsets


def _solved_rotations(positions, offsets, parents, children, order, Rotation) -> list:
    """Global rotations turning each joint's rest child bones onto the observed ones (see the module)."""
    T = positions.shape[0]
    rotations: list = [None] * len(parents)
    for j in order:
        p = parents[j]
        inherited = Rotation.identity(T) if p < 0 else rotations[p]
        kids = [c for c in children[j] if np.linalg.norm(offsets[c]) > 0]
        if not kids:
            rotations[j] = inherited
        elif len(kids) == 1:
            c = kids[0]
            rotations[j] = (
                _smallest_rotation(inherited.apply(offsets[c]), positions[:, c] - positions[:, j], Rotation) * inherited
            )
        else:
            rest = np.stack([offsets[c] for c in kids])  # [K, 3]
            seen = np.stack([positions[:, c] - positions[:, j] for c in kids], axis=1)  # [T, K, 3]
            rotations[j] = _kabsch(rest, seen, Rotation)
    return rotations


def _smallest_rotation(a: np.ndarray, b: np.ndarray, Rotation):
    """The rotations [T] of least angle taking directions ``a`` [T, 3] onto ``b`` [T, 3]."""
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    norm_b = np.linalg.norm(b, axis=1, keepdims=True)
    b = np.where(norm_b > 0, b / np.where(norm_b > 0, norm_b, 1.0), a)
    axis = np.cross(a, b)
    sin = np.linalg.norm(axis, axis=1)
    cos = np.einsum("ij,ij->i", a, b)
    opposite = (sin < 1e-12) & (cos < 0)
    if opposite.any():  # half a turn about any axis perpendicular to a
        helper = np.where(np.abs(a[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        perpendicular = np.cross(a, helper)
        axis[opposite] = perpendicular[opposite]
        sin[opposite] = np.linalg.norm(perpendicular[opposite], axis=1)
    angle = np.arctan2(sin, cos)
    unit = np.where(sin[:, None] > 0, axis / np.where(sin > 0, sin, 1.0)[:, None], 0.0)
    return Rotation.from_rotvec(unit * angle[:, None])


def _kabsch(rest: np.ndarray, seen: np.ndarray, Rotation):
    """The rotations [T] best turning the rest vectors [K, 3] onto the seen ones [T, K, 3] (least squares)."""
    h = np.einsum("ki,tkj->tij", rest, seen)  # [T, 3, 3]: sum over k of rest_k seen_k^T
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("tij,tjk->tik", vt.transpose(0, 2, 1), u.transpose(0, 2, 1))))
    fix = np.ones((len(d), 3))
    fix[:, 2] = np.where(d == 0, 1.0, d)
    r = np.einsum("tij,tj,tjk->tik", vt.transpose(0, 2, 1), fix, u.transpose(0, 2, 1))
    return Rotation.from_matrix(r)
