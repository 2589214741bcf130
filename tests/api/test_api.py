"""The Python API (docs/api.md): its script runs, its names resolve, ``import kinectdata`` stays cheap,
and the rate checks, pipelines and summaries behave as documented."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

import kinectdata as kd
from kinectdata.core.errors import ConfigError, KinectDataError

SAMPLES = REPO / "sample_data"


def _python_blocks(doc: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", doc.read_text(), re.S)


def test_the_api_page_runs(tmp_path, monkeypatch, capsys):
    pytest.importorskip("torch")
    (tmp_path / "sample_data").symlink_to(SAMPLES)
    monkeypatch.chdir(tmp_path)
    blocks = _python_blocks(REPO / "docs" / "api.md")
    assert len(blocks) == 2
    for i, block in enumerate(blocks):
        exec(compile(block, f"docs/api.md python block {i}", "exec"), {})
    out = capsys.readouterr().out
    assert "(649, 1, 129, 5)" in out and "(649, 65)" in out and "\n0.9\n" in out
    assert "22050 Hz, this recording's audio is at 16000 Hz" in out
    assert (tmp_path / "dataset" / "manifest.json").is_file()


def test_every_name_of_the_api_resolves():
    pytest.importorskip("torch")
    for name in kd.__all__:
        assert getattr(kd, name) is not None, name
    assert set(dir(kd)) >= set(kd.__all__)
    with pytest.raises(AttributeError):
        kd.no_such_name  # noqa: B018


def _modules_after(code: str) -> dict:
    probe = f"""
import json, sys
{code}
mods = sorted(sys.modules)
print(json.dumps({{"all": mods}}))
"""
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(json.loads(out.stdout)["all"])


def test_import_kinectdata_loads_no_heavy_library():
    loaded = _modules_after("import kinectdata")
    assert not loaded & {"torch", "h5py", "pandas", "scipy", "matplotlib", "kinectdata.formats"}


def test_the_windows_dataset_imports_no_reader():
    pytest.importorskip("torch")
    loaded = _modules_after("from kinectdata.dataset import WindowDataset")
    ours = {m for m in loaded if m.startswith("kinectdata")}
    assert "pandas" not in loaded and not any(m.startswith("kinectdata.formats") for m in ours)
    assert ours <= {"kinectdata", "kinectdata.core", "kinectdata.core.errors", "kinectdata.core.version"} | {
        "kinectdata.dataset",
        "kinectdata.dataset.layout",
        "kinectdata.dataset.windows",
    }


def test_build_config_from_a_pipeline_with_overrides():
    ltd = kd.BuildConfig.from_pipeline("listen-to-dance")
    assert ltd.features.extractor == "mel" and ltd.target.name == "listen_to_dance" and ltd.normalisation == "none"
    c = kd.BuildConfig.from_pipeline("yalta2016", features="motion_dance", normalisation="minmax", seed=None)
    assert c.features == kd.FEATURE_PRESETS["motion_dance"] and c.normalisation == "minmax" and c.seed == 0
    assert c.to_dict()["features"] == kd.FEATURE_PRESETS["motion_dance"].to_dict()
    with pytest.raises(ConfigError, match="unknown pipeline 'ballet'; known: listen-to-dance, yalta2016"):
        kd.BuildConfig.from_pipeline("ballet")
    with pytest.raises(ConfigError, match="no field colour"):
        kd.BuildConfig.from_pipeline("yalta2016", colour="red")
    with pytest.raises(ConfigError, match="unknown feature preset"):
        kd.BuildConfig.from_pipeline("yalta2016", features="mfcc")
    with pytest.raises(ConfigError, match="one frame"):  # 534-sample slices are 30 fps, not 60
        kd.BuildConfig.from_pipeline("yalta2016", fps=60)


def test_features_refuse_a_recording_of_another_frame_rate(tmp_path):
    rec = kd.align_files(SAMPLES / "synth_001.csv", SAMPLES / "synth_001.flac", tmp_path / "a.h5", fps=60)
    with pytest.raises(ConfigError, match="this recording has 60 fps"):
        kd.recording_features(rec, kd.FEATURE_PRESETS["yalta2016"])
    with pytest.raises(KinectDataError, match="44100 Hz, this recording's audio is at 16000 Hz"):
        rec.frame_starts(44100)
    starts = rec.frame_starts(16000, 267)  # 267 samples: one frame at 60 fps
    np.testing.assert_array_equal(starts, np.round(np.arange(rec.n_frames) * 16000 / 60))


def test_recording_features_equal_the_built_dataset_rows(tmp_path):
    """The whole-recording path (``recording_features``) and the build's streamed one agree."""
    import h5py

    rec = kd.align_files(SAMPLES / "synth_002.csv", SAMPLES / "synth_002.flac", tmp_path / "aligned" / "s.h5")
    config = kd.BuildConfig.from_pipeline("yalta2016", split_ratios=(1, 0, 0))
    kd.build_dataset(tmp_path / "aligned", tmp_path / "ds", config)
    features, padded = kd.recording_features(rec, config.features)
    with h5py.File(tmp_path / "ds" / "train-00000.h5") as f:
        np.testing.assert_allclose(f["input"][()], features, rtol=0, atol=1e-6)
        np.testing.assert_array_equal(f["audio_padded"][()], padded)


def test_summaries_are_one_short_line(tmp_path):
    rec = kd.align_files(SAMPLES / "synth_001.csv", SAMPLES / "synth_001.flac", offset=-0.8)
    for value in (rec, rec.motion, kd.BuildConfig.from_pipeline("yalta2016")):
        text = repr(value)
        assert "\n" not in text and len(text) < 200 and "array(" not in text, text
