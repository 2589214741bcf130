"""The standing foot planted while the body travels (kinectdata.targets.foot_lock): a foot that
stands stays where it is, the swinging one follows the body, the legs keep their lengths (measured
here with numpy's norms and a determinant), the leg's reach bounds the lag, a stepping dancer's
standing foot stops sliding, and targets without legs are left as they are."""

from __future__ import annotations

import numpy as np
import pytest

from kinectdata.core.jointsets import load_joint_set
from kinectdata.targets.foot_lock import LEAD_S, SHIFT_S, legs_of
from kinectdata.targets.specs import TargetSpec, generic_target
from kinectdata.targets.travel import travel_targets

FPS = 30.0
SPEC = generic_target("positions", load_joint_set("tang2018"))
NAMES = list(SPEC.positions)


def _col(joint: str) -> slice:
    start = SPEC.columns(joint, "position").start
    return slice(start, start + 3)


def _pose(left_lift: float = 0.0, right_lift: float = 0.0) -> np.ndarray:
    """A standing dancer's root-centred target vector [D] (metres, y up), knees a little bent; each
    foot raised by its lift."""
    pose = np.zeros(SPEC.dim)
    for side, x, lift in (("left", 0.1, left_lift), ("right", -0.1, right_lift)):
        pose[_col(f"{side}_hip")] = (x, -0.05, 0.0)
        pose[_col(f"{side}_knee")] = (x, -0.48 + lift / 2, 0.15)
        pose[_col(f"{side}_ankle")] = (x, -0.9 + lift, 0.0)
        pose[_col(f"{side}_heel")] = (x, -0.95 + lift, -0.05)
        pose[_col(f"{side}_toe")] = (x, -0.95 + lift, 0.12)
    pose[_col("neck")] = (0.0, 0.5, 0.0)
    return pose


def _world(frames: np.ndarray, joint: str) -> np.ndarray:
    return frames[:, _col(joint)] + frames[:, _col("pelvis")]


def _forward(frames: int, metres: float) -> np.ndarray:
    return np.stack([np.zeros(frames), np.linspace(0.0, metres, frames)], axis=1)


def test_the_standing_foot_stays_and_the_swinging_one_follows_the_body():
    values = np.tile(_pose(right_lift=0.1), (60, 1))
    moved = travel_targets(values, SPEC, _forward(60, 0.2), FPS)
    standing = _world(moved, "left_ankle")
    assert np.abs(standing - standing[0]).max() < 1e-3  # within a millimetre while the body goes 20 cm
    assert np.abs(_world(moved, "left_toe") - _world(moved, "left_toe")[0]).max() < 1e-3
    # the swinging one goes with the body, ahead of where the frames put it by LEAD_S of the body's
    # travel once the velocity it follows has settled
    speed = 0.2 / 59 * FPS  # m/s
    ahead = _world(moved, "right_ankle") - moved[:, _col("pelvis")] - values[:, _col("right_ankle")]
    assert np.abs(ahead[:, :2]).max() < 1e-9 and (ahead[:, 2] <= LEAD_S * speed + 1e-9).all()
    assert ahead[-1, 2] == pytest.approx(LEAD_S * speed, abs=1e-5)
    assert np.allclose(moved[:, _col("pelvis")][:, [0, 2]], _forward(60, 0.2))


def test_feet_within_the_margin_do_not_share_the_weight():
    """Feet a centimetre and a half apart in height, the higher one changing every 5 frames, the body
    travelling 0.2 m in a second: the foot lower in the first frame keeps the weight throughout and
    stays where it is, the other follows the body. Read from the heights alone (a sigmoid over 1 cm,
    as the turning pivots), each foot would stand about half of each 5 frames and both would slide."""
    lift = np.where((np.arange(30) // 5) % 2 == 0, 0.015, -0.015)  # > 0: the right foot higher
    values = np.stack([_pose(left_lift=max(-a, 0.0), right_lift=max(a, 0.0)) for a in lift])
    moved = travel_targets(values, SPEC, _forward(30, 0.2), FPS)
    left = _world(moved, "left_ankle")
    assert np.abs(left[:, [0, 2]] - left[0, [0, 2]]).max() < 1e-9
    ahead = _world(moved, "right_ankle") - moved[:, _col("pelvis")] - values[:, _col("right_ankle")]
    speed = 0.2 / 29 * FPS  # m/s
    assert np.abs(ahead[:, :2]).max() < 1e-9 and (ahead[:, 2] <= LEAD_S * speed + 1e-9).all()  # with the body


def test_the_weight_goes_to_the_foot_lower_by_more_than_the_margin():
    """The right foot 3 cm up for a second, then the left: the left foot stands and then, once the
    weight has shifted (within SHIFT_S), the right one; each stays where it is while it stands."""
    lift = np.where(np.arange(60) < 30, 0.03, -0.03)
    values = np.stack([_pose(left_lift=max(-a, 0.0), right_lift=max(a, 0.0)) for a in lift])
    moved = travel_targets(values, SPEC, _forward(60, 0.3), FPS)
    left, right = (_world(moved, f"{s}_ankle")[:, [0, 2]] for s in ("left", "right"))
    shifted = 30 + int(np.ceil(SHIFT_S * FPS))
    assert np.abs(left[:30] - left[0]).max() < 1e-9
    assert np.abs(right[shifted:] - right[shifted]).max() < 1e-9
    assert np.linalg.norm(right[shifted] - right[0]) > 0.1  # it had followed the body before


def test_the_legs_keep_their_lengths_and_the_knee_its_plane():
    values = np.tile(_pose(right_lift=0.1), (60, 1))
    moved = travel_targets(values, SPEC, _forward(60, 0.2), FPS)
    for a, b in (("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("left_ankle", "left_toe")):
        before = np.linalg.norm(values[:, _col(a)] - values[:, _col(b)], axis=1)
        after = np.linalg.norm(moved[:, _col(a)] - moved[:, _col(b)], axis=1)
        assert after == pytest.approx(before, abs=1e-9)
    hip, knee, ankle = (moved[:, _col(j)] for j in ("left_hip", "left_knee", "left_ankle"))
    old_knee = values[:, _col("left_knee")]
    plane = np.linalg.det(np.stack([knee - hip, ankle - hip, old_knee - hip], axis=1))
    assert np.abs(plane).max() < 1e-12
    assert np.abs(ankle[-1] - values[-1, _col("left_ankle")]).max() > 0.1  # the foot did stay behind


def test_the_leg_reaches_no_further_than_its_bones():
    values = np.tile(_pose(right_lift=0.1), (90, 1))
    moved = travel_targets(values, SPEC, _forward(90, 1.5), FPS)
    for side in ("left", "right"):
        hip, knee, ankle = (moved[:, _col(f"{side}_{j}")] for j in ("hip", "knee", "ankle"))
        leg = np.linalg.norm(knee - hip, axis=1) + np.linalg.norm(ankle - knee, axis=1)
        assert (np.linalg.norm(ankle - hip, axis=1) <= leg + 1e-9).all()
    assert np.linalg.norm(_world(moved, "left_ankle")[-1] - _world(moved, "left_ankle")[0]) > 1.0


def test_a_dancer_who_never_lifts_a_foot_steps_at_the_legs_reach():
    """The right foot held 5 cm up for 10 s while the body travels 0.4 m/s: the left foot stands
    until its leg reaches no further, then the weight shifts to the right one over a few frames and
    the left catches up, in turn. Without the steps the left foot would slide with the body from its
    first reach on, and the slower foot would move at the body's speed."""
    frames = 300
    values = np.tile(_pose(right_lift=0.05), (frames, 1))
    moved = travel_targets(values, SPEC, _forward(frames, 4.0), FPS)
    along = [np.diff(_world(moved, f"{s}_ankle")[:, [0, 2]], axis=0) for s in ("left", "right")]
    speed = np.linalg.norm(np.stack(along), axis=-1) * FPS  # [2, T-1] m/s
    assert (speed.min(axis=0) < 0.05).mean() > 0.75  # a foot stands but while the weight shifts
    # m/s per frame: a foot sets off and stops over frames (tang2018's dancers' ankles change speed by
    # more than 0.74 m/s in a frame at 30 fps in 1 % of frames, by 0.044 in the median)
    assert np.abs(np.diff(speed, axis=1)).max() < 0.75
    fast = speed > 0.8  # a step's start: the swinging foot catching up
    steps = [int((np.diff(fast[k].astype(int)) == 1).sum()) for k in (0, 1)]
    assert min(steps) >= 4  # each foot steps again and again (about 0.3 m a step over 4 m)
    ends = [_world(moved, f"{s}_ankle")[-1, 2] - moved[-1, _col("pelvis").start + 2] for s in ("left", "right")]
    assert max(abs(e) for e in ends) < 0.5  # both feet kept up with the body


def test_a_stepping_dancers_standing_foot_stops_sliding():
    """Feet lifted in turn at 1 Hz, the body travelling 0.4 m/s: added to the root alone the travel
    slides the standing foot at 0.4 m/s; planted, it does not slide."""
    t = np.arange(300) / FPS
    lift = 0.06 * np.maximum(np.sin(2 * np.pi * t), 0.0)
    values = np.stack([_pose(left_lift=a, right_lift=b) for a, b in zip(lift, np.roll(lift, 15))])
    path = _forward(300, 0.4 * t[-1])
    rigid = values.copy()
    rigid[:, [_col("pelvis").start, _col("pelvis").start + 2]] += path
    moved = travel_targets(values, SPEC, path, FPS)
    for frames, slides in ((rigid, True), (moved, False)):
        left, right = (_world(frames, f"{s}_ankle") for s in ("left", "right"))
        speed = [np.linalg.norm(np.gradient(f[:, [0, 2]], axis=0), axis=1) * FPS for f in (left, right)]
        lower_right = np.where(right[:, 1] < left[:, 1] - 0.03, speed[1], np.nan)
        standing = np.where(left[:, 1] < right[:, 1] - 0.03, speed[0], lower_right)
        median = np.nanmedian(standing)
        assert (median > 0.35) if slides else (median < 0.02)
    ends = [_world(moved, f"{s}_ankle")[-1, 2] - moved[-1, _col("pelvis").start + 2] for s in ("left", "right")]
    assert max(abs(e) for e in ends) < 0.35  # the feet kept up with the body over 4 m


def test_targets_without_legs_travel_as_a_whole():
    no_knee = TargetSpec.from_dict({**SPEC.to_dict(), "positions": [n for n in NAMES if n != "left_knee"]})
    assert legs_of(no_knee) is None
    values = np.random.default_rng(3).normal(0, 0.3, (40, no_knee.dim))
    moved = travel_targets(values, no_knee, _forward(40, 0.3), FPS)
    root = no_knee.columns("pelvis", "position").start
    expected = values.copy()
    expected[:, [root, root + 2]] += _forward(40, 0.3)
    assert np.array_equal(moved, expected)


def test_kinect_feet_are_leaves_below_the_ankle():
    kinect = generic_target("positions", load_joint_set("kinect_v2"))
    left, right = legs_of(kinect)
    start = {j: kinect.columns(j, "position").start for j in ("HipLeft", "KneeLeft", "AnkleLeft", "FootLeft")}
    assert (left.hip[0], left.knee[0], left.ankle[0]) == (start["HipLeft"], start["KneeLeft"], start["AnkleLeft"])
    assert sorted(c[0] for c in left.foot) == sorted([start["AnkleLeft"], start["FootLeft"]])
    assert right.ankle[0] == kinect.columns("AnkleRight", "position").start
