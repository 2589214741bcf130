"""Cleaning (kinectdata.cleaning): the vectorised filters equal a frame-by-frame computation, the
zero-phase filter keeps the timing and cuts what it should, bones come out at one length along their
own directions, and on a synthetic dancer seen by a simulated Kinect the cleaned joints are closer to
the truth than the sensor's."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

import kinectdata as kd
from kinectdata.cleaning.bones import hold_bone_lengths
from kinectdata.cleaning.jitter import one_euro, zero_phase
from kinectdata.cleaning.recurrence import BLOCK, smooth
from kinectdata.core.errors import ConfigError


def _one_euro_by_frame(p, t, weight, min_cutoff, beta, d_cutoff):
    """The 1-euro filter sample by sample, as the authors' reference code runs it (the speed from the
    raw samples), on each joint's 3-D speed, each smoothing factor times the sample's weight."""
    T, J, _ = p.shape
    out = np.empty_like(p)

    def alpha(cutoff, dt):
        return 1.0 / (1.0 + 1.0 / (2 * np.pi * cutoff * dt))

    for j in range(J):
        est, speed_est, raw = None, 0.0, None
        for i in range(T):
            if est is None:
                est, raw = p[i, j].copy(), p[i, j]
            else:
                dt = t[i] - t[i - 1]
                speed_est += alpha(d_cutoff, dt) * (np.linalg.norm(p[i, j] - raw) / dt - speed_est)
                a = alpha(min_cutoff + beta * speed_est, dt) * weight[i, j]
                est = a * p[i, j] + (1 - a) * est
                raw = p[i, j]
            out[i, j] = est
    return out


def test_the_blockwise_recurrence_equals_the_loop_across_block_edges():
    rng = np.random.default_rng(0)
    T = 3 * BLOCK + 5
    a, x, y0 = rng.uniform(0, 1, (T, 4)), rng.normal(size=(T, 4)), rng.normal(size=4)
    expected, y = np.empty_like(x), y0.copy()
    for t in range(T):
        y = a[t] * x[t] + (1 - a[t]) * y
        expected[t] = y
    np.testing.assert_allclose(smooth(a, x, y0), expected, rtol=0, atol=1e-12)


def test_the_one_euro_filter_equals_the_reference_run_frame_by_frame():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.030, 0.037, 200))  # a jittered clock
    p = np.cumsum(rng.normal(0, 0.02, (200, 3, 3)), axis=0)
    weight = rng.choice([1.0, 0.5], size=(200, 3))
    weight[0] = 1.0
    for min_cutoff, beta, d_cutoff in ((1.0, 0.7, 1.0), (2.0, 50.0, 3.0)):
        got = one_euro(p, t, confidence=weight, min_cutoff_hz=min_cutoff, beta=beta, d_cutoff_hz=d_cutoff)
        expected = _one_euro_by_frame(p, t, weight, min_cutoff, beta, d_cutoff)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_the_one_euro_filter_holds_through_a_gap_and_keeps_it_masked():
    t = np.arange(60) / 30.0
    p = np.zeros((60, 1, 3))
    p[:, 0, 0] = np.where(t < 1.0, 0.0, 1.0)
    mask = np.ones((60, 1), bool)
    mask[25:35] = False
    out = one_euro(p, t, mask)
    assert np.isnan(out[25:35]).all() and np.isfinite(out[mask]).all()
    np.testing.assert_allclose(out[:25, 0, 0], 0.0)  # nothing moved before the gap
    assert 0.0 < out[35, 0, 0] < 1.0  # the step after the gap is followed, smoothed


def test_the_zero_phase_filter_passes_slow_motion_in_time_and_cuts_jitter():
    fps = 30.0
    t = np.arange(600) / fps
    slow = 0.2 * np.sin(2 * np.pi * 0.5 * t)  # half a hertz: a dancer's sway
    fast = 0.01 * np.sin(2 * np.pi * 12.0 * t)  # 12 Hz: sensor jitter
    p = np.zeros((600, 1, 3))
    p[:, 0, 1] = slow + fast
    for method in ("butterworth", "savgol"):
        out = zero_phase(p, fps, method=method, cutoff_hz=4.0)[:, 0, 1]
        inner = slice(60, -60)
        assert np.abs(out[inner] - slow[inner]).max() < 0.1 * 0.01 + 0.002  # jitter down to a tenth and less
        lag = np.argmax(np.correlate(out[inner], slow[inner], "full")) - (len(slow[inner]) - 1)
        assert lag == 0, method


def test_the_zero_phase_filter_reads_each_sample_at_its_own_time():
    # a 2-Hz swing sampled by a sensor whose frames are stamped up to 8 ms off a 30-fps grid, with
    # frames 100, 200 and 300 dropped: taken as an even grid the swing is bent (centimetres about
    # each drop, the jitter's millimetres everywhere); on the frame grid it is followed
    rng = np.random.default_rng(0)
    grid = np.arange(400) / 30.0
    t = np.delete(grid + rng.uniform(-0.008, 0.008, grid.size), [100, 200, 300])
    t[0] = 0.0
    truth = 0.3 * np.sin(2 * np.pi * 2.0 * t)  # metres; its speed up to 3.8 m/s
    p = np.zeros((t.size, 1, 3))
    p[:, 0, 0] = truth
    inner = slice(30, -30)
    plain = zero_phase(p, 30.0, cutoff_hz=6.0)[:, 0, 0]
    timed = zero_phase(p, 30.0, cutoff_hz=6.0, times=t)[:, 0, 0]
    assert np.abs(plain - truth)[inner].max() > 0.03  # about a drop: 4 cm off
    assert np.abs(timed - truth)[inner].max() < 0.006  # the 6-Hz filter's own gain at 2 Hz: 1.2 %
    assert np.abs(timed - truth)[inner].mean() < 0.25 * np.abs(plain - truth)[inner].mean()


@pytest.mark.parametrize("dropped", [[1], [298], [1, 2], [150]])
@pytest.mark.parametrize("method", ["butterworth", "savgol"])
def test_a_frame_dropped_near_an_edge_is_left_to_the_filter(dropped, method):
    # without two samples on each side a dropped frame is not filled; it must not spoil the rest
    t = np.delete(np.arange(300) / 30.0, dropped)
    p = np.zeros((t.size, 2, 3))
    p[:, 0, 0] = 0.1 * np.sin(2 * np.pi * 0.5 * t)
    out = zero_phase(p, 30.0, method=method, times=t)
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out[10:-10, 0, 0], p[10:-10, 0, 0], atol=0.003)


def test_a_low_confidence_sample_counts_less_in_the_zero_phase_filter():
    p = np.zeros((90, 1, 3))
    p[45, 0, 0] = 0.5  # a spike
    full = zero_phase(p, 30.0)[45, 0, 0]
    weight = np.ones((90, 1))
    weight[45] = 0.1
    assert abs(zero_phase(p, 30.0, confidence=weight)[45, 0, 0]) < 0.2 * abs(full)


def test_bones_come_out_at_their_median_length_along_their_own_directions():
    js = kd.load_joint_set("kinect_v2")
    rng = np.random.default_rng(2)
    p = rng.normal(0, 0.3, (50, len(js), 3))
    mask = np.ones((50, len(js)), bool)
    mask[10, 5] = False
    out, held = hold_bone_lengths(p, js.parents, mask, spread=False)
    for j, parent in enumerate(js.parents):
        if parent < 0:
            continue
        both = mask[:, j] & mask[:, parent]
        bone, rebuilt = p[both, j] - p[both, parent], out[both, j] - out[both, parent]
        np.testing.assert_allclose(np.linalg.norm(rebuilt, axis=1), np.median(np.linalg.norm(bone, axis=1)))
        cosine = np.sum(bone * rebuilt, axis=1) / np.linalg.norm(bone, axis=1) / np.linalg.norm(rebuilt, axis=1)
        np.testing.assert_allclose(cosine, 1.0, atol=1e-12)
    assert np.isnan(out[10, 5]).all()


def test_a_simulated_kinect_dancer_comes_out_closer_to_the_truth():
    """The synthetic dancer at 30 fps seen through the simulated sensor (position noise 3 mm, inferred
    hands 10 mm with a drifting bias, a foot lost): the zero-phase filter brings the joints nearer the
    true motion, the causal one a little (it lags a fast dancer), and the bones stage makes every
    bone one length and brings the joints nearer still (each bone's error shared by its ends); rebuilt
    from the root alone, it carries each direction's noise down the chain and costs a millimetre."""
    from kinectdata.synth.dancer import dance
    from kinectdata.synth.sensor import SensorModel, apply_sensor_defects

    times = np.arange(0, 20, 1 / 30)
    beats = np.arange(2.0, 20.0, 0.5)
    truth = dance(seed=3, times_s=times, beat_times_s=beats, music_start_s=2.0, clap_time_s=None, tempo_bpm=120)
    noisy = apply_sensor_defects(truth, seed=3, model=SensorModel()).motion
    ok = noisy.position_mask

    def error(m):
        return float(np.linalg.norm(m.positions - truth.positions, axis=-1)[ok].mean())

    offline = kd.clean_motion(noisy, kd.CleanConfig(bones=False)).motion
    assert error(offline) < 0.7 * error(noisy)
    causal = kd.clean_motion(noisy, kd.CleanConfig(jitter="one_euro", bones=False)).motion
    assert error(causal) < error(noisy)
    both = kd.clean_motion(noisy)
    assert both.report.bone_cv_after < 1e-9 < both.report.bone_cv_before
    assert both.report.jerk_after < 0.5 * both.report.jerk_before
    assert error(both.motion) < 0.9 * error(offline)
    chain, _ = hold_bone_lengths(offline.positions, truth.joint_set.parents, offline.position_mask, spread=False)
    assert error(both.motion) + 0.0005 < float(np.linalg.norm(chain - truth.positions, axis=-1)[ok].mean())
    fixed = kd.clean_motion(noisy, kd.CleanConfig(jitter="butterworth")).motion  # one cutoff for the whole dance
    assert error(both.motion) < 0.92 * error(fixed)


def test_clean_on_the_command_line_reports_and_writes_any_format(tmp_path):
    out = tmp_path / "clean.npz"
    run = subprocess.run(
        [sys.executable, "-m", "kinectdata", "clean", str(REPO / "sample_data" / "synth_001.csv"), "-o", str(out),
         "--jitter", "butterworth", "--report", str(tmp_path / "report.json")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "bone-length CV" in run.stdout and "mean jerk" in run.stdout and f"wrote {out}" in run.stdout
    back = kd.read_motion(out, schema=tmp_path / "clean.schema.json")
    source = kd.read_motion(REPO / "sample_data" / "synth_001.csv")
    np.testing.assert_array_equal(back.position_mask, source.position_mask)
    np.testing.assert_allclose(back.times, source.times)
    assert (tmp_path / "report.json").exists()


def test_what_cleaning_cannot_do_is_one_line():
    mpi = kd.load_joint_set("openpose_mpi")
    flat = kd.Motion(times=np.arange(5) / 30.0, positions=np.zeros((5, len(mpi), 2)), joint_set=mpi)
    with pytest.raises(ConfigError, match="cleaning needs 3-D joints"):
        kd.clean_motion(flat)
    with pytest.raises(ConfigError, match="jitter filter 'median' is not one of"):
        kd.CleanConfig(jitter="median")


def test_short_gaps_are_filled_long_ones_left_and_inferred_jumps_taken_out():
    """A joint moving in a straight line at constant speed: a 3-frame gap comes back exactly (filled
    linearly, confidence 0.5), a 1-second gap stays masked and is named, an inferred sample 30 cm
    off the line is taken out and filled, and one 2 cm off (an inferred joint's usual bias) is kept."""
    from kinectdata.cleaning.gaps import fill_gaps

    js = kd.load_joint_set("kinect_v2")
    t = np.arange(120) / 30.0
    p = np.zeros((120, len(js), 3))
    p[:, :, 0] = 0.5 * t[:, None]  # every joint at 0.5 m/s along x
    mask = np.ones((120, len(js)), bool)
    confidence = np.ones((120, len(js)))
    hand = js.index("HandLeft")
    mask[10:13, hand] = False  # 0.1 s
    mask[50:80, hand] = False  # 1 s
    far, near = 30, 95
    p[far, hand, 1] += 0.30
    p[near, hand, 1] += 0.02
    confidence[[far, near], hand] = 0.5
    motion = kd.Motion(times=t, positions=p, joint_set=js, position_mask=mask, confidence=confidence)
    filled, report = fill_gaps(motion, max_gap_s=0.2, jump_m=0.1)
    truth = 0.5 * t
    np.testing.assert_allclose(filled.positions[10:13, hand, 0], truth[10:13], atol=1e-12)
    np.testing.assert_allclose(filled.positions[far, hand], [truth[far], 0.0, 0.0], atol=1e-12)
    assert filled.confidence[11, hand] == pytest.approx(0.5) and filled.positions[near, hand, 1] == pytest.approx(0.02)
    assert not filled.position_mask[50:80, hand].any()
    assert (report.jumps_replaced, report.gaps_filled, report.samples_filled) == (1, 2, 4)
    assert report.gaps_left == 1 and report.joints_left == ("HandLeft",)
    assert report.longest_left_s == pytest.approx(1.0, abs=0.04)
    unchanged = np.ones_like(mask)
    unchanged[[10, 11, 12, far], hand] = False
    unchanged[50:80, hand] = False
    np.testing.assert_array_equal(filled.positions[unchanged], p[unchanged])  # valid samples as they were
