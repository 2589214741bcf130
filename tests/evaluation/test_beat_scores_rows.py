"""The scores of many beat sets at once equal mir_eval's F-measure and the Beat Align Score of each
set taken alone."""

from __future__ import annotations

import mir_eval
import numpy as np
import pytest

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.beat_scores_rows import beat_align_scores, beat_fmeasures
from kinectdata.evaluation.rhythm import beat_align_score


def _rows(rng, draws=300, beats=24, period=0.5):
    """Music beats shifted by random phases and wrapped around a 12-s span, as beat_following makes them."""
    base = np.arange(beats) * period + 0.2
    phases = rng.uniform(0, period, draws)
    return np.sort(np.mod(base[None, :] + phases[:, None], 12.0), axis=1)


@pytest.mark.parametrize(
    "motion",
    [
        np.arange(0.37, 12, 0.61),  # beats further apart than the window: the counted path
        np.sort(np.random.default_rng(1).uniform(0, 12, 20)),  # at random: both paths
        np.sort(np.concatenate([np.arange(0.1, 12, 0.5), np.arange(0.16, 12, 1.0)])),  # pairs 0.06 s apart
        np.array([3.0, 3.05, 3.1, 3.15]),  # a cluster: every matching is mir_eval's own
        np.array([0.0, 11.99]),  # at the span's ends
    ],
    ids=["spread", "random", "pairs", "cluster", "ends"],
)
def test_each_row_scores_as_the_one_set_scorers_do(motion):
    music = _rows(np.random.default_rng(0))
    f = beat_fmeasures(music, motion, 0.1)
    to_motion = beat_align_scores(music, motion, 0.05, "music_to_motion")
    to_music = beat_align_scores(music, motion, 0.05, "motion_to_music")
    for d, row in enumerate(music):
        assert f[d] == pytest.approx(mir_eval.beat.f_measure(row, motion, f_measure_threshold=0.1), abs=1e-12)
        assert to_motion[d] == pytest.approx(beat_align_score(row, motion, 0.05, "music_to_motion"), abs=1e-12)
        assert to_music[d] == pytest.approx(beat_align_score(row, motion, 0.05, "motion_to_music"), abs=1e-12)
    assert f.min() < f.max()  # the phases do move the figures


def test_a_beat_exactly_at_the_window_counts_as_mir_eval_counts_it():
    music = np.array([[1.0, 2.0, 3.0], [1.5, 2.5, 3.5]])
    motion = np.array([1.25, 2.0, 3.25])  # 0.25 s off: inside a 0.25-s window, outside a 0.2-s one
    for window in (0.25, 0.2):
        expected = [mir_eval.beat.f_measure(row, motion, f_measure_threshold=window) for row in music]
        assert beat_fmeasures(music, motion, window).tolist() == expected


def test_empty_sets_score_zero_and_a_bad_direction_is_refused():
    music = _rows(np.random.default_rng(2), draws=5)
    assert beat_fmeasures(music, np.zeros(0), 0.1).tolist() == [0.0] * 5
    assert beat_align_scores(music[:, :0], np.array([1.0]), 0.05, "music_to_motion").tolist() == [0.0] * 5
    with pytest.raises(KinectDataError, match="direction"):
        beat_align_scores(music, np.array([1.0]), 0.05, "sideways")
    with pytest.raises(KinectDataError, match="increasing order"):
        beat_fmeasures(music, np.array([2.0, 1.0]), 0.1)
    with pytest.raises(KinectDataError, match="row 3 is not"):
        beat_fmeasures(np.concatenate([music[:3], music[3:, ::-1]]), np.array([1.0]), 0.1)
    with pytest.raises(KinectDataError, match="not a finite time"):
        beat_align_scores(music, np.array([1.0, np.nan]), 0.05, "music_to_motion")
    with pytest.raises(KinectDataError, match="window must be positive"):
        beat_fmeasures(music, np.array([1.0]), 0.0)
    with pytest.raises(KinectDataError, match="sigma must be positive"):
        beat_align_scores(music, np.array([1.0]), 0.0, "music_to_motion")


def test_crowded_beats_match_as_mir_eval_matches_them():
    """Motion beats in clusters, several within one music beat's window: the greedy matching's size is
    mir_eval's maximum matching, over many random sets."""
    rng = np.random.default_rng(4)
    for _ in range(40):
        centres = rng.uniform(0, 12, rng.integers(1, 30))
        motion = np.sort(np.concatenate([centres + rng.normal(0, 0.08, centres.size) for _ in range(3)]))
        music = np.sort(rng.uniform(0, 12, (20, rng.integers(1, 40))), axis=1)
        window = rng.choice([0.05, 0.1, 0.3])
        expected = [mir_eval.beat.f_measure(row, motion, f_measure_threshold=window) for row in music]
        assert beat_fmeasures(music, motion, window) == pytest.approx(expected, abs=1e-12)
