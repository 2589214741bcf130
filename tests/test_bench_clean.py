"""bench_clean's measures on small inputs: the numbers it prints come from the truth it is given."""

from __future__ import annotations

import pytest

from benchmarks.bench_clean import _overlap, swaps


def test_stretches_match_by_half_their_union():
    assert _overlap((10, 19), (10, 19)) == 1.0
    assert _overlap((10, 19), (15, 24)) == pytest.approx(5 / 15)
    assert _overlap((10, 19), (20, 29)) == 0.0


def test_the_turning_dancer_is_found_and_repaired():
    """One 20-s dance with its turns: every mirrored stretch found, its error cut to the sensor's noise."""
    figures = swaps(seeds=[0], seconds=20.0)
    assert figures["mirrored"] >= 1
    assert figures["precision"] == figures["recall"] == 1.0
    assert figures["error_before_mm"] > 100 > 10 > figures["error_after_mm"]
