"""Gaps and inferred jumps: a tracker loses a joint for a few frames, and while it only infers one
(Kinect's "inferred" state, confidence below 1) the joint can jump away from where the body is.

:func:`fill_gaps` first finds the inferred samples that jump: those further than ``jump_m`` from the
straight line between the joint's nearest fully tracked samples before and after them (a joint
inferred at the start or end of a recording has one side only and is kept). They are taken out,
then every gap no longer than ``max_gap_s`` is filled as ``align`` fills them
(:func:`kinectdata.align.timeline.resample_motion` onto the recording's own frame times: positions
linearly, orientations by slerp, a filled sample's confidence at most the inferred one's, 0.5).
Longer gaps stay masked and are listed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from kinectdata.align.timeline import Gap, resample_motion
from kinectdata.core.motion import Motion

TRACKED = 1.0
"""The confidence of a fully tracked sample; below it, a sample was inferred."""


@dataclass(frozen=True)
class GapReport:
    """What :func:`fill_gaps` did.

    Attributes:
        max_gap_s: the longest gap filled, seconds.
        jumps_replaced: inferred samples taken out for jumping, then filled or left masked.
        samples_filled: joint samples filled by interpolation.
        gaps_filled: runs of a joint's frames filled (a dropped frame of the whole recording, which has
            no frame to fill, is not one).
        gaps_left: position gaps longer than the limit (or at an edge of the recording), left masked.
        longest_left_s: the longest of them, seconds (0 when none).
        joints_left: the joints with a gap left.
    """

    max_gap_s: float
    jumps_replaced: int
    samples_filled: int
    gaps_filled: int
    gaps_left: int
    longest_left_s: float
    joints_left: tuple[str, ...]


def inferred_jumps(positions: np.ndarray, times: np.ndarray, mask: np.ndarray, confidence: np.ndarray,
                   jump_m: float) -> np.ndarray:  # fmt: skip
    """[T, J] True where a valid inferred sample (0 < confidence < 1) lies further than ``jump_m``
    metres from the line between the nearest fully tracked samples of its joint around it."""
    jumps = np.zeros(mask.shape, bool)
    tracked = mask & (confidence >= TRACKED)
    for j in range(mask.shape[1]):
        inferred = np.flatnonzero(mask[:, j] & ~tracked[:, j])
        anchors = np.flatnonzero(tracked[:, j])
        if inferred.size == 0 or anchors.size < 2:
            continue
        inside = (inferred > anchors[0]) & (inferred < anchors[-1])
        frames = inferred[inside]
        if frames.size == 0:
            continue
        expected = np.stack(
            [np.interp(times[frames], times[anchors], positions[anchors, j, c]) for c in range(positions.shape[-1])],
            axis=-1,
        )
        jumps[frames, j] = np.linalg.norm(positions[frames, j] - expected, axis=-1) > jump_m
    return jumps


def fill_gaps(motion: Motion, max_gap_s: float = 0.2, jump_m: float = 0.1) -> tuple[Motion, GapReport]:
    """Replace inferred jumps and fill short gaps (see the module docstring).

    Args:
        motion: the recording (positions in metres).
        max_gap_s: the longest gap filled, seconds of missing samples (``align``'s ``--max-gap``).
        jump_m: how far an inferred sample may lie from its tracked neighbours' line, metres.

    Returns:
        The recording with the same frame times, and the report.
    """
    jumps = inferred_jumps(motion.positions, motion.times, motion.position_mask, motion.confidence, jump_m)
    taken = dataclasses.replace(motion, position_mask=motion.position_mask & ~jumps)
    resampled = resample_motion(taken, motion.times, max_gap=max_gap_s)
    filled = resampled.motion
    left: list[Gap] = [g for g in resampled.gaps if g.quantity == "position" and not g.filled]
    filled_runs = np.diff(resampled.position_interpolated.astype(np.int8), axis=0, prepend=0) == 1
    report = GapReport(
        float(max_gap_s),
        int(jumps.sum()),
        int(resampled.position_interpolated.sum()),
        int(filled_runs.sum()),
        len(left),
        max((g.length for g in left), default=0.0),
        tuple(sorted({g.joint for g in left})),
    )
    return dataclasses.replace(filled, metadata=dict(motion.metadata)), report
