"""Joint arrays declared by an array schema: keys, joint set, clock, unit, axes and a track to add,
each checked on arrays made from a recording with known values."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO

from kinectdata.cli import main
from kinectdata.core.errors import FormatError, SchemaError
from kinectdata.formats import read_motion


@pytest.fixture(scope="module")
def take():
    return read_motion(REPO / "sample_data" / "synth_001.csv")


def _schema(folder, **fields):
    doc = {"name": "test_arrays", "joint_set": "kinect_v2", "time": {"fps": 30}} | fields
    path = folder / "arrays.json"
    path.write_text(json.dumps(doc))
    return path


def test_an_npy_in_metres_reads_as_it_is(tmp_path, take):
    np.save(tmp_path / "take.npy", take.positions)
    motion = read_motion(tmp_path / "take.npy", schema=_schema(tmp_path))
    np.testing.assert_array_equal(motion.positions[take.position_mask], take.positions[take.position_mask])
    np.testing.assert_array_equal(motion.position_mask, take.position_mask)  # NaN: that joint's frame invalid
    np.testing.assert_allclose(motion.times, np.arange(take.n_frames) / 30)
    assert motion.joint_set.name == "kinect_v2" and motion.metadata["schema"] == "test_arrays"


def test_an_npz_in_centimetres_z_up_left_handed_with_a_root_track(tmp_path, take):
    """The known answer: the take moved into such a file, then read back into kinectdata's axes."""
    ok = take.position_mask.all(axis=1)
    metres = take.positions[ok]
    root = metres[:, :1].copy()
    relative = (metres - root) * 100  # centimetres, relative to a root track
    track = root[:, 0] * 100
    # kinectdata's (x, y, z), y up, right-handed -> a file's z up, left-handed: (x, y, z) -> (-x, -z, y)
    to_file = lambda p: np.stack([-p[..., 0], -p[..., 2], p[..., 1]], axis=-1)  # noqa: E731
    stamps = np.cumsum(np.full(len(metres), 33.0)) + 1000.0
    np.savez(tmp_path / "take.npz", joints=to_file(relative), trans=to_file(track), stamps_ms=stamps)
    schema = _schema(
        tmp_path, positions="joints", add="trans", unit="cm", up="z", handedness="left",
        time={"key": "stamps_ms", "unit": "ms"},
    )  # fmt: skip
    motion = read_motion(tmp_path / "take.npz", schema=schema)
    np.testing.assert_allclose(motion.positions, metres, atol=1e-12)
    np.testing.assert_allclose(motion.times[:3], [0.0, 0.033, 0.066])


def test_a_json_object_and_a_user_joint_set_beside_the_schema(tmp_path, take):
    (tmp_path / "three.json").write_text(
        json.dumps({"name": "three", "joints": [{"name": "a", "parent": None}, {"name": "b", "parent": "a"},
                                                {"name": "c", "parent": "b"}]})
    )  # fmt: skip
    frames = take.positions[:5, :3].round(4)
    (tmp_path / "take.json").write_text(json.dumps({"xyz": frames.reshape(5, 9).tolist()}))
    motion = read_motion(
        tmp_path / "take.json", format="arrays", schema=_schema(tmp_path, joint_set="three.json", positions="xyz")
    )
    assert motion.joint_set.names == ("a", "b", "c") and motion.joint_set.parents == (-1, 0, 1)
    np.testing.assert_allclose(motion.positions, frames)
    # an array schema given says the file is arrays: no --format needed, whatever the suffix
    plain = read_motion(tmp_path / "take.json", schema=tmp_path / "arrays.json")
    np.testing.assert_array_equal(plain.positions, motion.positions)
    (tmp_path / "take.data").write_text((tmp_path / "take.json").read_text())
    np.testing.assert_array_equal(
        read_motion(tmp_path / "take.data", schema=tmp_path / "arrays.json").positions, frames
    )
    result = CliRunner().invoke(main, ["info", str(tmp_path / "take.json"), "--schema", str(tmp_path / "arrays.json")])
    assert result.exit_code == 0 and "format          arrays" in result.output, result.output
    # a CSV schema does not claim a file for the arrays reader
    csv = read_motion(REPO / "sample_data" / "synth_001.csv", schema="dumpkinectskeleton")
    assert csv.metadata["format"] == "csv"


def test_what_does_not_fit_is_one_line(tmp_path, take):
    np.save(tmp_path / "take.npy", take.positions)
    with pytest.raises(FormatError, match="give an array schema"):
        read_motion(tmp_path / "take.npy")
    with pytest.raises(FormatError, match=r"positions of shape \[672, 25, 3\]; the nite joint set needs \[T, 15, 3\]"):
        read_motion(tmp_path / "take.npy", schema=_schema(tmp_path, joint_set="nite"))
    np.savez(tmp_path / "take.npz", joints=take.positions)
    with pytest.raises(FormatError, match=r"no 'positions' for the positions \(keys: joints\)"):
        read_motion(tmp_path / "take.npz", schema=_schema(tmp_path, positions="positions"))
    with pytest.raises(SchemaError, match="at unit"):
        read_motion(tmp_path / "take.npy", schema=_schema(tmp_path, unit="furlong"))
    with pytest.raises(SchemaError, match=r"'missing.json' is neither a shipped joint set .* nor a joint-set file"):
        read_motion(tmp_path / "take.npy", schema=_schema(tmp_path, joint_set="missing.json"))
    np.save(tmp_path / "objects.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(FormatError, match="cannot read it as joint arrays .*Object arrays cannot be loaded"):
        read_motion(tmp_path / "objects.npy", schema=_schema(tmp_path))


def test_derived_joints_are_weighted_sums_and_must_be_the_sets_last_joints(tmp_path):
    joints = [{"name": "a", "parent": "mid"}, {"name": "b", "parent": "mid"}, {"name": "mid", "parent": None}]
    (tmp_path / "ab.json").write_text(json.dumps({"name": "ab_mid", "joints": joints}))
    values = np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3)
    values[1, 0] = np.nan  # a untracked in frame 1: the midpoint is too
    np.save(tmp_path / "take.npy", values)
    schema = _schema(tmp_path, joint_set="ab.json", derived={"mid": {"a": 0.25, "b": 0.75}})
    motion = read_motion(tmp_path / "take.npy", schema=schema)
    np.testing.assert_allclose(motion.positions[0, 2], 0.25 * values[0, 0] + 0.75 * values[0, 1])
    assert motion.position_mask.tolist() == [[True, True, True], [False, True, False]]
    with pytest.raises(SchemaError, match="derived: b must be the last joints of ab_mid"):
        read_motion(tmp_path / "take.npy", schema=_schema(tmp_path, joint_set="ab.json", derived={"b": {"a": 1}}))
    with pytest.raises(SchemaError, match="derived: mid is made of z, not joints the file holds"):
        read_motion(tmp_path / "take.npy", schema=_schema(tmp_path, joint_set="ab.json", derived={"mid": {"z": 1}}))


def test_a_root_track_places_the_root_and_a_file_may_give_its_own_rate(tmp_path):
    """tang2018's shape: joints relative to a ``center`` track that is the root's own position. The
    root (the joint set's last joint) is placed on the track, the others are offset from it; and one
    schema serves files of different rates, each rate given for its file (manifest ``fps``)."""
    joints = [{"name": "a", "parent": "root"}, {"name": "b", "parent": "a"}, {"name": "root", "parent": None}]
    (tmp_path / "abr.json").write_text(json.dumps({"name": "ab_root", "joints": joints}))
    rng = np.random.default_rng(0)
    relative, center = rng.normal(size=(6, 2, 3)), rng.normal(size=(6, 3)) + [0, 1, 2]
    np.savez(tmp_path / "take.npz", skeletons=relative, center=center)
    schema = _schema(tmp_path, joint_set="abr.json", positions="skeletons", root_track="center", time={"fps": 25})
    motion = read_motion(tmp_path / "take.npz", schema=schema)
    assert motion.joint_set.names == ("a", "b", "root")
    np.testing.assert_allclose(motion.positions[:, 2], center)
    np.testing.assert_allclose(motion.positions[:, :2], relative + center[:, None])
    np.testing.assert_allclose(motion.times, np.arange(6) / 25)
    own = read_motion(tmp_path / "take.npz", schema=schema, array_fps=24.45)
    np.testing.assert_allclose(own.times, np.arange(6) / 24.45)
    # a recordings manifest gives each file its rate; the build reads it with that clock
    from kinectdata.dataset.inputs import read_recordings

    (tmp_path / "recordings.json").write_text(
        json.dumps([{"recording": "take.npz", "audio": "take.npz", "schema": schema.name, "fps": 24.45}])
    )
    (entry,) = read_recordings(tmp_path / "recordings.json")
    np.testing.assert_allclose(entry.read_motion().times, np.arange(6) / 24.45)
    result = CliRunner().invoke(
        main, ["info", str(tmp_path / "take.npz"), "--schema", str(schema), "--array-fps", "50"]
    )
    assert result.exit_code == 0 and "50" in result.output, result.output
    with pytest.raises(SchemaError, match="root_track: the track is the root's, so ab_mid's last joint must be"):
        (tmp_path / "ab.json").write_text(json.dumps({"name": "ab_mid", "joints": joints[::-1]}))
        read_motion(tmp_path / "take.npz", schema=_schema(tmp_path, joint_set="ab.json", root_track="center"))
    with pytest.raises(SchemaError, match="root_track and add: give one"):
        read_motion(tmp_path / "take.npz", schema=_schema(tmp_path, joint_set="abr.json", root_track="c", add="c"))
