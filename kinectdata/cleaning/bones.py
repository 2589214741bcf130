"""Bones held to one length: a sensor's skeleton stretches (the tang2018 dancers' bones change
length by 1-5 cm within a dance; bone-length CV 0.10), a body does not.

Each bone gets the recording's robust length, the median over the frames where both its ends are
valid (or a length given, for a body that was measured), in two passes:

1. **spread** (:func:`spread_to_lengths`): each bone's error in length is shared between its two ends,
   bone after bone from the root out, over ``iterations`` rounds (the projection of position-based
   dynamics, Mueller et al. 2007, vectorised over frames): every joint moves a little, along its
   bones, towards the lengths, so a noisy joint is pulled back by all its neighbours;
2. **from the root out**: a joint is put at its parent's new place plus the length along the bone's
   own direction in that frame, so that every bone keeps its direction and has its length exactly.

After the first pass the second moves the joints by a fraction of a millimetre. Rebuilding from the
root alone (the second pass on the raw joints) carries each bone's direction noise to every joint
below it: on the simulated Kinect it left the joints 4.1 mm from the truth where the spread pass
leaves them 2.8 mm (the filter alone 3.2 mm; ``bench_clean``). A joint whose parent is masked in a
frame keeps its place (it starts the chain below it), and a masked joint stays masked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from kinectdata.core.body_quality import bone_lengths
from kinectdata.core.errors import ConfigError
from kinectdata.core.jointsets import parents_first


def robust_lengths(positions: np.ndarray, parents: Sequence[int], mask: np.ndarray) -> np.ndarray:
    """[J] each bone's median length over the frames where both its ends are valid (metres; NaN for
    a root and for a bone never seen whole)."""
    lengths = bone_lengths(positions, parents, mask)
    out = np.full(len(parents), np.nan)
    for j in range(len(parents)):
        seen = lengths[np.isfinite(lengths[:, j]), j]
        if seen.size:
            out[j] = float(np.median(seen))
    return out


SPREAD_ROUNDS = 20
"""Rounds of the spread pass: on the simulated Kinect 5 leave the joints within 0.02 mm of 50's."""


def spread_to_lengths(positions: np.ndarray, parents: Sequence[int], mask: np.ndarray, lengths: np.ndarray,
                      rounds: int = SPREAD_ROUNDS) -> np.ndarray:  # fmt: skip
    """[T, J, D] the joints moved towards bones of ``lengths`` [J] (metres; NaN: a bone left as it is),
    each bone's error in length shared equally by its two valid ends, for ``rounds`` rounds over the
    bones in parents-first order. ``positions`` [T, J, D] metres, ``mask`` [T, J]."""
    # joint-major [J, D, T]: each bone's step reads and writes two contiguous blocks, in place
    x = np.ascontiguousarray(np.where(mask[..., None], np.asarray(positions, np.float64), 0.0).transpose(1, 2, 0))
    bones = [j for j in parents_first(parents) if parents[j] >= 0 and np.isfinite(lengths[j])]
    share = {j: 0.5 * (mask[:, j] & mask[:, parents[j]]) for j in bones}
    bone, size, half = np.empty(x.shape[1:]), np.empty(x.shape[2]), np.empty(x.shape[2])
    for _ in range(rounds):
        for j in bones:
            parent = parents[j]
            np.subtract(x[j], x[parent], out=bone)
            np.sqrt(np.einsum("dt,dt->t", bone, bone), out=size)
            np.subtract(size, lengths[j], out=half)
            np.divide(half, size, out=half, where=size > 0)
            half[size <= 0] = 0.0
            half *= share[j]
            bone *= half
            x[j] -= bone
            x[parent] += bone
    return np.where(mask[..., None], x.transpose(2, 0, 1), np.nan)


def hold_bone_lengths(
    positions: np.ndarray,
    parents: Sequence[int],
    mask: np.ndarray,
    lengths: np.ndarray | None = None,
    spread: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Rebuild the skeleton with each bone at one length (see the module docstring).

    Args:
        positions: [T, J, D] joint positions, metres.
        parents: [J] each joint's parent index, -1 for a root.
        mask: [T, J] True where valid.
        lengths: [J] the lengths to hold, metres (NaN for a root, or to use the recording's own);
            default :func:`robust_lengths`.
        spread: run the spread pass first (False: only the rebuild from the root out).

    Returns:
        ``(positions [T, J, D], lengths [J])``: the rebuilt positions (NaN where masked) and the
        lengths held.
    """
    p = np.where(mask[..., None], np.asarray(positions, np.float64), np.nan)
    own = robust_lengths(p, parents, mask)
    held = own if lengths is None else np.where(np.isfinite(lengths), lengths, own)
    if spread:
        p = spread_to_lengths(p, parents, mask, held)
    p = np.ascontiguousarray(p.transpose(1, 2, 0))  # joint-major [J, D, T], as in the spread pass
    out = p.copy()
    for j in parents_first(parents):
        parent = parents[j]
        if parent < 0 or not np.isfinite(held[j]):
            continue
        bone = p[j] - p[parent]
        size = np.sqrt(np.einsum("dt,dt->t", bone, bone))
        both = mask[:, j] & mask[:, parent] & (size > 0)
        step = np.divide(held[j] * bone, size, out=np.zeros_like(bone), where=both)
        out[j] = np.where(both, out[parent] + step, out[j])
    return out.transpose(2, 0, 1).copy(), held


def lengths_by_name(names: Sequence[str], given: Mapping[str, float]) -> np.ndarray:
    """[J] lengths from ``{child joint name: metres}`` (NaN for the joints not named); ConfigError
    naming a joint the set does not have or a length that is not positive."""
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise ConfigError(f"bone lengths given for {', '.join(unknown)}, which the joint set does not have")
    out = np.full(len(names), np.nan)
    for name, length in given.items():
        if not (np.isfinite(length) and length > 0):
            raise ConfigError(f"the bone to {name} must have a positive length in metres, not {length!r}")
        out[list(names).index(name)] = float(length)
    return out
