"""The body's turning about the vertical (kinectdata.evaluation.metrics.turning), on generated
motion with known answers and against scipy's rotation fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.listening import TurningFigures, motion_energy_per_s
from kinectdata.evaluation.metrics.turning import Turning, turning, turning_rates

FPS = 30.0


def turning_body(yaw: np.ndarray, travel=(0.0, 0.0, 0.0), joints: int = 20, seed: int = 0) -> np.ndarray:
    """[T, J, 3] a rigid body (y up) turned by ``yaw`` [T] radians about its own vertical axis, its
    centre moving by ``travel`` metres per second."""
    body = np.random.default_rng(seed).normal(0.0, 0.3, (joints, 3))
    body -= body.mean(axis=0)
    turned = np.stack([Rotation.from_euler("y", -a).apply(body) for a in yaw])  # x towards z
    return turned + np.asarray(travel) * (np.arange(len(yaw)) / FPS)[:, None, None]


def test_a_rigid_turn_is_measured_at_scipys_angle_whatever_the_body_travels():
    t = np.arange(90) / FPS
    yaw = 1.5 * t + 0.8 * np.sin(2 * np.pi * 0.5 * t)
    positions = turning_body(yaw, travel=(0.5, 0.1, -0.3))
    rates = turning_rates(positions, FPS)
    centred = positions - positions.mean(axis=1, keepdims=True)
    for k in (0, 30, 87):  # scipy's least-squares rotation from frame k to frame k + 2
        fitted, _ = Rotation.align_vectors(centred[k + 2], centred[k])
        assert rates[k] == pytest.approx(-fitted.as_rotvec()[1] * FPS / 2, abs=1e-9)
    assert turning(positions, FPS).rate == pytest.approx(np.mean(np.abs(yaw[2:] - yaw[:-2])) * FPS / 2)


def test_a_turn_alone_is_all_of_the_energy_and_a_still_heading_none():
    t = np.arange(60) / FPS
    spun = turning(turning_body(2.0 * t), FPS)
    assert spun.energy == pytest.approx(motion_energy_per_s(turning_body(2.0 * t), None, FPS))
    assert spun.share == pytest.approx(1.0)
    # breathing and bobbing: every joint moves, out from the centre and up and down, with no turn
    body = turning_body(np.zeros(60))
    breathing = body * (1 + 0.2 * np.sin(2 * np.pi * t))[:, None, None] + [0, 0.1, 0] * np.sin(4 * t)[:, None, None]
    still = turning(breathing, FPS)
    assert still.rate == pytest.approx(0.0, abs=1e-12) and still.share == pytest.approx(0.0, abs=1e-12)
    assert still.energy > 0.01


def test_a_turns_energy_is_its_speed_squared_times_how_wide_the_body_is():
    """At a steady 2 rad/s, the turning's energy is the speed squared times the body's spread about
    the vertical (the chord of a frame pair's turn 0.2 % short of its arc), and the spread is the mean
    squared horizontal distance of the joints from the centre, however the body turned."""
    t = np.arange(60) / FPS
    positions = turning_body(2.0 * t)
    spun = turning(positions, FPS)
    centred = positions[:, :, [0, 2]] - positions[:, :, [0, 2]].mean(axis=1, keepdims=True)
    assert spun.spread == pytest.approx(float((centred**2).sum(axis=2).mean()), rel=1e-12)
    assert spun.turning_energy == pytest.approx(4.0 * spun.spread, rel=0.003)
    narrow = turning(positions * [0.5, 1.0, 0.5], FPS)  # arms in: half as wide, a quarter of the spread
    assert narrow.spread == pytest.approx(spun.spread / 4) and narrow.rate == pytest.approx(spun.rate)
    assert TurningFigures.of([spun], [narrow]).spread_ratio == pytest.approx(0.25)
    assert "the body 0.25 x as wide about the vertical" in TurningFigures.of([spun], [narrow]).verdict()


def test_a_joint_masked_or_missing_counts_as_if_it_were_not_there():
    t = np.arange(40) / FPS
    positions = turning_body(1.0 * t + 0.3 * np.sin(3 * t), joints=12)
    positions[:, 5] += np.random.default_rng(1).normal(0, 0.05, (40, 3))  # a joint that jitters on its own
    gappy = positions.copy()
    gappy[10:20, 3] = np.nan
    mask = np.ones(gappy.shape[:2], bool)
    mask[10:20, 3] = False
    whole = turning_rates(np.delete(positions, 3, axis=1), FPS)
    measured = turning_rates(gappy, FPS)
    free = np.ones(38, bool)
    free[8:20] = False  # the central differences that reach into the gap
    np.testing.assert_allclose(measured[~free], whole[~free], atol=1e-12)
    np.testing.assert_allclose(turning_rates(gappy, FPS, mask)[~free], whole[~free], atol=1e-12)


def test_motion_that_cannot_turn_is_one_clear_error():
    with pytest.raises(KinectDataError, match=r"positions \[T, J, 3\]"):
        turning(np.zeros((10, 4, 2)), FPS)
    with pytest.raises(KinectDataError, match="at least 3 frames"):
        turning(np.zeros((2, 4, 3)), FPS)
    with pytest.raises(KinectDataError, match="no joint is valid"):
        turning(np.full((5, 4, 3), np.nan), FPS)


def test_the_verdict_compares_the_turning_and_the_energy_left_without_it():
    real = [Turning(rate=2.0, energy=2.0, turning_energy=0.8), Turning(rate=1.8, energy=1.0, turning_energy=0.4)]
    made = [Turning(rate=0.2, energy=1.21, turning_energy=0.01), Turning(rate=0.2, energy=0.62, turning_energy=0.02)]
    figures = TurningFigures.of(real, made)
    assert figures.turning_ratio == pytest.approx((0.01 / 0.8 + 0.02 / 0.4) / 2)
    assert figures.energy_ratio_without_turning == pytest.approx((1.2 / 1.2 + 0.6 / 0.6) / 2)
    assert figures.real_share == pytest.approx(0.4) and not figures.turns
    assert figures.verdict().startswith("generated motion turns as the real motion does: no (")
    assert "the energy without the turning 1.00 x the real's" in figures.verdict()
    assert TurningFigures.of(real, real).turns
    flat = [Turning(rate=0.1, energy=1.0, turning_energy=0.01)]
    assert "not asked (the real motion hardly turns" in TurningFigures.of(flat, flat).verdict()


def test_the_travel_of_root_centred_targets_is_not_taken_for_a_turn():
    """Root-centred targets hold the root's travel where the other joints hold offsets from it:
    evaluate leaves that joint out of the turning, so a dancer crossing the floor does not turn."""
    from kinectdata.core.jointsets import load_joint_set
    from kinectdata.evaluation.evaluate import _travel_joint
    from kinectdata.evaluation.listening import HeldOutSong
    from kinectdata.targets.specs import generic_target

    spec = generic_target("positions", load_joint_set("tang2018"))
    root = spec.positions.index(spec.root)
    assert _travel_joint(spec, {"root_centre": True}) == root
    assert _travel_joint(spec, {"root_centre": False}) is None
    t = np.arange(60) / FPS
    body = turning_body(0.7 * t, joints=len(spec.positions) - 1)
    travel = np.stack([3.0 * t, np.zeros_like(t), 1.0 + 0.5 * t], axis=1)[:, None]  # metres from the start
    positions = np.concatenate([body[:, :root], travel, body[:, root:]], axis=1)
    song = HeldOutSong("W_1", np.zeros((60, 1)), np.zeros(3), positions, None, np.arange(5.0), FPS, travel_joint=root)
    assert song.body_turning(positions).rate == pytest.approx(0.7)
    assert song.body_turning(positions).share == pytest.approx(1.0)
    assert turning(positions, FPS).rate != pytest.approx(0.7, rel=0.1)  # with the travel in, it is no turn
