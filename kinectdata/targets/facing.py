"""Where a root-centred body faces, and the body turned to face one way (numpy).

A run that draws its turning (:mod:`kinectdata.targets.turning`) learns its poses facing one way
(``train --facing``: :func:`kinectdata.training.augment.facing_windows` turns every training pose
about the vertical so that its left-right axis lies along +x). A free run of such a network must
start from a pose facing the same way: started from a real first pose as it stood in the room, a
network that predicts each pose's change from the last keeps the arms where they were and turns
the trunk to the way it learnt, and the body comes out twisted, its elbows across its chest
(docs/notebook/2026-12-real-dance-variety.md, "The first pose's heading"). :func:`faced` turns a
pose to face one way and says by how much, so that the run can be turned back to the room after.

The heading is the angle, in the horizontal plane (x towards z, y up), of the sum of the trunk pairs'
left-minus-right vectors: the hips' and shoulders' (the arms wander), or every mirrored pair when
the joint set names neither.
"""

from __future__ import annotations

import re

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.targets.specs import TargetSpec

LEFT = re.compile(r"(?i)left|^L(?=[A-Z])")
"""A joint named for the body's left side (``left_hip``, ``HipLeft``, ``LShoulder``)."""
TRUNK = re.compile(r"(?i)hip|shoulder")
"""The pairs whose left-right vector gives the facing: the hips' and shoulders' (the arms wander)."""


def turned_joints(spec: TargetSpec) -> list[str]:
    """The joints a turn moves: every positioned joint but the root (whose values are its travel)."""
    return [j for j in spec.positions if j != spec.root]


def trunk_pairs(spec: TargetSpec) -> tuple[list[int], list[int]]:
    """The (left, right) joints whose left-minus-right vectors sum to the heading, as indices into
    :func:`turned_joints`.

    Raises:
        ConfigError: the targets are not 3-D positions, or name no left and right joint.
    """
    if spec.dimensions != 3 or spec.root not in spec.positions:
        raise ConfigError("facing: the targets must be 3-D joint positions centred on their root (--root-centre)")
    joints = turned_joints(spec)
    js = spec.joints
    image = js.mirror_image()
    pairs = []
    for j in joints:
        other = js.names[image[js.index(j)]]
        if other != j and other in joints and LEFT.search(j):
            pairs.append((joints.index(j), joints.index(other), bool(TRUNK.search(j))))
    trunk = [p for p in pairs if p[2]] or pairs
    if not trunk:
        raise ConfigError(f"facing: the target's joints name no left and right side ({', '.join(joints)})")
    return [a for a, _, _ in trunk], [b for _, b, _ in trunk]


def xz_columns(spec: TargetSpec) -> np.ndarray:
    """[J, 2] the x and z columns of each of :func:`turned_joints`."""
    starts = [spec.columns(j, "position").start for j in turned_joints(spec)]
    return np.array([[s, s + 2] for s in starts], np.int64).reshape(-1, 2)


def heading(values: np.ndarray, spec: TargetSpec) -> np.ndarray:
    """The body's heading, rad, of denormalised root-centred targets ``values`` [..., D] (metres):
    [...]; NaN where a trunk joint is not finite."""
    left, right = trunk_pairs(spec)
    xz = np.asarray(values, np.float64)[..., xz_columns(spec)]  # [..., J, 2]
    across = (xz[..., left, :] - xz[..., right, :]).sum(axis=-2)
    return np.arctan2(across[..., 1], across[..., 0])


def turn_about_root(values: np.ndarray, spec: TargetSpec, angle: np.ndarray | float) -> np.ndarray:
    """Denormalised root-centred targets [..., D] with every joint but the root turned about the
    vertical through the root by ``angle`` (rad, broadcast on ``...``; positive from x towards z); a
    new array, the root's values (its travel) and heights unchanged."""
    out = np.array(values, np.float64, copy=True)
    cols = xz_columns(spec)
    x, z = out[..., cols[:, 0]], out[..., cols[:, 1]]
    a = np.asarray(angle, np.float64)[..., None]
    cos, sin = np.cos(a), np.sin(a)
    out[..., cols[:, 0]], out[..., cols[:, 1]] = cos * x - sin * z, sin * x + cos * z
    return out


def faced(values: np.ndarray, spec: TargetSpec) -> tuple[np.ndarray, np.ndarray]:
    """Denormalised root-centred targets [..., D] turned to face one way (their left-right axis
    along +x, as the training poses of a ``--facing`` run), and the heading [...] (rad) each was
    turned from: :func:`turn_about_root` by ``heading`` gives them back. A pose whose heading is
    unknown is left as it is (heading 0)."""
    h = np.nan_to_num(heading(values, spec))
    return turn_about_root(values, spec, -h), h
