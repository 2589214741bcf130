"""The Motion container's invariants and the shipped joint sets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kinectdata.core.errors import SchemaError
from kinectdata.core.jointsets import find_joint_set, load_joint_set, shipped_joint_sets
from kinectdata.core.motion import Motion
from kinectdata.core.resources import schemas_dir

KINECT_V2_ORDER = [
    "SpineBase",
    "SpineMid",
    "Neck",
    "Head",
    "ShoulderLeft",
    "ElbowLeft",
    "WristLeft",
    "HandLeft",
    "ShoulderRight",
    "ElbowRight",
    "WristRight",
    "HandRight",
    "HipLeft",
    "KneeLeft",
    "AnkleLeft",
    "FootLeft",
    "HipRight",
    "KneeRight",
    "AnkleRight",
    "FootRight",
    "SpineShoulder",
    "HandTipLeft",
    "ThumbLeft",
    "HandTipRight",
    "ThumbRight",
]


def test_shipped_joint_sets_have_the_documented_sizes():
    sizes = {name: len(load_joint_set(name)) for name in shipped_joint_sets()}
    assert sizes == {
        "kinect_v2": 25, "nite": 15, "azure_kinect": 32, "openpose_mpi": 15, "smpl24": 24,
        "coco17_tree": 19, "smplh52": 52, "tang2018": 25,
    }  # fmt: skip
    assert load_joint_set("openpose_mpi").dimensions == 2


def test_kinect_v2_order_and_hierarchy():
    js = load_joint_set("kinect_v2")
    assert list(js.names) == KINECT_V2_ORDER  # JointType 0..24, from the SDK enumeration
    roots = [js.names[i] for i, p in enumerate(js.parents) if p < 0]
    assert roots == ["SpineBase"]
    assert js.names[js.parents[js.index("Neck")]] == "SpineShoulder"
    assert not js.has_orientation[js.index("Head")] and js.has_orientation[js.index("ElbowLeft")]
    assert len(js.bones()) == 24


def test_every_shipped_joint_set_is_a_tree_reaching_its_root():
    for name in shipped_joint_sets():
        js = load_joint_set(name)
        for j in range(len(js)):
            seen = 0
            while js.parents[j] >= 0:
                j = js.parents[j]
                seen += 1
                assert seen <= len(js)


def test_azure_alias_and_find_joint_set():
    az = load_joint_set("azure_kinect")
    assert az.index("SPINE_NAVAL") == az.index("SPINE_NAVEL") == 1
    assert find_joint_set(["HEAD", "NECK", "TORSO"]).name == "nite"
    assert find_joint_set(["SpineBase", "HandLeft"]).name == "kinect_v2"
    assert find_joint_set(["Nonsense"]) is None


def test_a_bad_joint_set_file_is_refused_with_its_path(tmp_path):
    doc = json.loads((schemas_dir() / "jointsets" / "nite.json").read_text())
    doc["joints"][0]["parent"] = "NOSE"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(SchemaError, match=r"bad\.json.*unknown parent 'NOSE'"):
        load_joint_set(bad)
    doc["joints"][0] = {"name": "HEAD"}
    bad.write_text(json.dumps(doc))
    with pytest.raises(SchemaError, match=r"bad\.json.*joints/0.*parent"):
        load_joint_set(bad)


def test_motion_masks_invalid_values_with_nan():
    js = load_joint_set("nite")
    pos = np.ones((3, 15, 3))
    mask = np.ones((3, 15), bool)
    mask[1, 2] = False
    m = Motion(np.array([0.0, 0.1, 0.2]), pos, js, position_mask=mask, orientations=np.tile([0, 0, 0, 1.0], (3, 15, 1)))
    assert np.isnan(m.positions[1, 2]).all() and not np.isnan(m.positions[0]).any()
    assert m.confidence[1, 2] == 0 and m.confidence[0, 0] == 1
    assert m.orientation_mask.all()
    assert m.duration == pytest.approx(0.2)


def test_motion_keeps_arrays_it_need_not_change_and_never_writes_into_the_callers():
    js = load_joint_set("nite")
    mask = np.ones((3, 15), bool)
    mask[1, 2] = False
    clean = np.ones((3, 15, 3))
    clean[1, 2] = np.nan
    kept = Motion(np.array([0.0, 0.1, 0.2]), clean, js, position_mask=mask)
    assert kept.positions is clean  # an hour-long recording is not copied for nothing
    dirty = np.ones((3, 15, 3))
    masked = Motion(np.array([0.0, 0.1, 0.2]), dirty, js, position_mask=mask)
    assert (dirty == 1).all()  # the caller's array is untouched
    assert np.isnan(masked.positions[1, 2]).all() and np.isnan(masked.positions).sum() == 3
    quats = np.tile([0, 0, 0, 1.0], (3, 15, 1))
    qmask = np.ones((3, 15), bool)
    qmask[0, 0] = False
    times = np.array([0.0, 0.1, 0.2])
    with_q = Motion(times, clean, js, position_mask=mask, orientations=quats, orientation_mask=qmask)
    assert (quats == np.tile([0, 0, 0, 1.0], (3, 15, 1))).all() and np.isnan(with_q.orientations[0, 0]).all()


def test_motion_rejects_bad_shapes_and_times():
    js = load_joint_set("nite")
    with pytest.raises(ValueError, match="positions"):
        Motion(np.zeros(3), np.zeros((3, 14, 3)), js)
    with pytest.raises(ValueError, match="increasing"):
        Motion(np.array([0.0, 0.2, 0.1]), np.zeros((3, 15, 3)), js)


def test_timing_counts_dropped_frames():
    js = load_joint_set("nite")
    t = np.arange(100) / 30.0
    t = np.delete(t, [10, 50, 51])  # one single drop and one double drop
    m = Motion(t, np.zeros((t.size, 15, 3)), js)
    timing = m.timing()
    assert timing["dropped_frames"] == 3
    assert timing["fps"] == pytest.approx(30.0)
    assert timing["jitter_ms"] == pytest.approx(0.0, abs=1e-6)


def test_the_frame_rate_is_the_timestamps_mean_rate_not_the_median_interval():
    """A recorder stamping 33.0, 33.0, 34.0 ms in turn runs at 1000 / 33.333 = 30.00 fps; the median
    interval (33.0 ms) says 30.30."""
    js = load_joint_set("nite")
    dt = np.tile([0.033, 0.033, 0.034], 100)
    t = np.concatenate([[0.0], np.cumsum(dt)])
    t = np.delete(t, [100, 200, 201])  # drops, counted and bridged
    m = Motion(t, np.random.default_rng(0).normal(size=(t.size, 15, 3)), js)
    timing = m.timing()
    expected = 1 / np.polyfit(np.delete(np.arange(301), [100, 200, 201]), t, 1)[0]  # the true frame numbers
    assert timing["fps"] == pytest.approx(expected, rel=1e-9) and timing["fps"] == pytest.approx(30.0, abs=0.01)
    assert timing["dropped_frames"] == 3 and timing["frozen_frames"] == 0


def test_frozen_frames_are_counted_over_valid_joints():
    js = load_joint_set("nite")
    p = np.random.default_rng(1).normal(size=(10, 15, 3))
    p[4] = p[3]
    p[5] = p[4]  # two frames repeat the one before
    p[8, :5] = p[7, :5]  # a partial repeat is motion, not a freeze
    mask = np.ones((10, 15), bool)
    mask[2, 0] = False
    p[2, 1:] = p[1, 1:]  # repeats every joint valid in both frames: frozen
    m = Motion(np.arange(10) / 30, p, js, position_mask=mask)
    assert m.frozen_frames() == 3


def _thirds_clock(n: int) -> np.ndarray:
    """Timestamps of a 30.00 fps recorder that stamps 33.0, 33.0 and 34.0 ms in turn: frame k at
    (k // 3) * 0.1 s plus 0, 33 or 66 ms. Median interval 33.0 ms, mean 33.33 ms."""
    k = np.arange(n)
    return (k // 3) * 0.1 + np.array([0.0, 0.033, 0.066])[k % 3]


def test_a_long_pause_counts_the_frames_it_lasted_even_when_the_median_is_off_the_mean():
    """150 frames missing in a row last 5.000 s: 151.5 median intervals (33.0 ms), so counting them
    by the median says 151 frames missing; the fitted interval (33.33 ms) says 150."""
    from kinectdata.core.motion import frame_clock

    t = _thirds_clock(600)
    kept = np.delete(np.arange(600), np.arange(300, 450))
    m = Motion(t[kept], np.random.default_rng(2).normal(size=(kept.size, 15, 3)), load_joint_set("nite"))
    timing = m.timing()
    assert timing["dropped_frames"] == 150
    assert timing["fps"] == pytest.approx(30.0, abs=0.01)
    interval, numbers = frame_clock(m.times)
    assert numbers.tolist() == kept.tolist()  # every frame's true number, the pause included
    assert interval == pytest.approx(0.1 / 3, rel=1e-3)


def test_frame_clock_needs_two_timestamps_and_keeps_precision_far_from_zero():
    from kinectdata.core.errors import ConfigError
    from kinectdata.core.motion import frame_clock

    with pytest.raises(ConfigError, match="at least two timestamps, got 1"):
        frame_clock(np.array([3.0]))
    unix = 1.7e9 + np.arange(100) / 30.0  # Unix seconds: a fit against raw values loses the slope's digits
    assert frame_clock(unix)[0] == pytest.approx(1 / 30, rel=1e-6)


def test_frozen_runs_give_where_each_stall_starts_and_how_long_it_holds():
    js = load_joint_set("nite")
    p = np.random.default_rng(3).normal(size=(20, 15, 3))
    p[5:9] = p[4]  # frames 5..8 hold frame 4's pose: a run of 4 at frame 5
    p[15] = p[14]  # a run of 1 at frame 15
    p[19] = p[18]  # a run of 1 at the last frame
    m = Motion(np.arange(20) / 30, p, js)
    assert m.frozen_runs() == [(5, 4), (15, 1), (19, 1)]
    assert m.frozen_frames() == 6 and m.timing()["frozen_frames"] == 6
    assert Motion(np.zeros(1), p[:1], js).frozen_runs() == []


def test_a_late_frame_beside_an_early_one_is_jitter_not_a_drop():
    """A recorder that stamps frames as they arrive (Lab Streaming Layer): at 30 fps, 40 frames
    come 52 ms after the one before and the next 14.7 ms after that (or early then late), and one
    frame is truly missing (66.7 ms, the next on time). The rate is the timestamps' 30.00 fps and
    one frame is dropped; counting each 52 ms interval as two frames said 40 more drops and ~30.6 fps."""
    rng = np.random.default_rng(3)
    t = np.arange(1200) / 30.0
    late = rng.choice(np.arange(10, 1180, 3), size=40, replace=False)
    for k in late[:20]:
        t[k] += 0.0187  # 52.0 ms after the frame before, 14.7 ms before the next
    for k in late[20:]:
        t[k] -= 0.0187  # early, then the next one late
    t = np.delete(t, 1190)  # one frame truly missing
    m = Motion(t, rng.normal(size=(t.size, 15, 3)), load_joint_set("nite"))
    timing = m.timing()
    assert timing["dropped_frames"] == 1
    assert timing["fps"] == pytest.approx(30.0, abs=0.005)
