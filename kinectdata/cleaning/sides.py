"""Left and right swapped back: a tracker that assumes a frontal body (Kinect's does) labels a dancer
seen from behind as if she faced it, so her left joints are written as right ones for as long as she
faces away, and the labels jump from one side to the other as she turns past side-on.

:func:`find_side_swaps` finds those stretches in two steps:

1. **Where the labels jump** (continuity of each side's joints): between two frames, each pair of
   mirrored joints (``JointSet.mirror_image``: left and right hip, knee, hand...) either kept its
   labels (each joint near where it was) or swapped them (each near where its mirror image was). A
   frame is a **flip** when the swapped pairing is closer for at least ``vote`` of the pairs seen in
   both frames and its summed squared distance is at most ``ratio`` times the kept pairing's. A real
   body's hands may cross, its hips and shoulders do not: one limb alone never makes a flip.
2. **Which side of each flip is mirrored.** The flips cut the recording into stretches whose labels
   alternate, so only one choice is left: which parity is the mirrored one. Where the joint set has
   feet (a ``left_foot`` / ``right_foot`` role whose joint is a leaf below the ankle), the facing
   the hips give (up x the left-to-right hip line, in right-handed coordinates: mirrored labels turn
   it round) is compared with the facing the feet give (where the toes point: the same whichever
   label a foot has); the parity whose frames agree less is the mirrored one. Without feet, or when
   they do not tell clearly (the two parities' mean signs less than 0.5 apart), the parity with fewer
   frames is taken as mirrored: a frontal tracker is right while the dancer faces it.

:func:`kinectdata.core.motion.sides_exchanged` swaps every mirrored pair's positions, masks,
confidences and orientations back in the frames found.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.core.jointsets import JointSet
from kinectdata.core.motion import held_from_nearest, true_runs

FLIP_VOTE = 0.75
"""The share of mirrored pairs whose swapped pairing must be the closer one for a flip."""
FLIP_RATIO = 0.5
"""A flip's swapped pairing: its summed squared distance at most this times the kept pairing's."""


@dataclass(frozen=True)
class SideSwaps:
    """The stretches :func:`find_side_swaps` found mirrored.

    Attributes:
        intervals: ``(first frame, last frame)`` of each mirrored stretch, inclusive.
        flips: the frames where the labels jumped (the first frame after each jump).
        judged_by: ``feet`` (the hips' facing against the feet's) or ``majority`` (the parity with
            fewer frames taken as mirrored).
    """

    intervals: tuple[tuple[int, int], ...]
    flips: tuple[int, ...]
    judged_by: str

    def frames(self, n_frames: int) -> np.ndarray:
        """[T] True in the mirrored frames."""
        out = np.zeros(n_frames, bool)
        for first, last in self.intervals:
            out[first : last + 1] = True
        return out


def mirrored_pairs(joint_set: JointSet) -> np.ndarray:
    """[P, 2] the (left, right) index pairs of a joint set's mirrored joints (each pair once);
    ConfigError when it has none."""
    image = joint_set.mirror_image()
    pairs = np.array([(j, int(image[j])) for j in range(len(image)) if image[j] > j], dtype=int).reshape(-1, 2)
    if len(pairs) < 2:
        raise ConfigError(f"joint set {joint_set.name} has fewer than two mirrored pairs: its sides cannot be told")
    return pairs


def label_flips(positions: np.ndarray, mask: np.ndarray, pairs: np.ndarray, vote: float = FLIP_VOTE,
                ratio: float = FLIP_RATIO) -> np.ndarray:  # fmt: skip
    """[T] True at each frame whose mirrored pairs swapped labels since the frame before (step 1 of
    the module docstring). A joint masked in a frame is compared from its last valid place.

    Args:
        positions: [T, J, 3] metres.
        mask: [T, J] True where valid.
        pairs: [P, 2] mirrored joint pairs (:func:`mirrored_pairs`).
    """
    held = held_from_nearest(np.asarray(positions, np.float64), mask)
    seen = np.maximum.accumulate(mask, axis=0)  # a joint compared once it has been seen
    left, right = held[:, pairs[:, 0]], held[:, pairs[:, 1]]  # [T, P, 3]
    both = seen[:, pairs[:, 0]] & seen[:, pairs[:, 1]]
    both = both[1:] & both[:-1]  # [T-1, P]

    def squared(a, b):
        return np.sum((a[1:] - b[:-1]) ** 2, axis=-1)

    kept = squared(left, left) + squared(right, right)
    swapped = squared(left, right) + squared(right, left)
    counted = both.sum(axis=1)
    closer = ((swapped < kept) & both).sum(axis=1)
    total_kept, total_swapped = (np.where(both, kept, 0.0).sum(axis=1), np.where(both, swapped, 0.0).sum(axis=1))
    flip = (counted >= 2) & (closer >= vote * counted) & (total_swapped <= ratio * total_kept)
    return np.concatenate([[False], flip])


def _foot_cue(positions: np.ndarray, mask: np.ndarray, joint_set: JointSet, up: np.ndarray) -> np.ndarray | None:
    """[T] the cosine between the facing the hips give (``up x (right hip - left hip)``, horizontal)
    and the one the toes give (each foot's joint minus its ankle, summed), NaN where not seen; None
    when the joint set has no feet whose joint is a leaf below an ankle below a knee below a hip."""
    feet = [joint_set.role(f"{side}_foot") for side in ("left", "right")]
    if None in feet or any(j in joint_set.parents for j in feet):
        return None
    hips = []
    for foot in feet:
        j = foot
        for _ in range(3):  # foot -> ankle -> knee -> hip
            j = joint_set.parents[j] if j >= 0 else -1
        hips.append(j)
    if min(hips) < 0 or joint_set.mirror_image()[hips[0]] != hips[1]:
        return None
    p = np.where(mask[..., None], np.asarray(positions, np.float64), np.nan)
    hips_facing = np.cross(up, p[:, hips[1]] - p[:, hips[0]])
    toes = sum(p[:, f] - p[:, joint_set.parents[f]] for f in feet)
    toes = toes - np.sum(toes * up, axis=-1, keepdims=True) * up  # horizontal
    scale = np.linalg.norm(hips_facing, axis=1) * np.linalg.norm(toes, axis=1)
    return np.sum(hips_facing * toes, axis=1) / np.where(scale > 0, scale, np.nan)


def find_side_swaps(
    positions: np.ndarray, mask: np.ndarray, joint_set: JointSet, up: tuple[float, float, float] = (0.0, 1.0, 0.0)
) -> SideSwaps:
    """The stretches of a recording whose left and right labels are mirrored (module docstring).

    Args:
        positions: [T, J, 3] metres.
        mask: [T, J] True where valid.
        joint_set: the recording's joint set (its mirrored pairs, its feet and hips).
        up: the unit vector pointing up in the recording's (right-handed) coordinates: +y for
            Kinect v1/v2 camera space, BVH and SMPL; -y for Azure Kinect's camera space.

    Raises:
        ConfigError: a joint set with fewer than two mirrored pairs.
    """
    pairs = mirrored_pairs(joint_set)
    T = positions.shape[0]
    flips = np.flatnonzero(label_flips(positions, mask, pairs))
    parity = np.zeros(T, np.int8)
    parity[flips] = 1
    parity = np.cumsum(parity) % 2  # [T] which side of an even number of flips a frame is on
    judged_by = "majority"
    odd = int(parity.sum()) <= T - int(parity.sum())  # the parity with fewer frames
    cue = _foot_cue(positions, mask, joint_set, np.asarray(up, np.float64)) if flips.size else None
    if cue is not None:
        seen = np.isfinite(cue)
        agree = [float(np.mean(np.sign(cue[seen & (parity == k)]))) if (seen & (parity == k)).any() else 0.0
                 for k in (0, 1)]  # fmt: skip
        if abs(agree[0] - agree[1]) > 0.5:  # the feet say clearly which parity faces its hips round
            odd = agree[1] < agree[0]
            judged_by = "feet"
    return SideSwaps(true_runs(parity == (1 if odd else 0)), tuple(int(f) for f in flips), judged_by)
