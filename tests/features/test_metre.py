"""The music's metre: 3 or 4 beats per bar, estimated from synthesized music whose downbeats sound
different from the other beats, and where a recording's metre comes from."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("librosa")

from helpers import metre_music  # noqa: E402

from kinectdata.core.errors import KinectDataError  # noqa: E402
from kinectdata.features.metre import (  # noqa: E402
    MEL_BANDS,
    MIN_BEATS,
    Metre,
    bar_similarity,
    beat_descriptors,
    estimate_beats_per_bar,
    recording_metre,
)

RATE = 22050  # metre_music's default rate
music = metre_music


@pytest.mark.parametrize("bpm", [100.0, 117.0, 130.0])
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("bars_of", [3, 4])
def test_the_estimate_tells_three_from_four(bpm, seed, bars_of):
    samples, beats = music(bpm, bars_of, bars=12, seed=seed)
    metre = estimate_beats_per_bar(samples, RATE, beats)
    assert metre.beats_per_bar == bars_of and metre.source == "estimated"
    assert set(metre.scores) == {3, 4}
    other = 7 - bars_of
    assert metre.scores[bars_of] > metre.scores[other] + 0.2  # not a near tie
    # a bar of the right length pairs downbeats with downbeats (alike), of the wrong one mostly
    # downbeats with other beats (unlike, after each band is standardised)
    assert metre.scores[bars_of] > 0 > metre.scores[other]
    assert f"{bars_of} beats per bar (estimated; bar-to-bar similarity 3: " in metre.describe()


def test_beat_descriptors_are_standardised_and_hear_the_bass_on_the_downbeats():
    samples, beats = music(110.0, 3, bars=8, seed=2)
    d = beat_descriptors(samples, RATE, beats)
    assert d.shape == (len(beats) - 1, MEL_BANDS)
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=1e-4)
    np.testing.assert_allclose(d.std(axis=0), 1.0, atol=1e-4)
    # the lowest mel bands (below ~150 Hz, where the bass tone sits) are loud on downbeats only
    down = np.arange(len(d)) % 3 == 0
    assert d[down, :3].mean() > 1.0 and d[~down, :3].mean() < -0.3


def test_bar_similarity_is_the_mean_cosine_one_and_two_bars_apart():
    from scipy.spatial.distance import cosine

    rng = np.random.default_rng(0)
    d = rng.normal(size=(20, 5))
    for m in (2, 3, 4):
        expected = np.mean([np.mean([1 - cosine(d[k], d[k + lag]) for k in range(20 - lag)]) for lag in (m, 2 * m)])
        assert bar_similarity(d, m) == pytest.approx(expected, rel=1e-12)
    periodic = np.tile(rng.normal(size=(3, 5)), (7, 1))  # repeats every 3 rows exactly
    assert bar_similarity(periodic, 3) == pytest.approx(1.0)
    assert bar_similarity(periodic, 4) < 0.9


def test_too_few_beats_is_an_error():
    samples, beats = music(120.0, 4, bars=4, seed=0)  # 16 beats
    assert len(beats) == MIN_BEATS - 1
    with pytest.raises(KinectDataError, match=f"at least {MIN_BEATS} beats, got 16"):
        estimate_beats_per_bar(samples, RATE, beats)


def test_a_recordings_metre_comes_from_its_manifest_entry_then_the_caller_then_the_music():
    waltz, beats = music(105.0, 3, bars=10, seed=3)
    assert recording_metre(3, None, RATE, beats, given=4) == Metre(3, "manifest", {})
    assert recording_metre(None, waltz, RATE, beats, given=2, found=4) == Metre(2, "given", {})
    assert recording_metre(None, waltz, RATE, beats, found=4) == Metre(4, "dataset", {})  # what the build found
    estimated = recording_metre(None, waltz, RATE, beats)
    assert (estimated.beats_per_bar, estimated.source) == (3, "estimated") and estimated.scores
    tracked = recording_metre(None, waltz, RATE)  # the beats tracked from the music itself
    assert (tracked.beats_per_bar, tracked.source) == (3, "estimated")
    assert recording_metre(None, None, RATE, beats) == Metre(4, "default", {})
    assert recording_metre(None, waltz, RATE, beats[:10]) == Metre(4, "default", {})  # too few beats
    assert Metre(4, "default", {}).describe() == "4 beats per bar (default)"
