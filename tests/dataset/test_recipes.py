"""Corpus recipes on small copies made in the shape of the real corpora (tests/corpus_copies.py):
what each lists, with which split, and that every entry reads back as the corpus's own numbers."""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from corpus_copies import (
    AISTPP_SEQUENCES,
    TANG2018_DANCES,
    coco_keypoints_m,
    finedance_motion,
    made_up_rest_joints,
    make_aistpp_copy,
    make_bvh_folder,
    make_finedance_copy,
    make_tang2018_copy,
)

from kinectdata.cli import main
from kinectdata.core.errors import ConfigError, CorpusError, SchemaError
from kinectdata.dataset.build import _key_entry
from kinectdata.dataset.folds import write_folds
from kinectdata.dataset.inputs import RecordingEntry, read_recordings, read_songs
from kinectdata.dataset.recipes import (
    prepare_aistpp,
    prepare_bvh_folder,
    prepare_corpus,
    prepare_finedance,
    prepare_tang2018,
)
from kinectdata.formats import read_motion


def _one_line_error(result) -> str:
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), result.output
    return lines[0]


# -- AIST++ -------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def aistpp(tmp_path_factory):
    return make_aistpp_copy(tmp_path_factory.mktemp("aistpp"))


def test_aistpp_lists_the_published_splits_and_leaves_out_what_the_corpus_does(aistpp):
    manifest = prepare_aistpp(aistpp)
    listed = {e.name: e.split for e in manifest.recordings}
    expected = {n: s for n, (_, _, s) in AISTPP_SEQUENCES.items() if s in ("train", "val", "test")}
    assert listed == expected
    skipped = dict(manifest.skipped)
    assert "ignore_list" in skipped["gLH_sBM_cAll_d16_mLH0_ch01"]
    assert "crossmodal" in skipped["gMH_sBM_cAll_d22_mMH3_ch04"]
    entry = next(e for e in manifest.recordings if e.name == "gPO_sBM_cAll_d10_mPO1_ch02")
    assert (entry.recording, entry.audio) == ("keypoints3d/gPO_sBM_cAll_d10_mPO1_ch02.pkl", "music/mPO1.flac")
    assert (entry.offset, entry.format, entry.schema) == (0.0, "arrays", "aistpp_keypoints3d")
    assert manifest.split_counts() == {"train": 2, "val": 1, "test": 1}

    with_unsplit = prepare_aistpp(aistpp, include_unsplit=True, keypoints="keypoints3d_optim")
    assert {e.name: e.split for e in with_unsplit.recordings}["gMH_sBM_cAll_d22_mMH3_ch04"] is None
    assert {e.schema for e in with_unsplit.recordings} == {"aistpp_keypoints3d_optim"}


def test_an_aistpp_entry_reads_as_the_keypoints_in_metres_at_60_fps_with_the_midpoints(aistpp, tmp_path):
    manifest = prepare_aistpp(aistpp)
    out = manifest.write(tmp_path / "recordings.yaml")
    doc = yaml.safe_load(out.read_text())
    assert doc["corpus"] == "aistpp" and doc["root"] == str(aistpp.resolve())
    with pytest.raises(SchemaError, match="root .* leads outside the manifest's folder"):
        read_recordings(out)
    entries = {e.name: e for e in read_recordings(out, allow_outside_paths=True)}
    motion = entries["gJB_sFM_cAll_d09_mJB2_ch03"].read_motion()
    expected = coco_keypoints_m("synth_001", 8.0, 6.0)  # what the copy was made from, in metres
    assert motion.joint_set.name == "coco17_tree"
    np.testing.assert_allclose(motion.times, np.arange(len(expected)) / 60.0)
    np.testing.assert_allclose(motion.positions[:, :17], expected, atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(
        motion.positions[:, 17], (expected[:, 11] + expected[:, 12]) / 2, atol=1e-9, equal_nan=True
    )
    np.testing.assert_allclose(
        motion.positions[:, 18], (expected[:, 5] + expected[:, 6]) / 2, atol=1e-9, equal_nan=True
    )


def test_a_manifest_written_inside_the_corpus_needs_no_outside_paths(aistpp):
    manifest = prepare_aistpp(aistpp)
    out = manifest.write(aistpp / "recordings.json")
    assert not manifest.root_outside(out)
    assert len(read_recordings(out)) == 4


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda a: [p.unlink() for p in (a / "keypoints3d").glob("*.pkl")], r"no keypoints3d/\*\.pkl"),
        (lambda a: [p.unlink() for p in (a / "music").iterdir()] and (a / "music").rmdir(), "no music folder"),
        (lambda a: (a / "splits" / "crossmodal_val.txt").unlink(), r"crossmodal_val\.txt: no such split list"),
        (lambda a: [p.unlink() for p in (a / "music").iterdir()], "no recording could be listed"),
    ],
    ids=["no keypoints", "no music folder", "a split list missing", "no music"],
)
def test_a_copy_that_is_not_aistpp_is_one_line(tmp_path, damage, message):
    annotations = make_aistpp_copy(tmp_path, seconds=1.0)
    damage(annotations)
    result = CliRunner().invoke(main, ["prepare", "aistpp", str(annotations), "-o", str(tmp_path / "r.yaml")])
    assert re.search(message, _one_line_error(result))
    assert not (tmp_path / "r.yaml").exists()


class _RunsCode:
    def __reduce__(self):
        import os

        return (os.system, ("touch pwned",))


def test_a_pickle_that_would_run_code_is_refused_with_one_line_and_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    evil = tmp_path / "gBR_sBM_cAll_d04_mBR0_ch01.pkl"
    evil.write_bytes(pickle.dumps({"keypoints3d": _RunsCode()}))
    result = CliRunner().invoke(main, ["info", str(evil), "--schema", "aistpp_keypoints3d"])
    line = _one_line_error(result)
    assert str(evil) in line and re.search(r"refused: the pickle asks for (posix|os|nt)\.system", line)
    assert not (tmp_path / "pwned").exists()


@pytest.mark.parametrize("protocol", [2, 4, 5])
def test_pickles_of_arrays_read_whatever_protocol_numpy_wrote_them_with(tmp_path, protocol):
    keypoints = coco_keypoints_m("synth_002", 0.0, 0.5) * 100.0
    path = tmp_path / "gBR_sBM_cAll_d04_mBR0_ch01.pkl"
    path.write_bytes(pickle.dumps({"keypoints3d": keypoints, "keypoints3d_optim": keypoints}, protocol=protocol))
    motion = read_motion(path, schema="aistpp_keypoints3d")
    np.testing.assert_allclose(motion.positions[:, :17], keypoints / 100.0, equal_nan=True)


# -- FineDance ----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def finedance(tmp_path_factory):
    return make_finedance_copy(tmp_path_factory.mktemp("finedance"), seconds=2.0)


def _homogeneous_chain(rest: np.ndarray, parents, translation: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Joint positions [T, 52, 3] the way SMPL-X's linear blend skinning chains them: one 4x4
    transform per joint, [R | rest offset from the parent], multiplied down the tree, frame by frame."""
    T, J = local.shape[:2]
    out = np.empty((T, J, 3))
    for t in range(T):
        world = []
        for j in range(J):
            m = np.eye(4)
            m[:3, :3] = local[t, j]
            m[:3, 3] = rest[j] - (rest[parents[j]] if parents[j] >= 0 else 0.0)
            world.append(m if parents[j] < 0 else world[parents[j]] @ m)
            out[t, j] = world[j][:3, 3] + translation[t]
    return out


def test_finedance_positions_equal_an_independent_forward_kinematics(tmp_path):
    from scipy.spatial.transform import Rotation

    from kinectdata.core.jointsets import load_joint_set

    data, translation, local = finedance_motion(1.0, seed=3)
    np.save(tmp_path / "001.npy", data)
    rest55 = made_up_rest_joints()
    np.save(tmp_path / "rest.npy", rest55[None])  # FineDance's file may carry a leading batch axis
    motion = read_motion(tmp_path / "001.npy", format="finedance", rest_joints=tmp_path / "rest.npy")
    rest = rest55[[*range(22), *range(25, 55)]].astype(np.float64)
    parents = load_joint_set("smplh52").parents
    expected = _homogeneous_chain(rest, parents, translation.astype(np.float32).astype(np.float64), local)
    np.testing.assert_allclose(motion.positions, expected, atol=2e-6)  # the file holds float32
    np.testing.assert_allclose(motion.times, np.arange(30) / 30.0)
    # the left wrist's global orientation: the local rotations multiplied down its chain from the root
    wrist = np.broadcast_to(np.eye(3), local.shape[:1] + (3, 3))
    for j in (0, 3, 6, 9, 13, 16, 18, 20):
        wrist = wrist @ local[:, j]
    got = Rotation.from_quat(motion.orientations[:, 20])
    assert (got.inv() * Rotation.from_matrix(wrist)).magnitude().max() < 1e-5


def test_finedance_at_rest_is_the_rest_skeleton_moved_by_the_translation(tmp_path):
    identity = np.tile([1.0, 0, 0, 0, 1.0, 0], 52)
    translation = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    np.save(tmp_path / "002.npy", np.concatenate([translation, np.tile(identity, (2, 1))], axis=1))
    rest = made_up_rest_joints()[[*range(22), *range(25, 55)]]
    np.save(tmp_path / "rest52.npy", rest)
    motion = read_motion(tmp_path / "002.npy", format="finedance", rest_joints=tmp_path / "rest52.npy")
    np.testing.assert_allclose(motion.positions, rest[None] + translation[:, None], atol=1e-6)
    np.testing.assert_allclose(np.abs(motion.orientations[..., 3]), 1.0, atol=1e-12)


def test_finedance_lists_the_published_split_and_finds_the_rest_joints_in_the_code_repository(finedance):
    manifest = prepare_finedance(finedance)
    assert {e.name: e.split for e in manifest.recordings} == {"001": "train", "002": "train", "063": "test"}
    assert dict(manifest.skipped).keys() == {"005", "116"}
    assert manifest.root == (finedance.parent.parent).resolve()  # FineDance/, which holds the rest joints
    entry = manifest.recordings[0]
    assert (entry.format, entry.rest_joints, entry.offset) == ("finedance", "smplx_neu_J_1.npy", 0.0)
    assert entry.recording == "data/finedance/motion/001.npy"
    dancer = prepare_corpus("finedance", finedance, split="cross_dancer")
    assert {e.name: e.split for e in dancer.recordings} == {"001": "test", "002": "test", "063": "train"}


def test_finedance_without_its_rest_joints_says_where_to_find_them(tmp_path):
    data = make_finedance_copy(tmp_path, seconds=0.5)
    (data.parent.parent / "smplx_neu_J_1.npy").unlink()
    result = CliRunner().invoke(main, ["prepare", "finedance", str(data), "-o", str(tmp_path / "r.yaml")])
    assert "--rest-joints FILE" in _one_line_error(result)
    result = CliRunner().invoke(main, ["info", str(data / "motion" / "001.npy"), "--format", "finedance"])
    assert "--rest-joints FILE" in _one_line_error(result)


# -- a BVH folder -------------------------------------------------------------------------------------


def test_a_bvh_folder_pairs_each_file_with_its_music_and_takes_splits_from_folder_names(tmp_path):
    folder = make_bvh_folder(tmp_path, seconds=1.0)
    manifest = prepare_bvh_folder(folder, unit="cm")
    assert {e.name: e.split for e in manifest.recordings} == {
        "test+salsa_03": "test",
        "train+salsa_01": "train",
        "train+salsa_02": "train",
    }
    assert dict(manifest.skipped).keys() == {"warmup"}
    out = manifest.write(folder / "recordings.yaml")
    entries = {e.name: e for e in read_recordings(out)}
    expected = read_motion(folder / "train" / "salsa_01.bvh", unit="cm")
    got = entries["train+salsa_01"].read_motion()
    np.testing.assert_allclose(got.positions, expected.positions, equal_nan=True)
    in_metres = prepare_bvh_folder(folder, unit="m").write(folder / "as_metres.yaml")
    scaled = {e.name: e for e in read_recordings(in_metres)}["train+salsa_01"].read_motion()
    np.testing.assert_allclose(scaled.positions, got.positions * 100.0, rtol=1e-9, equal_nan=True)


def test_options_a_recipe_does_not_take_are_refused():
    with pytest.raises(ConfigError, match="unit do not apply to aistpp"):
        prepare_corpus("aistpp", ".", unit="cm")
    with pytest.raises(ConfigError, match="unknown corpus"):
        prepare_corpus("cmu", ".")
    with pytest.raises(CorpusError, match="not a folder"):
        prepare_bvh_folder("no_such_folder")


# -- Dance with Melody (tang2018) ---------------------------------------------------------------------

TANG2018_TEST = {"C_2", "C_4", "R_2", "R_3", "T_5", "W_1", "W_3"}
TANG2018_VAL = {"C_6", "R_4", "W_4"}
"""kinectdata's acceptance split as docs/corpora.md states it (the recipe's KINECTDATA_SPLIT)."""
COMPLETE = {name for name, dance in TANG2018_DANCES.items() if dance.complete}
STYLE = {"C": ("cha-cha", 4), "R": ("rumba", 4), "T": ("tango", 4), "W": ("waltz", 3)}


@pytest.fixture(scope="module")
def tang(tmp_path_factory):
    return make_tang2018_copy(tmp_path_factory.mktemp("tang2018"), seconds=3.0)


def test_tang2018_lists_the_complete_dances_in_the_acceptance_split(tang):
    manifest = prepare_tang2018(tang)
    expected = {n: "test" if n in TANG2018_TEST else "val" if n in TANG2018_VAL else "train" for n in COMPLETE}
    assert {e.name: e.split for e in manifest.recordings} == expected
    assert manifest.split_counts() == {"train": 4, "val": 3, "test": 7}
    assert [e.name for e in manifest.recordings] == ["C_2", "C_4", "C_6", "C_7", "R_2", "R_3", "R_4", "R_5",
                                                     "T_5", "W_1", "W_3", "W_4", "W_5", "W_6"]  # fmt: skip
    assert manifest.build_options == ("--root-centre",) and manifest.target == "positions"
    unsplit = prepare_corpus("tang2018", tang, split="none")
    assert {e.name: e.split for e in unsplit.recordings} == dict.fromkeys(COMPLETE)
    assert unsplit.split_counts() == {"unsplit": len(COMPLETE)}
    assert {e.name for e in prepare_tang2018(tang, split=None).recordings} == COMPLETE


def test_tang2018_leaves_out_the_incomplete_dances_naming_the_missing_file(tang):
    skipped = dict(prepare_tang2018(tang).skipped)
    kept = "; its song alone is there"
    assert skipped == {
        "C_1": f"DANCE_C_1/skeletons.json is missing or empty{kept}",
        "C_9": "DANCE_C_9/audio.mp3 is missing or empty",
        "R_6": f"DANCE_R_6/skeletons.json is missing or empty{kept}",
        "T_1": "DANCE_T_1/skeletons.json is missing or empty",  # it lacks audio.mp3 too
        "W_2": "DANCE_W_2/audio.mp3 is missing or empty",
        "W_9": "DANCE_W_9/audio.mp3 is missing or empty",  # held, but empty
        "W_13": f"DANCE_W_13/skeletons.json is missing or empty{kept}",
    }
    assert set(skipped) == set(TANG2018_DANCES) - COMPLETE
    listed = dict(prepare_tang2018(tang, labelled_songs=True).skipped)
    assert listed["C_1"] == "DANCE_C_1/skeletons.json is missing or empty; its song is kept to hear the style by"


def test_tang2018_lists_a_song_without_its_dance_as_labelled_music_when_asked(tang, tmp_path):
    assert prepare_tang2018(tang).songs == ()  # not by default: on the folds they cost the hearing a song
    manifest = prepare_tang2018(tang, labelled_songs=True)
    assert [(s.name, s.audio, s.style) for s in manifest.songs] == [
        ("C_1", "DANCE_C_1/audio.mp3", "cha-cha"),
        ("R_6", "DANCE_R_6/audio.mp3", "rumba"),
        ("W_13", "DANCE_W_13/audio.mp3", "waltz"),
    ]
    written = manifest.write(tmp_path / "tang.yaml")
    songs = read_songs(written, allow_outside_paths=True)
    assert [(s.name, s.style) for s in songs] == [("C_1", "cha-cha"), ("R_6", "rumba"), ("W_13", "waltz")]
    assert Path(songs[0].audio) == (tang / "DANCE_C_1" / "audio.mp3").resolve()
    # the folds keep them: a fold's build hears with them too
    folds = write_folds(written, 2)
    assert [s.name for s in read_songs(folds[0].path, allow_outside_paths=True)] == ["C_1", "R_6", "W_13"]


def test_tang2018_entries_carry_the_style_metre_offset_and_format(tang):
    for entry in prepare_tang2018(tang).recordings:
        dance = TANG2018_DANCES[entry.name]
        assert (entry.style, entry.beats_per_bar) == STYLE[entry.name[0]]
        assert entry.offset == pytest.approx(dance.start / 25.0, abs=1e-12)
        assert (entry.recording, entry.audio) == (f"DANCE_{entry.name}/skeletons.json", f"DANCE_{entry.name}/audio.mp3")
        assert entry.format == "tang2018"


def test_a_tang2018_entry_reads_at_the_dances_own_rate(tang, tmp_path):
    out = prepare_tang2018(tang).write(tmp_path / "tang.yaml")
    doc = yaml.safe_load(out.read_text())
    assert doc["corpus"] == "tang2018" and doc["recordings"][0]["beats_per_bar"] == 4
    entries = {e.name: e for e in read_recordings(out, allow_outside_paths=True)}
    assert (entries["W_4"].style, entries["W_4"].beats_per_bar) == ("waltz", 3)
    motion = entries["W_4"].read_motion()
    frames, extra = 75, TANG2018_DANCES["W_4"].extra
    np.testing.assert_allclose(motion.times, np.arange(frames) * (frames + extra) / (25.0 * frames), rtol=1e-12)
    direct = read_motion(tang / "DANCE_W_4" / "skeletons.json")
    np.testing.assert_array_equal(motion.positions, direct.positions)


def test_music_facts_are_no_reading_options_but_count_for_the_build():
    entry = RecordingEntry(name="W_1", recording="a.json", audio="a.mp3", offset=0.0, format="tang2018")
    with_facts = RecordingEntry(**{**entry.to_dict(), "style": "waltz", "beats_per_bar": 3})
    assert with_facts.options() == entry.options()  # a work file's key adds them where the features hear them
    assert with_facts.to_dict()["beats_per_bar"] == 3
    splits = {"W_1": "train"}
    assert _key_entry(with_facts, splits) == _key_entry(entry, splits) | {"style": "waltz", "beats_per_bar": 3}


def test_a_csv_manifest_reads_beats_per_bar_as_a_whole_number(tang):
    path = tang / "dances.csv"
    path.write_text(
        "name,recording,audio,split,offset,format,style,beats_per_bar\n"
        "W_1,DANCE_W_1/skeletons.json,DANCE_W_1/audio.mp3,train,0,tang2018,waltz, 3\n"
        "R_2,DANCE_R_2/skeletons.json,DANCE_R_2/audio.mp3,test,0.32,tang2018,rumba,\n"
    )
    entries = {e.name: e for e in read_recordings(path)}
    assert entries["W_1"].beats_per_bar == 3 and isinstance(entries["W_1"].beats_per_bar, int)
    assert (entries["W_1"].style, entries["R_2"].beats_per_bar) == ("waltz", None)
    path.write_text(path.read_text().replace("rumba,\n", "rumba,3.5\n"))
    with pytest.raises(SchemaError) as err:
        read_recordings(path)
    assert str(err.value) == f"{path}, line 3: beats_per_bar '3.5' is not a whole number"
    result = CliRunner().invoke(main, ["build-dataset", str(path), "-o", str(tang / "never"), "--target", "positions"])
    assert _one_line_error(result) == f"Error: {path}, line 3: beats_per_bar '3.5' is not a whole number"
    path.unlink()


def test_tang2018_refuses_a_split_it_does_not_have_and_a_folder_without_dances(tang, tmp_path):
    result = CliRunner().invoke(main, ["prepare", "tang2018", str(tang), "-o", str(tmp_path / "r.yaml"), "--split",
                                       "cross_genre"])  # fmt: skip
    assert "split 'cross_genre': the tang2018 recipe takes 'kinectdata' or 'none'" in _one_line_error(result)
    result = CliRunner().invoke(main, ["prepare", "tang2018", str(tang / "utils"), "-o", str(tmp_path / "r.yaml")])
    assert "no DANCE_<style>_<n> folders" in _one_line_error(result)
    assert not (tmp_path / "r.yaml").exists()


def test_tang2018_leaves_out_a_dance_whose_config_is_broken_saying_what_is_wrong(tmp_path):
    dances = {name: TANG2018_DANCES[name] for name in ("W_1", "W_3")}
    root = make_tang2018_copy(tmp_path, seconds=0.5, dances=dances)
    (root / "DANCE_W_1" / "config.json").write_text('{"start_position": 40, "end_position": 20}')
    manifest = prepare_tang2018(root)
    assert [e.name for e in manifest.recordings] == ["W_3"]
    assert manifest.skipped == (("W_1", "DANCE_W_1/config.json: end_position 20 is not after start_position 40"),)
    (root / "DANCE_W_3" / "config.json").write_text("[]")  # nothing left: one line naming the first reason
    result = CliRunner().invoke(main, ["prepare", "tang2018", str(root), "-o", str(tmp_path / "r.yaml")])
    assert _one_line_error(result) == (
        f"Error: {root}: no recording could be listed (2 left out; the first: "
        "DANCE_W_1/config.json: end_position 20 is not after start_position 40)"
    )
    assert not (tmp_path / "r.yaml").exists()


def test_a_dance_linked_from_elsewhere_is_listed_under_the_root_and_built_with_outside_paths(tmp_path):
    dances = {name: TANG2018_DANCES[name] for name in ("W_1", "W_3")}
    root = make_tang2018_copy(tmp_path / "corpus", seconds=0.5, dances=dances)
    elsewhere = tmp_path / "other_disk"
    elsewhere.mkdir()
    (root / "DANCE_W_3").rename(elsewhere / "DANCE_W_3")
    (root / "DANCE_W_3").symlink_to(elsewhere / "DANCE_W_3", target_is_directory=True)
    manifest = prepare_tang2018(root)
    linked = next(e for e in manifest.recordings if e.name == "W_3")
    assert (linked.recording, linked.audio) == ("DANCE_W_3/skeletons.json", "DANCE_W_3/audio.mp3")
    out = tmp_path / "tang.yaml"
    assert CliRunner().invoke(main, ["prepare", "tang2018", str(root), "-o", str(out)]).exit_code == 0
    with pytest.raises(SchemaError, match="leads outside"):  # the manifest's root is elsewhere: refused without leave
        read_recordings(out)
    found = read_recordings(out, allow_outside_paths=True)[1].recording
    assert found == str((elsewhere / "DANCE_W_3" / "skeletons.json").resolve())


# -- from the command line to a dataset -----------------------------------------------------------------


def test_prepare_then_build_dataset_keeps_the_published_splits(aistpp, tmp_path):
    runner = CliRunner()
    manifest = tmp_path / "recordings.yaml"
    result = runner.invoke(main, ["prepare", "aistpp", str(aistpp), "-o", str(manifest)])
    assert result.exit_code == 0, result.output
    assert "4 recordings of aistpp (2 train, 1 val, 1 test)" in result.output
    assert "gLH_sBM_cAll_d16_mLH0_ch01: in ignore_list.txt" in result.output
    next_line = result.output.strip().splitlines()[-2]
    assert result.output.strip().splitlines()[-1].startswith("  (for the cdhc model: --pipeline listen-to-dance")
    assert next_line == (
        f"next: kinectdata build-dataset {manifest} -o DATASET --target positions --features yalta2016_rhythm "
        "--allow-outside-paths"
    )
    args = ["build-dataset", str(manifest), "-o", str(tmp_path / "ds"), "--target", "positions"]
    result = runner.invoke(main, [*args, "--allow-outside-paths"])
    assert result.exit_code == 0, result.output
    import json

    doc = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    splits = {r["name"]: r["split"] for r in doc["recordings"]}
    assert splits == {n: s for n, (_, _, s) in AISTPP_SEQUENCES.items() if s in ("train", "val", "test")}
    assert doc["config"]["target"]["joint_set"] == "coco17_tree"


def test_formats_lists_the_corpus_readers_array_schemas_and_joint_sets():
    result = CliRunner().invoke(main, ["formats"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    finedance = next(line for line in lines if line.split()[:1] == ["finedance"])
    assert "--format only" in finedance  # its .npy is not told apart from joint arrays by detection
    assert any(line.split()[:1] == ["aistpp_keypoints3d_optim"] for line in lines)
    for joint_set, size in (("coco17_tree", 19), ("smplh52", 52)):
        assert any(line.split()[:3] == [joint_set, str(size), "joints,"] for line in lines)


def test_prepare_tang2018_then_build_dataset_root_centred_keeps_splits_and_music_facts(tang, tmp_path):
    runner = CliRunner()
    manifest = tmp_path / "tang.yaml"
    result = runner.invoke(main, ["prepare", "tang2018", str(tang), "-o", str(manifest)])
    assert result.exit_code == 0, result.output
    lines = result.output.strip().splitlines()
    assert lines[0] == f"wrote {manifest}: 14 recordings of tang2018 (4 train, 3 val, 7 test) under {tang.resolve()}"
    assert lines[1:4] == ["left out 7:",
                          "  C_1: DANCE_C_1/skeletons.json is missing or empty; its song alone is there",
                          "  C_9: DANCE_C_9/audio.mp3 is missing or empty"]  # fmt: skip
    assert lines[-3] == "  ... and 2 more"
    listed = runner.invoke(main, ["prepare", "tang2018", str(tang), "-o", str(tmp_path / "s.yaml"), "--labelled-songs"])
    assert listed.exit_code == 0, listed.output
    assert "listed 3 songs without a dance as labelled music (1 cha-cha, 1 rumba, 1 waltz)" in listed.output
    assert lines[-2] == (
        f"next: kinectdata build-dataset {manifest} -o DATASET --target positions --root-centre "
        "--features yalta2016_rhythm --allow-outside-paths"
    )
    args = ["build-dataset", str(manifest), "-o", str(tmp_path / "ds"), "--target", "positions"]
    result = runner.invoke(main, [*args, "--root-centre", "--allow-outside-paths"])
    assert result.exit_code == 0, result.output
    import json

    doc = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    expected = {n: "test" if n in TANG2018_TEST else "val" if n in TANG2018_VAL else "train" for n in COMPLETE}
    assert {r["name"]: r["split"] for r in doc["recordings"]} == expected
    assert {s: sorted(v["recordings"]) for s, v in doc["splits"].items()} == {
        s: sorted(n for n, x in expected.items() if x == s) for s in ("train", "val", "test")
    }
    assert doc["config"]["root_centre"] is True and doc["config"]["target"]["joint_set"] == "tang2018"
    inputs = {e["name"]: e for e in doc["inputs"]}
    assert {n: (e["style"], e["beats_per_bar"]) for n, e in inputs.items()} == {n: STYLE[n[0]] for n in COMPLETE}
    offsets = {r["name"]: r["offset"] for r in doc["recordings"]}
    assert offsets["C_7"] == {"seconds": pytest.approx(60 / 25.0), "source": "given", "confidence": 1.0}

    unsplit = tmp_path / "unsplit.yaml"
    result = runner.invoke(main, ["prepare", "tang2018", str(tang), "-o", str(unsplit), "--split", "none"])
    assert result.exit_code == 0, result.output
    assert "14 recordings of tang2018 (14 unsplit)" in result.output
    assert {e.split for e in read_recordings(unsplit, allow_outside_paths=True)} == {None}
