"""Where a generated dance starts and where it stands in the world.

A model is given the pose before its first frame and then its own outputs. ``evaluate`` starts
every free run from the recording's true first pose; ``generate`` does the same when it dances to
an aligned recording's music or to a dataset split's songs (:class:`StartPose` from
:func:`recording_start` or from the dataset), and from the mean training pose when it only has
audio.

A run trained on root-centred targets (``--root-centre``) outputs the body around its root and the
root's travel from where the dance began, not where the dancer stood. Written out, the motion is put
back in the world:

- at the recording's **anchor** (:func:`kinectdata.targets.specs.root_anchor`: its root's mean
  position over its first second, as the targets were centred) when the dance is made for a
  recording: the root starts where the real dancer's did and travels as the model says;
- else by the **floor rule** (:func:`floor_anchor`): the root starts above the origin, and the
  lowest joint of the first frame stands on the floor (height 0 along y, kinectdata's up axis).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kinectdata.core.motion import Motion
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.skeleton import rebuild_positions
from kinectdata.targets.specs import TargetSpec, extract_targets, root_anchor


@dataclass(frozen=True)
class StartPose:
    """The start of a generated dance.

    Attributes:
        pose: [D] normalised target vector of frame 0 (a recording's true first pose, masked
            components filled as the model's kind fills them); frame 0 of the result is this pose and
            the model makes frames 1..T-1. None: the mean training pose is the pose before frame 0
            and the model makes every frame.
        anchor: [C] where a root-centred motion stands (metres), or None: :func:`floor_anchor`.
        source: what the start came from, for the printout (``"the recording's first pose"``).
    """

    pose: np.ndarray | None = None
    anchor: np.ndarray | None = None
    source: str = "the mean training pose"


def recording_start(motion: Motion, dataset: dict[str, Any], kind: Any) -> StartPose | None:
    """The start a recording gives a run: its first pose as the run's normalised target and its
    anchor when the run is root-centred; None when the recording's joint set is not the run's.

    Args:
        motion: the recording (e.g. an aligned ``.h5``'s motion).
        dataset: the run's ``config.json`` ``dataset`` record (``target``, ``normalisation``,
            ``root_centre``, ``start_pose``).
        kind: the run's :class:`~kinectdata.models.kind.ModelKind` (its ``fill_previous``).
    """
    spec = TargetSpec.from_dict(dataset["target"])
    js = motion.joint_set
    if (js.names, js.parents) != (spec.joints.names, spec.joints.parents):
        return None
    centred = bool(dataset["root_centre"])
    values, mask = extract_targets(motion, spec, root_centre=centred)
    start = np.asarray(dataset["start_pose"], np.float32)
    norm = Normalizer.from_dict(dataset["normalisation"])
    first = _same_hemisphere(values[0], norm.invert(start, spec), spec)
    pose = norm.apply(first[None], mask[:1])[0]
    pose = np.asarray(kind.fill_previous(pose, mask[0], start), np.float32)
    anchor = root_anchor(motion, spec) if centred else None
    if anchor is not None and not np.isfinite(anchor).all():
        anchor = None
    return StartPose(pose, anchor, "the recording's first pose")


def target_poses(
    values: np.ndarray,
    spec: TargetSpec,
    skeleton: dict,
    root_centred: bool,
    anchor: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The joints of denormalised target vectors [T, D], as ``generate`` writes them and ``live``
    sends them: positions [T, J, C] (NaN where not placed: 3-D ones by forward kinematics over the
    dataset's rest ``skeleton``, :func:`~kinectdata.targets.skeleton.rebuild_positions`; a 2-D
    target's as it gives them), orientations [T, J, 4] where the target has any (else None), and
    the anchor a root-centred 3-D motion stands at: ``anchor``, else the floor rule's from its first
    frame (None when the motion is not root-centred)."""
    js = spec.joints
    T, J = values.shape[0], len(js)
    orientations = None
    if spec.orientations:
        orientations = np.full((T, J, 4), np.nan)
        for joint in spec.orientations:
            orientations[:, js.index(joint)] = values[:, spec.columns(joint, "orientation")]
    if spec.dimensions != 3:
        positions = np.full((T, J, spec.dimensions), np.nan)
        for joint in spec.positions:
            positions[:, js.index(joint)] = values[:, spec.columns(joint, "position")]
        return positions, orientations, None
    if not (root_centred and spec.root is not None):
        return rebuild_positions(values, spec, skeleton, root_centred=root_centred)[0], orientations, None
    if anchor is None:
        first, _ = rebuild_positions(values[:1], spec, skeleton, root_centred=True)
        anchor = floor_anchor(first)
    positions, _ = rebuild_positions(values, spec, skeleton, root_centred=True, anchor=anchor)
    return positions, orientations, anchor


def floor_anchor(positions: np.ndarray) -> np.ndarray:
    """[3] the floor rule's anchor for positions [T, J, 3] (metres, y up, around the root): the
    root's start above the origin, the lowest valid joint of the first frame at height 0."""
    first = positions[0]
    lowest = np.nanmin(first[:, 1]) if np.isfinite(first[:, 1]).any() else 0.0
    return np.array([0.0, -float(lowest), 0.0])


def _same_hemisphere(pose: np.ndarray, reference: np.ndarray, spec: TargetSpec) -> np.ndarray:
    """Target vector ``pose`` [D] (target units) with each quaternion negated where it points away
    from ``reference``'s (q and -q are one rotation; the dataset put every track in its training
    mean's hemisphere)."""
    if not spec.orientations:
        return pose
    out = np.array(pose, np.float64)
    block = out[spec.orientation_slice].reshape(-1, 4)
    ref = np.asarray(reference, np.float64)[spec.orientation_slice].reshape(-1, 4)
    block[np.sum(block * ref, axis=1) < 0] *= -1
    out[spec.orientation_slice] = block.reshape(-1)
    return out
