"""The Beat Align Score and the beat F-measure of many sets of music beats against one motion at once.

The chance levels of :func:`kinectdata.evaluation.beat_following.beat_following` score each motion
against its music's beats shifted by a thousand random phases. Scored one set at a time that is a
thousand calls per recording and figure; here the sets are scored together (a sorted search for
the nearest beats, one pass over the motion beats for the F-measure's matching), equal row by row
to :func:`~kinectdata.evaluation.rhythm.beat_align_score` and
:func:`~kinectdata.evaluation.rhythm.motion_beat_fmeasure` (``mir_eval.beat.f_measure``), which
tests/evaluation/test_beat_scores_rows.py checks against them.
"""

from __future__ import annotations

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.rhythm import BAS_DIRECTIONS, _beat_array


def beat_align_scores(music_rows: np.ndarray, motion_beats_s: np.ndarray, sigma_s: float, direction: str) -> np.ndarray:
    """Beat Align Score of each row of music beats against one motion's beats.

    Args:
        music_rows: [D, B] music beat times, seconds, increasing within each row.
        motion_beats_s: [K] motion beat times, seconds, increasing, on the same clock.
        sigma_s: the Gaussian's width, seconds (> 0).
        direction: ``music_to_motion`` (averaged over each row's music beats) or ``motion_to_music``
            (averaged over the motion beats, against each row).

    Returns:
        [D] scores in 0..1; 0 where the set averaged over or the other set is empty (what
        :func:`~kinectdata.evaluation.beat_following.beat_following` counts for a recording
        without beats).
    """
    music, motion = _sorted_beats(music_rows, motion_beats_s)
    if direction not in BAS_DIRECTIONS:
        raise KinectDataError(f"Beat Align Score direction must be one of {BAS_DIRECTIONS}, got {direction!r}")
    if not sigma_s > 0:
        raise KinectDataError(f"Beat Align Score sigma must be positive, got {sigma_s} s")
    if music.shape[1] == 0 or motion.size == 0:
        return np.zeros(music.shape[0])
    if direction == "music_to_motion":
        nearest = _nearest_gap(music, motion)
    else:
        nearest = np.stack([_nearest_gap(motion, row) for row in music])
    return np.mean(np.exp(-(nearest**2) / (2 * sigma_s**2)), axis=1)


def beat_fmeasures(music_rows: np.ndarray, motion_beats_s: np.ndarray, window_s: float) -> np.ndarray:
    """F-measure of one motion's beats against each row of music beats, as ``mir_eval.beat.f_measure``.

    The pairs within the window are mir_eval's (a music beat in [motion beat - window, motion beat +
    window], both ends computed as mir_eval computes them). Each motion beat's partners are then a
    run of consecutive music beats whose first and last move forward with the motion beat, and for
    such pairs the largest matching is the greedy one: each motion beat in turn takes the earliest
    music beat of its run not yet taken (Glover 1967, convex bipartite graphs). That matching's
    size is what mir_eval's maximum matching finds.

    Args:
        music_rows: [D, B] music beat times, seconds, increasing within each row.
        motion_beats_s: [K] motion beat times, seconds, increasing.
        window_s: the tolerance, seconds (> 0).

    Returns:
        [D] F-measures in 0..1; 0 where either set is empty.
    """
    music, motion = _sorted_beats(music_rows, motion_beats_s)
    if not window_s > 0:
        raise KinectDataError(f"F-measure window must be positive, got {window_s} s")
    rows, size = music.shape
    if size == 0 or motion.size == 0:
        return np.zeros(rows)
    first = np.stack([np.searchsorted(row, motion - window_s, side="left") for row in music])  # [D, K]
    after = np.stack([np.searchsorted(row, motion + window_s, side="right") for row in music])
    taken = np.full(rows, -1)
    matched = np.zeros(rows)
    for k in range(motion.size):
        candidate = np.maximum(first[:, k], taken + 1)
        hit = candidate < after[:, k]
        taken = np.where(hit, candidate, taken)
        matched += hit
    precision, recall = matched / motion.size, matched / size
    with np.errstate(invalid="ignore"):
        return np.where(matched > 0, 2 * precision * recall / (precision + recall), 0.0)


def _sorted_beats(music_rows, motion_beats_s) -> tuple[np.ndarray, np.ndarray]:
    """[D, B] and [K] float64 finite beat times, each row and the motion beats increasing (the
    motion beats checked as the one-set scorers check theirs: ``rhythm._beat_array``)."""
    motion = _beat_array(motion_beats_s, "motion beats", increasing=True)
    music = np.asarray(music_rows, dtype=np.float64)
    if music.ndim != 2:
        raise KinectDataError(f"music beat rows must be [D, B] times in seconds, got shape {music.shape}")
    finite = np.isfinite(music).all(axis=1)
    if not finite.all():
        raise KinectDataError(f"music beats: row {int(np.argmin(finite))} holds a time that is not finite")
    backwards = (np.diff(music, axis=1) < 0).any(axis=1)
    if backwards.any():
        raise KinectDataError(f"music beats must be in increasing order: row {int(np.argmax(backwards))} is not")
    return music, motion


def _nearest_gap(beats: np.ndarray, sorted_beats: np.ndarray) -> np.ndarray:
    """|b - nearest of ``sorted_beats``| for every value of ``beats`` (any shape), seconds: the
    nearest is one of the two between which b would be inserted."""
    at = np.searchsorted(sorted_beats, beats)
    below = sorted_beats[np.maximum(at - 1, 0)]
    above = sorted_beats[np.minimum(at, sorted_beats.size - 1)]
    return np.minimum(np.abs(beats - below), np.abs(beats - above))
