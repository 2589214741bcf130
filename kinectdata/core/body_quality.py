"""Two checks the Kinect world needs that the field's tables do not have: bones that keep their
length, and motion without jitter (in ``core``: the metrics report them, and cleaning measures what
it changed by them; :mod:`kinectdata.evaluation.metrics` exports them).

A rigid body's bones do not stretch; a sensor's skeleton (or a generator's) does. Kinect-class
trackers also shake: jitter shows as a large jerk (the third derivative of position).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinectdata.core.errors import KinectDataError


def bone_lengths(positions: np.ndarray, parents: Sequence[int], mask: np.ndarray | None = None) -> np.ndarray:
    """[T, J] the length of the bone from ``parents[j]`` to ``j`` in each frame (the positions'
    unit), NaN for a root and where either end is not valid.

    Args:
        positions: [T, J, D] joint positions.
        parents: [J] parent index of each joint, -1 for a root.
        mask: [T, J] bool, True where valid, or None (valid where finite).
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or len(parents) != p.shape[1]:
        raise KinectDataError(f"positions [T, J, D] with J = {len(parents)} parents needed, got shape {p.shape}")
    valid = np.isfinite(p).all(axis=2)
    if mask is not None:
        valid &= np.asarray(mask, dtype=bool)
    out = np.full(valid.shape, np.nan)
    children = [j for j, parent in enumerate(parents) if parent >= 0]
    ends = [parents[j] for j in children]
    both = valid[:, children] & valid[:, ends]
    out[:, children] = np.where(both, np.linalg.norm(p[:, children] - p[:, ends], axis=2), np.nan)
    return out


def bone_length_variation(positions: np.ndarray, parents: Sequence[int], mask: np.ndarray | None = None) -> np.ndarray:
    """Per-bone coefficient of variation of the bone's length over time.

    Args:
        positions: [T, J, D] joint positions (any unit).
        parents: [J] parent index of each joint, -1 for a root; each joint with a parent is a bone.
        mask: [T, J] bool, True where valid, or None (valid where finite).

    Returns:
        [J] float64: std / mean of the length of the bone from ``parents[j]`` to ``j`` over the
        frames where both ends are valid (ddof 0); NaN for roots and bones with fewer than 2 such
        frames or zero mean length.
    """
    lengths = bone_lengths(positions, parents, mask)
    result = np.full(lengths.shape[1], np.nan)
    for j in range(lengths.shape[1]):
        length = lengths[np.isfinite(lengths[:, j]), j]
        if length.size >= 2 and length.mean() > 0:
            result[j] = length.std() / length.mean()
    return result


def mean_jerk(positions: np.ndarray, fps: float, mask: np.ndarray | None = None) -> float:
    """Mean magnitude of the third derivative of position, over joints and frames.

    Args:
        positions: [T, J, D] joint positions in metres on a uniform grid, T >= 4.
        fps: frames per second.
        mask: [T, J] bool, True where valid; a jerk counts only where its 4 frames are valid.

    Returns:
        Mean jerk in m/s^3 (position units per second cubed); NaN when no jerk counts.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[0] < 4:
        raise KinectDataError(f"jerk needs [T >= 4, J, D] positions, got shape {p.shape}")
    if not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    valid = np.isfinite(p).all(axis=2)
    if mask is not None:
        valid &= np.asarray(mask, dtype=bool)
    jerk = np.linalg.norm(np.diff(np.where(valid[..., None], p, np.nan), n=3, axis=0), axis=2) * fps**3
    counted = np.isfinite(jerk)
    return float(jerk[counted].mean()) if counted.any() else float("nan")
