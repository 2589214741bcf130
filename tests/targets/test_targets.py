"""Target specs and target extraction, checked on hand-built motions with known values."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import YALTA_ORIENTATIONS, YALTA_POSITIONS

from kinectdata.core.errors import KinectDataError, SchemaError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.targets.specs import TargetSpec, extract_targets, load_target_spec, shipped_target_specs


def z_rotation(angle: np.ndarray) -> np.ndarray:
    """[..., 4] (x, y, z, w) quaternions of rotations by angle (radians) about z."""
    angle = np.asarray(angle, dtype=float)
    zero = np.zeros_like(angle)
    return np.stack([zero, zero, np.sin(angle / 2), np.cos(angle / 2)], axis=-1)


def known_motion(joint_set: str, T: int = 5, fps: float = 30.0) -> Motion:
    """Position of joint j at frame t: (j, t, 100 + j) cm; orientation: rotation about z by
    0.01 * (j + 1) * (t + 1) rad (w > 0)."""
    js = load_joint_set(joint_set)
    J = len(js)
    t = np.arange(T)[:, None]
    j = np.arange(J)[None, :]
    pos = np.stack(np.broadcast_arrays(j * 0.01, t * 0.01, 1.0 + j * 0.01), axis=-1).astype(float)
    q = z_rotation(0.01 * (j + 1) * (t + 1))
    return Motion(np.arange(T) / fps, pos, js, orientations=q, metadata={"format": "test"})


def write_spec(tmp_path, doc, name="spec.json"):
    path = tmp_path / name
    path.write_text(json.dumps(doc) if isinstance(doc, dict) else doc, encoding="utf-8")
    return path


# -- specs -------------------------------------------------------------------------------------


def test_shipped_specs_and_dims():
    dims = {name: load_target_spec(name).dim for name in shipped_target_specs()}
    # azure: every joint but the 5 face points (NOSE, EYE_LEFT/RIGHT, EAR_LEFT/RIGHT) has an orientation
    assert dims == {
        "yalta65": 65,
        "kinect_v2_full": 147,
        "kinect_v2_positions": 75,
        "nite_full": 15 * 3 + 11 * 4,
        "azure_kinect_full": 204,
        "listen_to_dance": 15 * 2 + 14,
    }
    for name in shipped_target_specs():
        spec = load_target_spec(name)
        assert len(spec.component_names()) == spec.dim == len(set(spec.component_names()))
        assert spec.description


def test_yalta65_joints_and_component_names():
    spec = load_target_spec("yalta65")
    assert list(spec.positions) == YALTA_POSITIONS and list(spec.orientations) == YALTA_ORIENTATIONS
    assert spec.joint_set == "kinect_v2" and spec.root == "SpineBase"
    names = spec.component_names()
    assert names[:4] == ["SpineBase.x", "SpineBase.y", "SpineBase.z", "HandLeft.x"]
    assert names[9:14] == ["SpineBase.qx", "SpineBase.qy", "SpineBase.qz", "SpineBase.qw", "SpineMid.qx"]
    assert names[-1] == "KneeRight.qw"
    assert spec.position_slice == slice(0, 9) and spec.orientation_slice == slice(9, 65)
    assert spec.quaternion_slices[1] == slice(13, 17) and spec.columns("ElbowLeft", "orientation") == slice(29, 33)
    assert spec.columns("HandRight") == slice(6, 9)


def test_kinect_v2_full_lists_every_joint_that_can_carry_an_orientation():
    spec = load_target_spec("kinect_v2_full")
    js = load_joint_set("kinect_v2")
    assert spec.positions == js.names
    assert set(spec.orientations) == {n for n, h in zip(js.names, js.has_orientation) if h}
    nite = load_target_spec("nite_full")
    assert not {"LEFT_HAND", "RIGHT_HAND", "LEFT_FOOT", "RIGHT_FOOT"} & set(nite.orientations)


@pytest.mark.parametrize("name", ["yalta65", "kinect_v2_full", "nite_full", "azure_kinect_full"])
def test_to_dict_round_trip(name):
    spec = load_target_spec(name)
    doc = json.loads(json.dumps(spec.to_dict()))
    again = TargetSpec.from_dict(doc)
    assert again == spec and again.to_dict() == spec.to_dict()


def test_spec_file_defaults_root_and_accepts_aliases(tmp_path):
    path = write_spec(
        tmp_path,
        {"name": "t", "joint_set": "azure_kinect", "positions": ["SPINE_NAVAL"], "orientations": ["PELVIS"]},
    )
    spec = load_target_spec(path)
    assert spec.positions == ("SPINE_NAVEL",) and spec.root == "PELVIS" and spec.dim == 7
    assert load_target_spec(spec) is spec


@pytest.mark.parametrize(
    "change, words",
    [
        ({"positions": ["SpineBase", "Tail"]}, ["positions", "'Tail'"]),
        ({"orientations": ["Head"]}, ["orientations", "'Head'", "no orientation"]),
        ({"orientations": ["ElbowLeft", "HandTipRight"]}, ["'HandTipRight'"]),
        ({"positions": ["HandLeft", "HandRight", "HandLeft"]}, ["positions", "'HandLeft'", "twice"]),
        ({"joint_set": "kinect_v3"}, ["joint_set", "kinect_v3"]),
        ({"joint_set": "nite"}, ["positions", "'SpineBase'"]),
        ({"joint_set": "openpose_mpi", "positions": ["Head"], "orientations": ["Head"]}, ["orientations", "'Head'"]),
        (
            {"joint_set": "openpose_mpi", "positions": ["Chest"], "orientations": [], "limbs": ["Chest"]},
            ["limbs", "root"],
        ),
        ({"position_scale": "per_frame"}, ["position_scale"]),
        ({"root": "Tail"}, ["root", "'Tail'"]),
        ({"positions": [], "orientations": []}, ["empty"]),
        ({"extra": 1}, ["extra"]),
        ({"positions": "SpineBase"}, ["positions"]),
    ],
)
def test_bad_spec_files_name_the_file_and_field(tmp_path, change, words):
    doc = {"name": "bad", "joint_set": "kinect_v2", "positions": ["SpineBase"], "orientations": ["SpineBase"]}
    doc.update(change)
    path = write_spec(tmp_path, doc)
    with pytest.raises(SchemaError) as err:
        load_target_spec(path)
    assert str(path) in str(err.value)
    for w in words:
        assert w in str(err.value)


def test_missing_field_and_not_json(tmp_path):
    path = write_spec(tmp_path, {"name": "x", "joint_set": "kinect_v2", "positions": ["SpineBase"]})
    with pytest.raises(SchemaError, match="orientations"):
        load_target_spec(path)
    path = write_spec(tmp_path, '{"name": "x",', name="broken.json")
    with pytest.raises(SchemaError, match="invalid JSON") as err:
        load_target_spec(path)
    assert str(path) in str(err.value)
    with pytest.raises(SchemaError, match="yalta65"):
        load_target_spec("no_such_spec")
    with pytest.raises(SchemaError, match="not found"):
        load_target_spec(tmp_path / "missing.json")


# -- extraction --------------------------------------------------------------------------------


def test_yalta65_components_land_at_the_documented_indices():
    m = known_motion("kinect_v2")
    values, mask = extract_targets(m, load_target_spec("yalta65"))
    assert values.shape == mask.shape == (5, 65) and values.dtype == np.float64 and mask.all()
    t = np.arange(5)
    # Kinect v2 JointType: SpineBase 0, HandLeft 7, HandRight 11
    for col, j in ((0, 0), (3, 7), (6, 11)):
        np.testing.assert_allclose(values[:, col], j * 0.01)
        np.testing.assert_allclose(values[:, col + 1], t * 0.01)
        np.testing.assert_allclose(values[:, col + 2], 1.0 + j * 0.01)
    jointtype = [0, 1, 20, 2, 4, 5, 6, 8, 9, 10, 12, 13, 16, 17]  # YALTA_ORIENTATIONS as JointType
    for k, j in enumerate(jointtype):
        angle = 0.01 * (j + 1) * (t + 1)
        np.testing.assert_allclose(values[:, 9 + 4 * k : 13 + 4 * k], z_rotation(angle), atol=1e-12)


def test_nite_and_azure_layouts():
    values, _ = extract_targets(known_motion("nite"), load_target_spec("nite_full"))
    assert values.shape == (5, 89)
    np.testing.assert_allclose(values[:, 24], 0.08)  # TORSO (joint 8) is the 9th position: column 24
    np.testing.assert_allclose(values[:, 45:49], z_rotation(0.01 * np.arange(1, 6)), atol=1e-12)  # HEAD (0)
    np.testing.assert_allclose(values[:, 53:57], z_rotation(0.09 * np.arange(1, 6)), atol=1e-12)  # TORSO
    values, _ = extract_targets(known_motion("azure_kinect"), load_target_spec("azure_kinect_full"))
    assert values.shape == (5, 204)
    np.testing.assert_allclose(values[:, 3 * 26], 0.26)  # HEAD is joint 26
    np.testing.assert_allclose(values[:, 96 + 4 * 26 : 96 + 4 * 27], z_rotation(0.27 * np.arange(1, 6)), atol=1e-12)


def test_masks_follow_position_and_orientation_masks():
    m = known_motion("kinect_v2")
    pmask, omask = np.ones((5, 25), bool), np.ones((5, 25), bool)
    pmask[1, 7] = False  # HandLeft position, frame 1
    omask[2, 5] = False  # ElbowLeft orientation, frame 2
    m = Motion(m.times, m.positions, m.joint_set, pmask, orientations=m.orientations, orientation_mask=omask)
    values, mask = extract_targets(m, load_target_spec("yalta65"))
    expected = np.ones((5, 65), bool)
    expected[1, 3:6] = False
    expected[2, 29:33] = False  # ElbowLeft is the 6th orientation: 9 + 4 * 5
    np.testing.assert_array_equal(mask, expected)
    assert np.all(values[~mask] == 0.0) and np.isfinite(values).all()


def test_quaternions_are_made_continuous_keeping_the_first_sign():
    T = 8
    m = known_motion("kinect_v2", T=T)
    angle = np.linspace(0.1, 0.8, T)
    truth = z_rotation(angle)
    stored = -truth  # starts with w < 0: kept (the dataset build chooses hemispheres across recordings)
    stored[3] *= -1  # and a sign jump in the middle
    stored[5:] *= -1
    q = m.orientations.copy()
    q[:, 1] = stored  # SpineMid
    q[:, 0] = truth  # SpineBase: already fine, must be untouched
    omask = np.ones((T, 25), bool)
    omask[0, 20] = False  # SpineShoulder: first valid frame is 1, where w < 0
    q[:, 20] = -truth
    q[4, 20] = truth[4]
    m = Motion(m.times, m.positions, m.joint_set, orientations=q, orientation_mask=omask)
    values, mask = extract_targets(m, load_target_spec("yalta65"))
    np.testing.assert_allclose(values[:, 9:13], truth, atol=1e-12)
    np.testing.assert_allclose(values[:, 13:17], -truth, atol=1e-12)
    np.testing.assert_allclose(values[1:, 17:21], -truth[1:], atol=1e-12)
    assert not mask[0, 17:21].any() and np.all(values[0, 17:21] == 0.0)


def test_root_centring_by_hand():
    T = 40
    js = load_joint_set("kinect_v2")
    pos = np.zeros((T, 25, 3))
    pos[:, 0] = np.stack([0.01 * np.arange(T), np.ones(T), 2 * np.ones(T)], axis=1)  # SpineBase walks along x
    pos[:, 7] = [0.5, 1.5, 2.0]  # HandLeft still
    pos[:, 11] = [-0.5, 1.5, 2.5]  # HandRight still
    pmask = np.ones((T, 25), bool)
    pmask[[0, 5], 0] = False  # root lost at frames 0 and 5
    m = Motion(np.arange(T) / 30.0, pos, js, pmask)
    spec = TargetSpec("p", "kinect_v2", ("SpineBase", "HandLeft", "HandRight"), (), root="SpineBase")
    values, mask = extract_targets(m, spec, root_centre=True)
    t = np.arange(T)
    ok = ~np.isin(t, [0, 5])
    np.testing.assert_array_equal(mask, np.repeat(ok[:, None], 9, axis=1))
    # fps 30: the root's start is its mean over its first 30 valid frames, 1..4 and 6..31
    start_x = 0.01 * (10 + 481) / 30
    np.testing.assert_allclose(values[ok, 0], 0.01 * t[ok] - start_x, atol=1e-12)
    np.testing.assert_allclose(values[ok, 1:3], 0.0, atol=1e-12)
    np.testing.assert_allclose(values[ok, 3], 0.5 - 0.01 * t[ok], atol=1e-12)
    np.testing.assert_allclose(values[ok, 4:6], [[0.5, 0.0]] * ok.sum(), atol=1e-12)
    np.testing.assert_allclose(values[ok, 6:9], np.c_[-0.5 - 0.01 * t[ok], [[0.5, 0.5]] * ok.sum()], atol=1e-12)
    assert np.all(values[~ok] == 0.0)

    # at 15 fps the first second is 15 valid frames: 1..4 and 6..16
    m15 = Motion(np.arange(T) / 15.0, pos, js, pmask)
    values15, _ = extract_targets(m15, spec, root_centre=True)
    np.testing.assert_allclose(values15[ok, 0], 0.01 * t[ok] - 0.01 * (10 + 121) / 15, atol=1e-12)
    # without centring, the raw positions
    raw, _ = extract_targets(m, spec)
    np.testing.assert_allclose(raw[ok, 0], 0.01 * t[ok])


def test_root_centring_a_root_not_listed_and_no_root():
    m = known_motion("kinect_v2")
    spec = TargetSpec("h", "kinect_v2", ("HandLeft",), (), root="SpineBase")
    values, _ = extract_targets(m, spec, root_centre=True)
    np.testing.assert_allclose(values, [[0.07, 0.0, 0.07]] * 5, atol=1e-12)
    with pytest.raises(KinectDataError, match="no root"):
        extract_targets(m, TargetSpec("h", "kinect_v2", ("HandLeft",), ()), root_centre=True)


def test_wrong_joint_set_and_missing_orientations_are_refused():
    with pytest.raises(KinectDataError, match="kinect_v2.*nite"):
        extract_targets(known_motion("nite"), load_target_spec("yalta65"))
    m = known_motion("kinect_v2")
    no_q = Motion(m.times, m.positions, m.joint_set, metadata={"format": "csv", "schema": "kinectreader"})
    with pytest.raises(KinectDataError) as err:
        extract_targets(no_q, load_target_spec("yalta65"))
    assert "kinectreader" in str(err.value) and "positions-only" in str(err.value)
    positions_only = TargetSpec("p", "kinect_v2", ("HandLeft",), ())
    values, mask = extract_targets(no_q, positions_only)
    assert values.shape == (5, 3) and mask.all()


def test_listen_to_dance_target_scales_each_axis_per_recording_and_adds_limb_lengths():
    """30 coordinates min-max scaled per axis over the recording, then 14 limb lengths in those
    units, computed here joint by joint from the joint set's parent links."""
    js = load_joint_set("openpose_mpi")
    spec = load_target_spec("listen_to_dance")
    rng = np.random.default_rng(3)
    T = 40
    pos = rng.uniform([100, 50], [1800, 1000], (T, 15, 2))
    mask = rng.random((T, 15)) > 0.1
    motion = Motion(np.arange(T) / 30, np.where(mask[..., None], pos, np.nan), js, position_mask=mask)
    values, vmask = extract_targets(motion, spec)
    assert values.shape == (T, 44) and spec.component_names()[:2] == ["Head.x", "Head.y"]
    assert spec.component_names()[30] == "Head-Neck.length"
    lo = [pos[..., a][mask].min() for a in range(2)]
    hi = [pos[..., a][mask].max() for a in range(2)]
    for j, name in enumerate(js.names):
        for a in range(2):
            col = 2 * spec.positions.index(name) + a
            expected = (pos[:, j, a] - lo[a]) / (hi[a] - lo[a])
            np.testing.assert_allclose(values[mask[:, j], col], expected[mask[:, j]], atol=1e-12)
            assert not vmask[~mask[:, j], col].any()
    for k, name in enumerate(spec.limbs):
        j, p = js.index(name), js.parents[js.index(name)]
        ok = mask[:, j] & mask[:, p]
        d = [(pos[:, j, a] - pos[:, p, a]) / (hi[a] - lo[a]) for a in range(2)]
        np.testing.assert_allclose(values[ok, 30 + k], np.hypot(*d)[ok], atol=1e-12)
        np.testing.assert_array_equal(vmask[:, 30 + k], ok)
    valid = values[:, :30][vmask[:, :30]]
    assert valid.min() == 0.0 and valid.max() == 1.0


def test_limbs_need_their_joints_listed_as_positions(tmp_path):
    path = tmp_path / "spec.json"
    doc = {"name": "x", "joint_set": "openpose_mpi", "positions": ["Head"], "orientations": [], "limbs": ["Head"]}
    path.write_text(json.dumps(doc))
    with pytest.raises(SchemaError, match=r"spec.json: limbs: the limb Head-Neck needs 'Neck' under positions"):
        load_target_spec(path)


def test_limb_lengths_are_true_lengths_when_root_centred():
    """Root-centring moves the root into its own frame of reference; the limbs to it keep their length."""
    js = load_joint_set("openpose_mpi")
    rng = np.random.default_rng(5)
    pos = rng.uniform(0, 500, (20, 15, 2))
    motion = Motion(np.arange(20) / 30, pos, js)
    spec = load_target_spec("listen_to_dance")
    plain, _ = extract_targets(motion, spec)
    centred, _ = extract_targets(motion, spec, root_centre=True)
    span_plain = pos.reshape(-1, 2).max(0) - pos.reshape(-1, 2).min(0)
    chest, rhip = js.index("Chest"), js.index("RHip")
    k = spec.limbs.index("RHip")
    np.testing.assert_allclose(plain[:, 30 + k], np.hypot(*((pos[:, rhip] - pos[:, chest]) / span_plain).T))
    # centred: the same pixel differences over the centred coordinates' spans
    c = pos - pos[:, chest : chest + 1]
    c[:, chest] = pos[:, chest] - pos[:, chest].mean(axis=0)  # its mean over the first second (all 20 frames)
    span_c = c.reshape(-1, 2).max(0) - c.reshape(-1, 2).min(0)
    np.testing.assert_allclose(centred[:, 30 + k], np.hypot(*((pos[:, rhip] - pos[:, chest]) / span_c).T))
