"""Safety: nothing untrusted is unpickled, manifests are validated before use, and the paths of a
recordings manifest stay inside its folder unless allowed."""

from __future__ import annotations

import ast
import json
import shutil

import pytest
from click.testing import CliRunner
from conftest import REPO, TINY_TRAINING

from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError, SchemaError
from kinectdata.dataset.inputs import read_recordings

SAMPLES = REPO / "sample_data"
PACKAGE = REPO / "kinectdata"


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


class _Planted:
    """Unpickling this object would create ``path``: the proof that code ran."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return open, (self.path, "w")


def _calls(tree: ast.AST, names: set[str]) -> list[ast.Call]:
    """Calls in ``tree`` of a function or method named like one of ``names`` (``torch.load``, ``load``...)."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            dotted = ast.unparse(f)
            if dotted in names or (isinstance(f, ast.Attribute) and f.attr in names):
                found.append(node)
    return found


def test_no_loader_in_the_package_can_unpickle():
    """torch.load only with weights_only=True; no pickle, np.load(allow_pickle=True), marshal or shelve."""
    torch_loads = 0
    for path in PACKAGE.rglob("*.py"):
        tree = ast.parse(path.read_text(), filename=str(path))
        for call in _calls(tree, {"torch.load"}):
            torch_loads += 1
            weights_only = [k for k in call.keywords if k.arg == "weights_only"]
            assert weights_only and ast.unparse(weights_only[0].value) == "True", f"{path}:{call.lineno}"
        for call in _calls(tree, {"pickle.load", "pickle.loads", "marshal.loads", "shelve.open", "dill.load"}):
            pytest.fail(f"{path}:{call.lineno}: {ast.unparse(call)}")
        for call in _calls(tree, {"np.load", "numpy.load"}):
            assert not any(k.arg == "allow_pickle" for k in call.keywords), f"{path}:{call.lineno}"
    assert torch_loads >= 1  # the checkpoint loader is found, so the scan looks where it should


def test_a_checkpoint_with_a_pickled_object_is_refused_naming_the_file(tmp_path):
    torch = pytest.importorskip("torch")
    from kinectdata.models.run import load_checkpoint, load_model

    planted = tmp_path / "planted.txt"
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "config.json").write_text("{}")
    for name in ("checkpoint.pt", "model.pt"):
        torch.save({"model": {"w": torch.zeros(2)}, "extra": _Planted(planted)}, run_dir / name)
    with pytest.raises(KinectDataError, match=r"checkpoint\.pt: not a readable kinectdata checkpoint"):
        load_checkpoint(run_dir / "checkpoint.pt")
    with pytest.raises(KinectDataError, match=r"model\.pt: not a readable kinectdata checkpoint"):
        load_model(run_dir)
    result = run("generate", SAMPLES / "synth_001.flac", "--run", run_dir, "-o", tmp_path / "out.csv")
    assert result.exit_code == 1 and f"{run_dir / 'model.pt'}: not a readable" in result.output
    assert not planted.exists()


def test_dataset_manifests_are_validated_before_training_or_evaluation(tmp_path):
    pytest.importorskip("torch")
    from kinectdata.models.run import read_manifest
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    dataset = tmp_path / "dataset"
    dataset.mkdir()
    (dataset / "manifest.json").write_text(json.dumps({"format": "kinectdata.dataset", "format_version": 2}))
    with pytest.raises(SchemaError, match=r"manifest\.json: at \(top level\): 'build_key' is a required property"):
        read_manifest(dataset)
    with pytest.raises(SchemaError, match=r"manifest\.json: .*required property \(and \d+ more problems"):
        train(dataset, tmp_path / "run", TrainConfig(**TINY_TRAINING))
    assert not (tmp_path / "run").exists()


@pytest.fixture
def outside(tmp_path):
    """(manifest folder, a recording and audio outside it): copies of synth_001 in tmp_path/elsewhere."""
    base, elsewhere = tmp_path / "base", tmp_path / "elsewhere"
    base.mkdir()
    elsewhere.mkdir()
    for ext in (".csv", ".flac"):
        shutil.copy(SAMPLES / f"synth_001{ext}", elsewhere / f"synth_001{ext}")
    return base, elsewhere / "synth_001.csv", elsewhere / "synth_001.flac"


def test_manifest_paths_may_not_leave_the_manifest_folder(outside):
    base, csv_file, audio = outside
    manifest = base / "recordings.json"
    (base / "link.csv").symlink_to(csv_file)
    for recording, why in [
        ("../elsewhere/synth_001.csv", rf"leads outside the manifest's folder or root {base} \(to {csv_file}\)"),
        (str(csv_file), "is an absolute path"),
        ("link.csv", rf"leads outside the manifest's folder or root {base} \(to {csv_file}\)"),
    ]:
        manifest.write_text(json.dumps([{"recording": recording, "audio": "../elsewhere/synth_001.flac"}]))
        with pytest.raises(SchemaError, match=rf"recordings\[0\]: recording {recording} {why}") as err:
            read_recordings(manifest)
        assert str(err.value).startswith(f"{manifest}: ")
        entries = read_recordings(manifest, allow_outside_paths=True)
        assert [(e.recording, e.audio) for e in entries] == [(str(csv_file), str(audio))]
    shutil.copy(audio, base / "song.flac")
    (base / "takes").mkdir()
    shutil.copy(csv_file, base / "takes" / "synth_001.csv")
    manifest.write_text(json.dumps([{"recording": "takes/../takes/synth_001.csv", "audio": "./song.flac"}]))
    (entry,) = read_recordings(manifest)  # `..` that stays inside is fine
    assert entry.recording == str((base / "takes" / "synth_001.csv").resolve())


def test_a_csv_manifest_names_the_line_and_the_path(outside):
    base, csv_file, audio = outside
    shutil.copy(audio, base / "song.flac")
    manifest = base / "recordings.csv"
    manifest.write_text(
        f"recording,audio,split\n{csv_file.name},song.flac,train\n../elsewhere/{csv_file.name},song.flac,test\n"
    )
    (base / csv_file.name).write_bytes(csv_file.read_bytes())
    with pytest.raises(SchemaError, match=r"recordings\.csv, line 3: .*recording \.\./elsewhere/synth_001\.csv leads"):
        read_recordings(manifest)


def test_build_dataset_refuses_outside_paths_unless_allowed(outside, tmp_path):
    base, csv_file, audio = outside
    manifest = base / "recordings.yaml"
    manifest.write_text(f"recordings:\n  - recording: {csv_file}\n    audio: {audio}\n")
    result = run("build-dataset", manifest, "-o", tmp_path / "ds")
    assert result.exit_code == 1
    assert f"{manifest}: recordings[0]: recording {csv_file} is an absolute path" in result.output
    assert "--allow-outside-paths" in result.output and not (tmp_path / "ds").exists()
    result = run("build-dataset", manifest, "-o", tmp_path / "ds", "--allow-outside-paths")
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "ds" / "manifest.json").read_text())["inputs"][0]["recording"] == str(csv_file)
