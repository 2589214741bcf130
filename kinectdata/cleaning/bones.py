"""Bones held to one length: a sensor's skeleton stretches (the tang2018 dancers' bones change
length by 1-5 cm within a dance; bone-length CV 0.10), a body does not.

Each bone gets the recording's robust length, the median over the frames where both its ends are
valid (or a length given, for a body that was measured), and the skeleton is rebuilt from the root
out: a joint is put at its parent's new place plus that length along the bone's own direction in
that frame, so that every bone keeps its direction and only its length changes. A joint whose parent
is masked in a frame keeps its place (it starts the chain below it), and a masked joint stays masked.
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


def hold_bone_lengths(
    positions: np.ndarray,
    parents: Sequence[int],
    mask: np.ndarray,
    lengths: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Rebuild the skeleton with each bone at one length (see the module docstring).

    Args:
        positions: [T, J, D] joint positions, metres.
        parents: [J] each joint's parent index, -1 for a root.
        mask: [T, J] True where valid.
        lengths: [J] the lengths to hold, metres (NaN for a root, or to use the recording's own);
            default :func:`robust_lengths`.

    Returns:
        ``(positions [T, J, D], lengths [J])``: the rebuilt positions (NaN where masked) and the
        lengths held.
    """
    p = np.where(mask[..., None], np.asarray(positions, np.float64), np.nan)
    own = robust_lengths(p, parents, mask)
    held = own if lengths is None else np.where(np.isfinite(lengths), lengths, own)
    out = p.copy()
    for j in parents_first(parents):
        parent = parents[j]
        if parent < 0 or not np.isfinite(held[j]):
            continue
        bone = p[:, j] - p[:, parent]
        size = np.linalg.norm(bone, axis=-1, keepdims=True)
        both = mask[:, j] & mask[:, parent] & (size[:, 0] > 0)
        direction = np.divide(bone, size, out=np.zeros_like(bone), where=size > 0)
        out[both, j] = out[both, parent] + held[j] * direction[both]
    return out, held


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
