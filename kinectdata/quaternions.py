"""Quaternion helpers on [..., 4] arrays in scipy's scalar-last order (x, y, z, w).

Rotation maths itself is left to :mod:`scipy.spatial.transform`; these functions only handle
what scipy does not: component order, zero quaternions meaning "no orientation", and sign
continuity over time (q and -q are the same rotation, but a learning target must not jump
between them).
"""

from __future__ import annotations

import numpy as np

UNIT_TOLERANCE = 0.05
"""A stored quaternion whose norm is further than this from 1 is rejected as not a rotation."""


def wxyz_to_xyzw(q: np.ndarray) -> np.ndarray:
    """Reorder [..., 4] quaternions from (w, x, y, z) to (x, y, z, w)."""
    return np.concatenate([q[..., 1:4], q[..., :1]], axis=-1)


def xyzw_to_wxyz(q: np.ndarray) -> np.ndarray:
    """Reorder [..., 4] quaternions from (x, y, z, w) to (w, x, y, z)."""
    return np.concatenate([q[..., 3:4], q[..., :3]], axis=-1)


def reorder(q: np.ndarray, order: str) -> np.ndarray:
    """[..., 4] quaternions stored in ``order`` ("xyzw" or "wxyz") as (x, y, z, w)."""
    if order == "xyzw":
        return q
    if order == "wxyz":
        return wxyz_to_xyzw(q)
    raise ValueError(f"unknown quaternion order {order!r}")


def split_missing_and_normalise(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normalise stored quaternions and find the ones that are not rotations.

    Args:
        q: [..., 4] quaternions as read from a file (any finite values).

    Returns:
        ``(unit, present, bad)``: ``unit`` [..., 4] normalised quaternions (NaN where not
        present); ``present`` [...] bool, False for all-zero quaternions, which sensors write for
        "no orientation"; ``bad`` [...] bool, True where a non-zero quaternion's norm is further
        than :data:`UNIT_TOLERANCE` from 1 (a wrong column mapping, or corrupt data).
    """
    norm = np.linalg.norm(q, axis=-1)
    present = norm > 1e-9
    bad = present & (np.abs(norm - 1.0) > UNIT_TOLERANCE)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = q / norm[..., None]
    unit[~present] = np.nan
    return unit, present, bad


def make_continuous(q: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Flip signs along axis 0 so that each valid quaternion has q . q_prev >= 0.

    ``q_prev`` is the previous *valid* quaternion of the same series, so continuity holds across
    masked gaps too. The first valid quaternion of each series keeps its sign.

    Args:
        q: [T, ..., 4] quaternions (x, y, z, w).
        mask: [T, ...] bool, True where valid; all valid when None.

    Returns:
        A new [T, ..., 4] array.
    """
    q = np.array(q, dtype=np.float64)
    T = q.shape[0]
    flat = q.reshape(T, -1, 4)
    valid = np.ones(flat.shape[:2], bool) if mask is None else np.asarray(mask, bool).reshape(T, -1)
    for s in range(flat.shape[1]):
        idx = np.flatnonzero(valid[:, s])
        if idx.size < 2:
            continue
        series = flat[idx, s]
        dots = np.einsum("ij,ij->i", series[1:], series[:-1])
        flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
        flat[idx, s] = series * flips[:, None]
    return flat.reshape(q.shape)
