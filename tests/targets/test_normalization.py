"""Normalisation statistics and the maxabs / minmax normalisers."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import random_motion

from kinectdata.targets.normalization import Normalizer, NormStats, count_out_of_range
from kinectdata.targets.specs import extract_targets, load_target_spec

F9 = np.float32(0.9)


def targets(seed: int = 0, T: int = 120, root_centre: bool = True):
    spec = load_target_spec("kinect_v2_full")
    values, mask = extract_targets(random_motion(T, seed=seed), spec, root_centre=root_centre)
    return spec, values, mask


def fitted(method: str, seed: int = 0):
    spec, values, mask = targets(seed)
    stats = NormStats.from_arrays(values, mask, spec.component_names())
    return spec, values, mask, Normalizer.fit(stats, method)


def valid_extremes(y, mask, fn):
    return np.array([fn(y[mask[:, c], c]) for c in range(y.shape[1])])


def test_maxabs_maps_each_components_largest_magnitude_to_0_9():
    spec, values, mask, norm = fitted("maxabs")
    y = norm.apply(values, mask)
    assert y.dtype == np.float32 and norm.method == "maxabs" and not norm.degenerate
    assert np.all(valid_extremes(np.abs(y), mask, np.max) == F9)
    assert np.all(np.abs(y) <= F9)
    # the paper's formula, computed independently
    m = valid_extremes(np.abs(values), mask, np.max)
    np.testing.assert_allclose(y, np.where(mask, 0.9 * values / m, 0.0), rtol=1e-6, atol=1e-7)
    assert np.all(y[~mask] == 0.0)


def test_minmax_maps_min_and_max_to_minus_and_plus_0_9():
    spec, values, mask, norm = fitted("minmax")
    y = norm.apply(values, mask)
    assert np.all(valid_extremes(y, mask, np.min) == -F9)
    assert np.all(valid_extremes(y, mask, np.max) == F9)
    lo = valid_extremes(values, mask, np.min)
    hi = valid_extremes(values, mask, np.max)
    expected = -0.9 + 1.8 * (values - lo) / (hi - lo)
    np.testing.assert_allclose(y[mask], expected[mask], rtol=1e-6, atol=1e-7)
    assert np.all(y[~mask] == 0.0)


@pytest.mark.parametrize("method", ["maxabs", "minmax"])
def test_invert_undoes_apply_and_gives_unit_quaternions(method):
    spec, values, mask, norm = fitted(method)
    back = norm.invert(norm.apply(values, mask), spec, mask=mask)
    assert back.dtype == np.float64
    span = valid_extremes(values, mask, np.max) - valid_extremes(values, mask, np.min)
    pos = spec.position_slice
    np.testing.assert_allclose(back[:, pos], values[:, pos], rtol=1e-6, atol=1e-6 * span[pos].max())
    for s in spec.quaternion_slices:
        q, ok = back[:, s], mask[:, s.start]
        np.testing.assert_allclose(np.linalg.norm(q[ok], axis=1), 1.0, atol=1e-6)
        np.testing.assert_allclose(q[ok], values[ok, s], atol=1e-6)
        assert np.all(q[~ok] == 0.0)  # zero quaternions of masked entries stay zero
    assert np.all(back[~mask] == 0.0)


def test_maxabs_invert_keeps_masked_quaternions_zero_without_a_mask():
    spec, values, mask, norm = fitted("maxabs")
    back = norm.invert(norm.apply(values, mask), spec)
    for s in spec.quaternion_slices:
        assert np.all(back[~mask[:, s.start], s] == 0.0)
    with pytest.raises(ValueError, match="does not describe"):
        norm.invert(np.zeros((1, 147)), load_target_spec("yalta65"))


def test_stats_merged_over_chunks_equal_stats_of_the_whole():
    spec, values, mask = targets(T=200)
    names = spec.component_names()
    whole = NormStats.from_arrays(values, mask, names)
    chunks = [NormStats.from_arrays(values[a:b], mask[a:b], names) for a, b in ((0, 7), (7, 90), (90, 91), (91, 200))]
    merged = NormStats.merge_all(chunks)
    np.testing.assert_array_equal(merged.count, mask.sum(axis=0))
    for a, b in ((merged.count, whole.count), (merged.min, whole.min), (merged.max, whole.max)):
        np.testing.assert_array_equal(a, b)
    assert merged.names == tuple(names)
    empty = NormStats.empty(spec.dim, names)
    np.testing.assert_array_equal(empty.merge(whole).max, whole.max)
    with pytest.raises(ValueError, match="different target layouts"):
        whole.merge(NormStats.empty(3))


def test_negated_stats_equal_stats_of_negated_values():
    spec, values, mask = targets(T=50)
    columns = np.zeros(spec.dim, bool)
    columns[spec.quaternion_slices[2]] = True
    flipped = np.where(columns, -values, values)
    a = NormStats.from_arrays(values, mask).negated(columns)
    b = NormStats.from_arrays(flipped, mask)
    for x, y in ((a.count, b.count), (a.min, b.min), (a.max, b.max)):
        np.testing.assert_array_equal(x, y)


def test_to_dict_round_trips_exactly_through_json():
    spec, values, mask, norm = fitted("minmax")
    stats = NormStats.from_arrays(values, mask, spec.component_names())
    stats_doc = json.loads(json.dumps(stats.to_dict(), allow_nan=False))
    again = NormStats.from_dict(stats_doc)
    assert again.to_dict() == stats.to_dict()
    np.testing.assert_array_equal(again.min, stats.min)
    doc = json.loads(json.dumps(norm.to_dict(), allow_nan=False))
    assert doc["method"] == "minmax" and doc["names"] == spec.component_names() and len(doc["scale"]) == 147
    back = Normalizer.from_dict(doc)
    assert back.to_dict() == norm.to_dict()
    np.testing.assert_array_equal(back.scale, norm.scale)
    np.testing.assert_array_equal(back.offset, norm.offset)
    np.testing.assert_array_equal(back.apply(values, mask), norm.apply(values, mask))


def test_degenerate_components():
    train = np.array([[1.0, 2.0, 0.0, 5.0], [3.0, 2.0, 0.0, 7.0], [-4.0, 2.0, 0.0, 9.0]])
    mask = np.ones_like(train, bool)
    mask[:, 3] = False  # component 3 never valid
    stats = NormStats.from_arrays(train, mask)
    assert stats.count.tolist() == [3, 3, 3, 0] and np.isnan(stats.min[3])
    assert NormStats.from_dict(json.loads(json.dumps(stats.to_dict(), allow_nan=False))).count.tolist() == [3, 3, 3, 0]
    other = np.array([[8.0, 3.0, 0.5, 11.0]])

    maxabs = Normalizer.fit(stats, "maxabs")
    assert maxabs.degenerate == (3,)
    np.testing.assert_allclose(maxabs.scale, [0.9 / 4, 0.9 / 2, 1.0, 1.0])
    np.testing.assert_allclose(maxabs.offset, 0.0)
    y = maxabs.apply(other)
    np.testing.assert_allclose(y, [[1.8, 0.9 * 3 / 2, 0.5, 11.0]], rtol=1e-6)  # not clipped
    assert count_out_of_range(y).tolist() == [1, 1, 0, 1]

    minmax = Normalizer.fit(stats, "minmax")
    assert minmax.degenerate == (3,)
    np.testing.assert_allclose(minmax.offset, [-0.5, 2.0, 0.0, 0.0])
    np.testing.assert_array_equal(minmax.apply(train, mask)[:, 1:3], 0.0)  # constant components map to 0.0
    np.testing.assert_allclose(minmax.apply(other), [[-0.9 + 1.8 * 12 / 7, 1.0, 0.5, 11.0]], rtol=1e-6)
    np.testing.assert_allclose(minmax.invert(minmax.apply(other)), other, rtol=1e-6)
    assert count_out_of_range(minmax.apply(other), np.array([[True, True, False, False]])).tolist() == [1, 1, 0, 0]


def test_masked_entries_stay_zero_and_bad_input_is_refused():
    stats = NormStats.from_arrays(np.array([[1.0, -2.0], [0.5, 4.0]]))
    norm = Normalizer.fit(stats)
    y = norm.apply(np.array([[1.0, 123.0]]), np.array([[True, False]]))
    assert y.tolist() == [[np.float32(0.9), 0.0]]
    with pytest.raises(ValueError, match=r"\[\.\.\., 2\]"):
        norm.apply(np.zeros((3, 5)))
    with pytest.raises(ValueError, match="unknown normalisation method"):
        Normalizer.fit(stats, "zscore")
