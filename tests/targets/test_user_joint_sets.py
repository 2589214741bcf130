"""A joint set kinectdata does not ship (a made-up 19-joint dancer) through schema files only: a CSV
dialect and a target spec name its file, a dataset is built, and its manifest carries the set."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from conftest import REPO
from helpers import DANCER19, write_dancer19_schemas

from kinectdata.core.errors import KinectDataError, SchemaError
from kinectdata.core.jointsets import joint_set_from_dict, load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features import PRESETS
from kinectdata.targets.specs import TargetSpec, extract_targets, load_target_spec


@pytest.fixture
def corpus(tmp_path):
    """The joint-set file, a dialect for its CSV and a positions spec, all in ``schemas/``; two
    recordings of it in ``takes/`` with copies of the bundled songs and a recordings manifest."""
    schemas = tmp_path / "schemas"
    schemas.mkdir()
    write_dancer19_schemas(schemas)
    (schemas / "dancer19_positions.json").write_text(
        json.dumps(
            {
                "name": "dancer19_positions",
                "joint_set": "dancer19.json",
                "positions": list(DANCER19),
                "orientations": [],
            }
        )
    )
    takes = tmp_path / "takes"
    takes.mkdir()
    rng = np.random.default_rng(0)
    entries = []
    for k, split in ((1, "train"), (2, "val"), (3, "test")):
        n = 30 * 20
        rest = rng.normal(0, 0.3, (len(DANCER19), 3)) + [0, 1, 2.5]
        sway = 0.05 * np.sin(np.arange(n)[:, None, None] * 0.2 + rng.uniform(0, 6, (1, len(DANCER19), 3)))
        pos = rest + sway
        header = ["t"] + [f"{j}_{a}" for j in DANCER19 for a in "xyz"]
        rows = [",".join([f"{t / 30:.4f}"] + [f"{v:.5f}" for v in pos[t].ravel()]) for t in range(n)]
        (takes / f"take{k}.csv").write_text("\n".join([",".join(header), *rows]) + "\n")
        shutil.copy(REPO / "sample_data" / f"synth_00{k}.flac", takes / f"take{k}.flac")
        entries.append(
            {
                "recording": f"takes/take{k}.csv",
                "audio": f"takes/take{k}.flac",
                "offset": 0.0,
                "schema": "schemas/dancer19_csv.json",
                "split": split,
            }
        )
    (tmp_path / "recordings.json").write_text(json.dumps(entries))
    return tmp_path


def test_a_spec_file_names_a_joint_set_file_and_carries_it(corpus):
    spec = load_target_spec(corpus / "schemas" / "dancer19_positions.json")
    js = load_joint_set(corpus / "schemas" / "dancer19.json")
    assert spec.joint_set == "dancer19" and spec.joints == js and spec.dim == 57
    assert spec.root == "pelvis"
    doc = json.loads(json.dumps(spec.to_dict()))  # as a manifest stores it
    assert doc["joint_set"]["joints"][4] == {"name": "head", "parent": "neck"}
    again = TargetSpec.from_dict(doc)
    assert again == spec and again.joints.parents == js.parents
    assert joint_set_from_dict(js.to_dict()) == js


def test_a_dataset_of_an_unshipped_joint_set_from_schema_files_only(corpus, tmp_path):
    spec = load_target_spec(corpus / "schemas" / "dancer19_positions.json")
    config = BuildConfig(features=PRESETS["yalta2016"], target=spec, split_ratios=(1, 0, 0))
    manifest = build_dataset(corpus / "recordings.json", tmp_path / "ds", config)
    target = TargetSpec.from_dict(manifest["config"]["target"])
    assert target == spec and target.joints.names == tuple(DANCER19)
    assert manifest["target_dim"] == 57 and manifest["totals"]["recordings"] == 3
    assert manifest["splits"]["train"]["rows"] > 500


def test_what_does_not_fit_is_refused_with_one_line(corpus):
    schemas = corpus / "schemas"
    missing = schemas / "missing_set.json"
    missing.write_text(json.dumps({"name": "x", "joint_set": "nowhere.json", "positions": ["a"], "orientations": []}))
    with pytest.raises(SchemaError, match=r"'nowhere.json' is neither a shipped joint set .* nor a joint-set file"):
        load_target_spec(missing)
    impostor = schemas / "impostor.json"
    impostor.write_text(json.dumps({"name": "kinect_v2", "joints": [{"name": "a", "parent": None}]}))
    named = schemas / "named.json"
    named.write_text(json.dumps({"name": "y", "joint_set": "impostor.json", "positions": ["a"], "orientations": []}))
    with pytest.raises(SchemaError, match="'kinect_v2' is a shipped joint set's name, with other joints: rename it"):
        load_target_spec(named)
    spec = load_target_spec(schemas / "dancer19_positions.json")
    other = joint_set_from_dict({"name": "dancer19", "joints": [{"name": "pelvis", "parent": None}]})
    motion = Motion(np.arange(3) / 30, np.zeros((3, 1, 3)), other)
    with pytest.raises(KinectDataError, match="target spec 'dancer19_positions' is for joint set 'dancer19'"):
        extract_targets(motion, spec)


def test_a_generic_target_needs_no_spec_file(corpus, tmp_path):
    """--target positions: the spec is made for the recordings' joint set when they are read."""
    from click.testing import CliRunner

    from kinectdata.cli import main

    out = tmp_path / "ds"
    result = CliRunner().invoke(
        main, ["build-dataset", str(corpus / "recordings.json"), "-o", str(out), "--target", "positions"]
    )
    assert result.exit_code == 0, result.output
    manifest = json.loads((out / "manifest.json").read_text())
    spec = TargetSpec.from_dict(manifest["config"]["target"])
    assert spec.name == "dancer19_positions" and spec.positions == tuple(DANCER19) and spec.orientations == ()
    assert manifest["target_dim"] == 57
    written = load_target_spec(corpus / "schemas" / "dancer19_positions.json")  # the same vector, by hand
    assert (spec.positions, spec.joints, spec.dim) == (written.positions, written.joints, written.dim)


def test_a_generic_target_refuses_recordings_of_two_joint_sets(corpus, tmp_path):
    entries = json.loads((corpus / "recordings.json").read_text())
    shutil.copy(REPO / "sample_data" / "synth_001.csv", corpus / "takes" / "kinect.csv")
    shutil.copy(REPO / "sample_data" / "synth_001.flac", corpus / "takes" / "kinect.flac")
    entries.append({"recording": "takes/kinect.csv", "audio": "takes/kinect.flac", "split": "train"})
    (corpus / "mixed.json").write_text(json.dumps(entries))
    config = BuildConfig(features=PRESETS["yalta2016"], target={"generic": "positions"})
    with pytest.raises(
        KinectDataError, match=r"use different joint sets, so the generic 'positions' target .*dancer19 .*kinect_v2"
    ):
        build_dataset(corpus / "mixed.json", tmp_path / "ds", config)


@pytest.mark.slow
def test_an_unshipped_joint_set_goes_to_a_trained_model_and_the_fields_metrics(corpus, tmp_path):
    """Issue 17's end to end: schema files only, to a dataset, a trained model and the field's
    metrics through the joint-set file's own SMPL-24 mapping."""
    pytest.importorskip("torch")
    from conftest import TINY_TRAINING

    from kinectdata.core.joint_mapping import load_smpl24_mapping
    from kinectdata.evaluation.evaluate import evaluate
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    js = load_joint_set(corpus / "schemas" / "dancer19.json")
    mapping = load_smpl24_mapping(js)
    positions = np.random.default_rng(1).normal(size=(2, len(js), 3))
    smpl, _ = mapping.apply(positions)
    names = list(js.names)
    np.testing.assert_allclose(
        smpl[:, 9], (positions[:, names.index("spine2")] + positions[:, names.index("neck")]) / 2
    )
    assert mapping.describe()["approximated"]["left_hand"] == "no hand joint: the wrist stands in"

    config = BuildConfig(features=PRESETS["yalta2016"], target={"generic": "positions"})
    build_dataset(corpus / "recordings.json", tmp_path / "ds", config)
    train(tmp_path / "ds", tmp_path / "run", TrainConfig(**TINY_TRAINING))
    results = evaluate(tmp_path / "run", tmp_path / "ds", "test", engines=[("torch", "float32")], bootstrap=20)
    assert "unavailable" not in results["field"], results["field"]
    assert {"fid_k", "bas"} <= {k.lower() for k in results["field"]["metrics"]}
