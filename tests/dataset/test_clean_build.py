"""build-dataset --clean and a manifest's ``clean``: the dataset a cleaned recording gives."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from conftest import REPO

import kinectdata as kd
from kinectdata.core.errors import ConfigError, SchemaError
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.config import BuildConfig
from kinectdata.dataset.inputs import read_recordings

pytestmark = pytest.mark.filterwarnings("ignore::kinectdata.dataset.build.EmptySplitWarning")  # one training recording

SESSION = REPO / "sample_data" / "synth_001"
OFFSET = json.loads(SESSION.with_suffix(".truth.json").read_text())["offset_s"]


def _config(**kw) -> BuildConfig:
    return BuildConfig.from_pipeline("yalta2016", target="positions", **kw)


def _manifest(path, recording, **entry):
    doc = [{"recording": str(recording), "audio": str(SESSION.with_suffix(".flac")), "split": "train",
            "offset": OFFSET, "name": "synth_001", **entry}]  # fmt: skip
    path.write_text(json.dumps(doc))
    return path


def _targets(folder, manifest):
    record = manifest["recordings"][0]
    with h5py.File(folder / record["shard"], "r") as f:
        return f["current"][record["start"] : record["start"] + record["frames"]].astype(np.float64)


def test_a_build_with_clean_equals_a_build_of_the_recording_cleaned_first(tmp_path):
    """The build that cleans (--clean) against the plain build of the same recording cleaned by
    kd.clean_motion and written as a canonical CSV: the same targets (to the CSV's six decimals);
    and the build without cleaning differs."""
    cleaned = kd.clean_motion(kd.read_motion(SESSION.with_suffix(".csv"))).motion
    kd.write_motion(cleaned, tmp_path / "synth_001.csv")
    raw = _manifest(tmp_path / "raw.json", SESSION.with_suffix(".csv"))
    first = _manifest(tmp_path / "first.json", tmp_path / "synth_001.csv")
    with_clean = build_dataset(raw, tmp_path / "with_clean", _config(clean={}), allow_outside_paths=True)
    cleaned_first = build_dataset(first, tmp_path / "cleaned_first", _config(), allow_outside_paths=True)
    plain = build_dataset(raw, tmp_path / "plain", _config(), allow_outside_paths=True)
    a, b = _targets(tmp_path / "with_clean", with_clean), _targets(tmp_path / "cleaned_first", cleaned_first)
    np.testing.assert_allclose(a, b, atol=2e-5)
    assert np.abs(a - _targets(tmp_path / "plain", plain)).max() > 1e-3
    assert with_clean["config"]["clean"] == {} and "clean" not in plain["config"]


def test_a_manifest_entry_says_for_itself(tmp_path):
    """clean: false wins over the build's --clean; clean: {settings} over its defaults."""
    raw = SESSION.with_suffix(".csv")
    plain = build_dataset(_manifest(tmp_path / "p.json", raw), tmp_path / "plain", _config(), allow_outside_paths=True)
    opted_out = build_dataset(_manifest(tmp_path / "o.json", raw, clean=False), tmp_path / "out", _config(clean={}),
                              allow_outside_paths=True)  # fmt: skip
    np.testing.assert_array_equal(_targets(tmp_path / "out", opted_out), _targets(tmp_path / "plain", plain))
    own = build_dataset(_manifest(tmp_path / "s.json", raw, clean={"jitter": "none", "bones": False}),
                        tmp_path / "own", _config(), allow_outside_paths=True)  # fmt: skip
    gaps_only = kd.clean_motion(kd.read_motion(raw), kd.CleanConfig(jitter="none", bones=False)).motion
    kd.write_motion(gaps_only, tmp_path / "synth_001.csv")
    first = build_dataset(_manifest(tmp_path / "f.json", tmp_path / "synth_001.csv"), tmp_path / "first", _config(),
                          allow_outside_paths=True)  # fmt: skip
    np.testing.assert_allclose(_targets(tmp_path / "own", own), _targets(tmp_path / "first", first), atol=2e-5)


def test_a_work_file_is_keyed_on_the_cleaning_that_ran_not_on_todays_defaults(tmp_path):
    """``clean: {}`` asks for the defaults: its work files are keyed on every setting, so that the
    same settings spelt out give the same key, and a default changed since (the jitter filter was
    Butterworth before the Wiener smoother) is not taken for the cleaning an old work file had."""
    from kinectdata.dataset.prepare import unit_key

    entry = read_recordings(_manifest(tmp_path / "m.json", SESSION.with_suffix(".csv")), allow_outside_paths=True)[0]

    def key(clean):
        return unit_key(entry, {"motion": "h"}, _config(clean=clean), None)

    assert key({}) == key({"jitter": "wiener", "cutoff_hz": 6.0}) == key(kd.CleanConfig().resolved())
    assert key({}) != key({"jitter": "butterworth"}) and key({}) != key(None)


def test_bad_cleaning_settings_are_one_line(tmp_path):
    raw = SESSION.with_suffix(".csv")
    with pytest.raises(SchemaError, match="clean"):
        read_recordings(_manifest(tmp_path / "bad.json", raw, clean={"jitter": "median"}), allow_outside_paths=True)
    with pytest.raises(ConfigError, match="clean: no cleaning setting smoothness"):
        _config(clean={"smoothness": 3})
    csv = tmp_path / "bad.csv"
    csv.write_text(f"recording,audio,clean\n{raw},{SESSION.with_suffix('.flac')},maybe\n")
    with pytest.raises(SchemaError, match="line 2.*clean 'maybe' is neither true nor false"):
        read_recordings(csv, allow_outside_paths=True)
    csv.write_text(f"recording,audio,clean\n{raw},{SESSION.with_suffix('.flac')},yes\n")
    assert read_recordings(csv, allow_outside_paths=True)[0].clean is True
