"""Quaternion helpers on [..., 4] arrays in scipy's scalar-last order (x, y, z, w).

Rotation maths is left to :mod:`scipy.spatial.transform`, except :func:`slerp`: scipy's ``Slerp``
builds Rotation objects whose overhead dominated resampling (0.3 s of 0.4 s for a 10-minute
recording), so the formula is applied to arrays here, and tested against scipy's ``Slerp``. The
other functions handle what scipy does not: component order, zero quaternions meaning "no
orientation", and sign continuity over time (q and -q are the same rotation, but a learning
target must not jump between them).
"""

from __future__ import annotations

import numpy as np

from kinectdata.core.errors import ConfigError

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
    raise ConfigError(f"unknown quaternion order {order!r}")


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


def scatter(q: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Sum of the outer products q q^T over time, per series: [T, K, 4] -> [K, 4, 4].

    The same for q and -q, so it can be summed over recordings whatever sign each one uses; its
    principal eigenvector is the average rotation (:func:`average_quaternion`). ``mask`` [T, K]
    selects the valid quaternions (all when None).
    """
    q = np.asarray(q, dtype=np.float64)
    valid = np.ones(q.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    q = np.where(valid[..., None], q, 0.0)
    return np.einsum("tki,tkj->kij", q, q)


def average_quaternion(scatter_sum: np.ndarray) -> np.ndarray:
    """The average rotation of each series from its :func:`scatter`: [K, 4, 4] -> [K, 4] (x, y, z, w).

    It is the unit quaternion maximising sum (q . avg)^2 (Markley et al. 2007, the method of
    ``scipy.spatial.transform.Rotation.mean``): the principal eigenvector. Its sign is set so
    that its largest-magnitude component is positive. A series without valid quaternions
    (zero scatter) gets the identity.
    """
    scatter_sum = np.asarray(scatter_sum, dtype=np.float64)
    _, vectors = np.linalg.eigh(scatter_sum)
    avg = vectors[..., :, -1]  # eigh sorts eigenvalues in ascending order
    largest = np.take_along_axis(avg, np.abs(avg).argmax(axis=-1)[..., None], axis=-1)
    avg = avg * np.where(largest < 0, -1.0, 1.0)
    empty = ~np.any(scatter_sum != 0, axis=(-2, -1))
    avg[empty] = [0.0, 0.0, 0.0, 1.0]
    return avg


def slerp(q0: np.ndarray, q1: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation from ``q0`` to ``q1`` at fraction ``w``.

    Args:
        q0, q1: [N, 4] unit quaternions (x, y, z, w), in the same hemisphere (q0 . q1 >= 0, as
            :func:`make_continuous` leaves consecutive samples), so the arc is the shortest one.
        w: [N] fractions in 0..1.

    Returns:
        [N, 4] unit quaternions, in the hemisphere of the inputs.
    """
    dot = np.clip(np.einsum("ij,ij->i", q0, q1), -1.0, 1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    close = sin_theta < 1e-6  # (nearly) the same rotation: linear interpolation is exact enough
    safe = np.where(close, 1.0, sin_theta)
    a = np.where(close, 1.0 - w, np.sin((1.0 - w) * theta) / safe)
    b = np.where(close, w, np.sin(w * theta) / safe)
    out = a[:, None] * q0 + b[:, None] * q1
    return out / np.linalg.norm(out, axis=1, keepdims=True)
