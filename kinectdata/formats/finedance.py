"""FineDance motion files (``motion/<NNN>.npy``): joint rotations on the SMPL-X body, read as joint
positions and orientations.

What the reader relies on (FineDance, github.com/li-ronghui/FineDance: README.md, which shows how a
motion file is read; data/code/pre_motion.py, which poses the body; vis.py, the kinematic tree):

- A motion file is a [T, 315] array: the root translation (metres), then one rotation per joint of
  the SMPL-H layout (``smplh52``: 22 body joints, 15 per hand), each local to its parent, in the 6-D
  form of PyTorch3D's ``matrix_to_rotation_6d`` (the matrix's first two rows). FineDance's derived
  [T, 319] files (``motion_fea319``: 4 foot contacts first) are read too. 30 frames per second.
- Every dancer is posed on the neutral SMPL-X body with zero shape: its 55 rest joints
  (``smplx_neu_J_1.npy`` in FineDance's code, [55, 3] metres; jaw and eyes are dropped here). The
  root joint lies at its rest position plus the translation; each other joint at its parent's
  position plus the parent's global rotation applied to its rest offset.
- y is up (FineDance's renderer looks at the body with y up).

Those rest joints come from the SMPL-X model, whose licence kinectdata cannot take on: the file is
given (``rest_joints``), never shipped.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import make_continuous
from kinectdata.formats.common import load_numpy
from kinectdata.formats.registry import register_reader

FPS = 30.0
JOINTS = 52
COLUMNS = {3 + 6 * JOINTS: 0, 4 + 3 + 6 * JOINTS: 4}
"""Columns of a motion file -> where its translation starts (after 4 foot contacts in motion_fea319)."""
DET_TOLERANCE = 1e-3
"""A 6-D rotation whose rows are (nearly) parallel or zero gives no rotation: |det - 1| above this."""
SMPLX_KEPT = (*range(22), *range(25, 55))
"""The SMPL-H joints among SMPL-X's 55: all but the jaw (22) and the eyes (23, 24)."""


def rotations_from_6d(d6: np.ndarray) -> np.ndarray:
    """Rotation matrices [..., 3, 3] from the 6-D form [..., 6] (the first two rows, Gram-Schmidt
    orthonormalised, the third their cross product: Zhou et al. 2019, as PyTorch3D computes it).
    NaN where the two rows are zero or parallel."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    with np.errstate(invalid="ignore", divide="ignore"):
        b1 = a1 / np.linalg.norm(a1, axis=-1, keepdims=True)
        b2 = a2 - np.sum(b1 * a2, axis=-1, keepdims=True) * b1
        b2 = b2 / np.linalg.norm(b2, axis=-1, keepdims=True)
    return np.stack([b1, b2, np.cross(b1, b2)], axis=-2)


def load_rest_joints(path: str | Path) -> np.ndarray:
    """The rest joints [52, 3] (metres) of the SMPL-H layout from a [55, 3] SMPL-X file (FineDance's
    ``smplx_neu_J_1.npy``; [1, 55, 3] too) or a [52, 3] one."""
    path = Path(path)
    rest = load_numpy(path, "rest joints")
    if not isinstance(rest, np.ndarray) or rest.dtype.kind not in "fiu":
        raise FormatError(path, "rest joints must be one array of numbers (.npy)")
    rest = rest.astype(np.float64)
    if rest.ndim == 3 and rest.shape[0] == 1:
        rest = rest[0]
    if rest.shape == (55, 3):
        rest = rest[list(SMPLX_KEPT)]
    if rest.shape != (JOINTS, 3) or not np.isfinite(rest).all():
        raise FormatError(path, f"rest joints of shape {list(rest.shape)}; expected [55, 3] (SMPL-X) or [52, 3] metres")
    return rest


@register_reader("finedance", description="FineDance motion .npy (SMPL-H 6-D rotations + root), with --rest-joints")
def read_finedance(path: Path, *, rest_joints: str | Path | None = None) -> Motion:
    """Read a FineDance motion file (see the module docstring).

    Args:
        path: ``motion/<NNN>.npy``, [T, 315] (or [T, 319]).
        rest_joints: the rest joints of the neutral SMPL-X body (FineDance's ``smplx_neu_J_1.npy``).

    Returns:
        A Motion of joint set ``smplh52`` at 30 fps: ``positions`` [T, 52, 3] metres, y up;
        ``orientations`` [T, 52, 4] global (x, y, z, w). A frame with a value that is not finite,
        or a rotation that is not one, is invalid for the joints it moves.
    """
    path = Path(path)
    if rest_joints is None:
        raise FormatError(
            path,
            "FineDance motion is joint rotations: its positions need the SMPL-X rest joints (smplx_neu_J_1.npy "
            "in FineDance's code): give --rest-joints FILE",
        )
    rest = load_rest_joints(rest_joints)
    data = load_numpy(path, "a FineDance motion")
    if not isinstance(data, np.ndarray):
        raise FormatError(path, "an .npz archive; a FineDance motion is one .npy array")
    if data.ndim != 2 or data.shape[1] not in COLUMNS or data.dtype.kind not in "fiu":
        raise FormatError(
            path,
            f"an array of shape {list(data.shape)} ({data.dtype}); a FineDance motion is [T, 315] or [T, 319] numbers",
        )
    if len(data) < 1:
        raise FormatError(path, "no frames")
    start = COLUMNS[data.shape[1]]
    with np.errstate(invalid="ignore", over="ignore"):  # values beyond float64 become inf: invalid frames
        values = data.astype(np.float64)
    translation = values[:, start : start + 3]
    local = rotations_from_6d(values[:, start + 3 :].reshape(len(data), JOINTS, 6))
    rotation_ok = np.abs(np.linalg.det(np.nan_to_num(local)) - 1.0) < DET_TOLERANCE  # [T, 52]
    local[~rotation_ok] = np.nan
    joint_set = load_joint_set("smplh52")
    positions, global_r = _forward_kinematics(rest, joint_set.parents, translation, local)
    valid = np.isfinite(positions).all(axis=2) & np.isfinite(global_r).all(axis=(2, 3))
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

    quats = np.full((len(data), JOINTS, 4), np.nan)
    quats[valid] = Rotation.from_matrix(global_r[valid]).as_quat()
    return Motion(
        times=np.arange(len(data)) / FPS,
        positions=np.where(valid[..., None], positions, np.nan),
        joint_set=joint_set,
        position_mask=valid,
        orientations=make_continuous(quats, valid),
        orientation_mask=valid,
        metadata={
            "format": "finedance",
            "nominal_fps": FPS,
            "time_source": f"frame index at {FPS:g} fps",
            "rest_joints": str(rest_joints),
            "time_origin": None,
        },
    )


def _forward_kinematics(
    rest: np.ndarray, parents: tuple[int, ...], translation: np.ndarray, local: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Global positions [T, 52, 3] and rotation matrices [T, 52, 3, 3] from the rest joints [52, 3],
    each joint's parent index (parents come before children), the root translation [T, 3] and local
    rotations [T, 52, 3, 3]."""
    T = len(translation)
    positions = np.empty((T, JOINTS, 3))
    global_r = np.empty((T, JOINTS, 3, 3))
    positions[:, 0] = rest[0] + translation
    global_r[:, 0] = local[:, 0]
    for j in range(1, JOINTS):
        p = parents[j]
        positions[:, j] = positions[:, p] + global_r[:, p] @ (rest[j] - rest[p])
        global_r[:, j] = global_r[:, p] @ local[:, j]
    return positions, global_r
