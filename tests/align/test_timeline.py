"""Resampling onto an exact grid: linear positions, slerp orientations, sign continuity, gaps."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from kinectdata.align.timeline import resample_motion
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import make_continuous, split_missing_and_normalise, wxyz_to_xyzw, xyzw_to_wxyz

NITE = load_joint_set("nite")


def _jittered_times(n=90, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 30.0 + rng.uniform(-0.004, 0.004, n)
    return t - t[0]


def _smooth_rotations(t):
    """A rotation turning about a slowly changing axis: [T] Rotation."""
    rotvec = np.stack([np.sin(1.3 * t), 0.8 * np.cos(0.7 * t), 1.5 * t], axis=-1)
    return Rotation.from_rotvec(rotvec)


def test_make_continuous_flips_only_signs_and_skips_masked():
    rng = np.random.default_rng(1)
    q = _smooth_rotations(np.linspace(0, 3, 60)).as_quat()
    flips = rng.choice([-1.0, 1.0], size=60)
    mask = rng.random(60) > 0.2
    out = make_continuous(q * flips[:, None], mask)
    np.testing.assert_allclose(np.abs(out), np.abs(q))
    valid = out[mask]
    assert (np.einsum("ij,ij->i", valid[1:], valid[:-1]) >= 0).all()
    assert np.allclose(out[mask][0], (q * flips[:, None])[mask][0])  # first valid keeps its sign


def test_component_orders_and_zero_quaternions():
    q = np.array([[0.1, 0.2, 0.3, 0.9], [0, 0, 0, 0], [0, 0, 0.6, 0.6]])
    assert np.allclose(wxyz_to_xyzw(xyzw_to_wxyz(q)), q)
    assert wxyz_to_xyzw(np.array([1.0, 2, 3, 4])).tolist() == [2, 3, 4, 1]
    unit, present, bad = split_missing_and_normalise(q)
    assert present.tolist() == [True, False, True]
    assert bad.tolist() == [False, False, True]  # norm 0.85
    assert np.isnan(unit[1]).all() and np.linalg.norm(unit[0]) == pytest.approx(1)


def test_positions_resample_linear_motion_exactly():
    t = _jittered_times()
    a, b = np.random.default_rng(2).normal(size=(2, 15, 3))
    m = Motion(t, a + b * t[:, None, None], NITE)
    grid = np.arange(0, t[-1], 1 / 30)
    r = resample_motion(m, grid)
    np.testing.assert_allclose(r.motion.positions, a + b * grid[:, None, None], atol=1e-12)
    assert r.motion.position_mask.all() and not r.position_interpolated.any() and r.gaps == []


def test_orientations_match_scipy_slerp_and_stay_continuous():
    t = _jittered_times(seed=3)
    rot = _smooth_rotations(t)
    flips = np.random.default_rng(4).choice([-1.0, 1.0], size=t.size)
    q = np.repeat((rot.as_quat() * flips[:, None])[:, None], 15, axis=1)
    m = Motion(t, np.zeros((t.size, 15, 3)), NITE, orientations=q)
    grid = np.arange(0, t[-1], 1 / 30)
    r = resample_motion(m, grid)
    expected = Slerp(t, rot)(grid)
    got = Rotation.from_quat(r.motion.orientations[:, 5])
    assert (got * expected.inv()).magnitude().max() < 1e-9
    out = r.motion.orientations[:, 5]
    assert (np.einsum("ij,ij->i", out[1:], out[:-1]) > 0).all()
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)


def test_short_gap_is_interpolated_and_flagged_long_gap_masked():
    t = np.arange(120) / 30.0
    pos = np.repeat(t[:, None, None], 15, axis=1) * np.array([1.0, 2.0, 3.0])
    mask = np.ones((120, 15), bool)
    mask[30:34, 2] = False  # 4 frames = 0.133 s without data
    mask[60:80, 3] = False  # 20 frames = 0.667 s
    m = Motion(t, pos, NITE, position_mask=mask)
    grid = np.arange(0, 3.9, 1 / 30) + 0.5 / 30  # between source frames
    r = resample_motion(m, grid, max_gap=0.2)
    inside_short = (grid > t[29]) & (grid < t[34])
    assert r.position_interpolated[inside_short, 2].all()
    assert r.motion.position_mask[inside_short, 2].all()
    np.testing.assert_allclose(r.motion.positions[inside_short, 2], grid[inside_short, None] * [1, 2, 3])
    inside_long = (grid > t[59]) & (grid < t[80])
    assert not r.motion.position_mask[inside_long, 3].any()
    assert np.isnan(r.motion.positions[inside_long, 3]).all()
    assert r.position_interpolated.sum() == inside_short.sum()
    long_gaps = [g for g in r.gaps if not g.filled]
    assert [(g.joint, round(g.length, 3)) for g in long_gaps] == [("RIGHT_SHOULDER", 0.667)]
    filled = [g for g in r.gaps if g.filled]
    assert [(g.joint, round(g.length, 3)) for g in filled] == [("LEFT_SHOULDER", 0.133)]


def test_max_gap_boundary_and_no_extrapolation():
    t = np.arange(60) / 30.0
    mask = np.ones((60, 15), bool)
    mask[10:16, 0] = False  # 6 missing frames = 0.2 s: filled at max_gap 0.2
    mask[:5, 1] = False  # joint 1 starts late, joint 2 ends early
    mask[50:, 2] = False
    m = Motion(t, np.ones((60, 15, 3)), NITE, position_mask=mask)
    grid = np.arange(0, t[-1] + 1e-9, 1 / 30)
    filled = resample_motion(m, grid, max_gap=0.2)
    assert filled.motion.position_mask[10:16, 0].all() and filled.position_interpolated[10:16, 0].all()
    masked = resample_motion(m, grid, max_gap=0.19)
    assert not masked.motion.position_mask[10:16, 0].any()
    assert not filled.motion.position_mask[:5, 1].any() and filled.motion.position_mask[5:, 1].all()
    assert not filled.motion.position_mask[50:, 2].any() and filled.motion.position_mask[:50, 2].all()


def test_dropped_frame_is_filled_and_flagged_for_every_joint():
    t = np.delete(np.arange(40) / 30.0, 20)
    m = Motion(t, np.zeros((39, 15, 3)), NITE)
    grid = np.arange(40) / 30.0
    r = resample_motion(m, grid)
    assert r.position_interpolated[20].all() and r.position_interpolated.sum() == 15
    assert r.motion.position_mask.all()


def test_gap_length_counts_missing_frames_whatever_the_jitter():
    rng = np.random.default_rng(7)
    t = np.arange(200) / 30.0 + rng.uniform(-0.006, 0.006, 200)
    mask = np.ones((200, 15), bool)
    mask[50:56, 0] = False  # 6 missing frames: 0.2 s, filled at max_gap 0.2 whatever the jitter
    mask[100:107, 1] = False  # 7 missing frames: 0.233 s, masked
    m = Motion(t, np.zeros((200, 15, 3)), NITE, position_mask=mask)
    r = resample_motion(m, np.arange(0.1, 6.5, 1 / 30), max_gap=0.2)
    gaps = {g.joint: g for g in r.gaps}
    assert gaps["HEAD"].length == pytest.approx(6 / 30, rel=0.02) and gaps["HEAD"].filled
    assert gaps["NECK"].length == pytest.approx(7 / 30, rel=0.02) and not gaps["NECK"].filled


def test_edge_gaps_are_marked_and_filled_values_are_at_most_inferred():
    t = np.arange(60) / 30.0
    mask = np.ones((60, 15), bool)
    mask[:3, 4] = False  # joint 4 appears late: an edge gap
    mask[20:23, 5] = False  # a short inner gap
    m = Motion(t, np.ones((60, 15, 3)), NITE, position_mask=mask)
    r = resample_motion(m, t, max_gap=0.2)
    edge = [g for g in r.gaps if g.joint == "LEFT_ELBOW"]
    assert len(edge) == 1 and edge[0].edge and not edge[0].filled
    assert edge[0].length == pytest.approx(3 / 30)
    assert (r.motion.confidence[20:23, 5] == 0.5).all() and (r.motion.confidence[10, 5] == 1.0)


def test_slerp_matches_scipy_including_nearly_equal_rotations():
    from kinectdata.core.quaternions import slerp

    rng = np.random.default_rng(5)
    q0 = Rotation.random(200, random_state=1).as_quat()
    q1 = (Rotation.from_rotvec(rng.normal(0, 1.0, (200, 3))) * Rotation.from_quat(q0)).as_quat()
    q1[:50] = (Rotation.from_rotvec(rng.normal(0, 1e-8, (50, 3))) * Rotation.from_quat(q0[:50])).as_quat()
    q1 *= np.sign(np.einsum("ij,ij->i", q0, q1))[:, None]  # same hemisphere, as after make_continuous
    w = rng.uniform(0, 1, 200)
    got = Rotation.from_quat(slerp(q0, q1, w))
    for i in range(200):
        ref = Slerp([0.0, 1.0], Rotation.from_quat([q0[i], q1[i]]))([w[i]])[0]
        assert (got[i] * ref.inv()).magnitude() < 1e-9


def test_average_quaternion_matches_scipy_mean_whatever_the_signs():
    from kinectdata.core.quaternions import average_quaternion, scatter

    rng = np.random.default_rng(4)
    centres = Rotation.random(3, random_state=4)
    q = np.stack([(c * Rotation.from_rotvec(rng.normal(0, 0.3, (40, 3)))).as_quat() for c in centres], axis=1)
    signs = rng.choice([-1.0, 1.0], size=(40, 3))
    mask = rng.random((40, 3)) > 0.2
    got = average_quaternion(scatter(q * signs[..., None], mask))
    for k in range(3):
        expected = Rotation.from_quat(q[mask[:, k], k]).mean().as_quat()
        assert abs(float(got[k] @ expected)) == pytest.approx(1.0, abs=1e-9)
        assert got[k][np.argmax(np.abs(got[k]))] > 0  # the documented sign
    np.testing.assert_array_equal(average_quaternion(np.zeros((1, 4, 4))), [[0.0, 0.0, 0.0, 1.0]])


def test_a_gap_lasts_its_missing_frames_at_the_fitted_rate_not_the_median_interval():
    """A 30.00 fps recorder stamping 33.0, 33.0, 34.0 ms in turn (median 33.0 ms) with a joint lost
    for 150 frames: the gap is 150 frames of 1/30 s = 5.000 s, not 151 or 152 of 33.0 ms."""
    k = np.arange(600)
    t = (k // 3) * 0.1 + np.array([0.0, 0.033, 0.066])[k % 3]
    mask = np.ones((600, 15), bool)
    mask[300:450, 4] = False
    m = Motion(t, np.zeros((600, 15, 3)), NITE, position_mask=mask)
    r = resample_motion(m, np.arange(0.0, 19.9, 1 / 30), max_gap=0.2)
    (gap,) = [g for g in r.gaps if g.joint == NITE.names[4]]
    assert gap.length == pytest.approx(5.0, abs=1e-3) and not gap.filled
    assert gap.start == pytest.approx(t[299]) and gap.end == pytest.approx(t[450])
