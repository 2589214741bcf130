"""One quaternion sign per joint across a dataset's recordings.

q and -q are the same rotation. Within a recording the targets are sign-continuous
(:func:`~kinectdata.targets.specs.extract_targets`), but each recording's track may sit in either
hemisphere, and a model trained on a mix would have to learn +q for some songs and -q for
others. No fixed rule fixes that: "w >= 0" splits exactly at half-turn rotations, which is where
Kinect puts the joints of a dancer facing the sensor. So the build picks, per joint, the average
orientation of the training split (:func:`~kinectdata.core.quaternions.average_quaternion` of the
summed sign-free scatter matrices) and negates each recording's whole track of that joint when
its sum points away from it (negative dot product). Continuity within the track is kept, and
the choice depends only on the training split, like the normalisation.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from kinectdata.core.quaternions import average_quaternion, scatter
from kinectdata.targets.specs import TargetSpec


def orientation_stats(values: np.ndarray, mask: np.ndarray, spec: TargetSpec) -> dict[str, list]:
    """A recording's per-joint quaternion statistics from its targets [T, D] and mask [T, D]:
    ``scatter`` [K, 4, 4] (sign-free) and ``sum`` [K, 4] of the valid quaternions."""
    T, K = values.shape[0], len(spec.orientations)
    q = values[:, spec.orientation_slice].reshape(T, K, 4)
    valid = mask[:, spec.orientation_slice].reshape(T, K, 4)[..., 0]
    q = np.where(valid[..., None], q, 0.0)
    return {"scatter": scatter(q, valid).tolist(), "sum": q.sum(axis=0).tolist()}


def reference_orientations(stats: Iterable[dict[str, list]], spec: TargetSpec) -> np.ndarray:
    """[K, 4] average orientation per joint (x, y, z, w) over the given recordings' stats."""
    total = np.zeros((len(spec.orientations), 4, 4))
    for s in stats:
        total += np.asarray(s["scatter"], dtype=np.float64).reshape(total.shape)
    return average_quaternion(total)


def track_flips(stats: dict[str, list], reference: np.ndarray) -> np.ndarray:
    """[K] bool: which joints' tracks to negate so that they agree with ``reference`` [K, 4]."""
    sums = np.asarray(stats["sum"], dtype=np.float64).reshape(reference.shape)
    return np.einsum("ki,ki->k", sums, reference) < 0


def flipped_columns(spec: TargetSpec, flips: np.ndarray) -> np.ndarray:
    """[D] bool: the target columns negated by ``flips`` [K]."""
    columns = np.zeros(spec.dim, bool)
    for s, flip in zip(spec.quaternion_slices, flips):
        columns[s] = flip
    return columns


def apply_flips(values: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Targets [T, D] with the ``columns`` [D] negated (masked zeros stay +0.0)."""
    return np.where(columns & (values != 0), -values, values)
