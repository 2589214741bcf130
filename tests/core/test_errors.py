"""One error and warning contract: bad settings are ConfigError (a KinectDataError and a ValueError),
every warning is a KinectDataWarning, a damaged file is one clear line, a bug in our own code is not
disguised as damage, and the CLI prints one line for any KinectDataError."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import warnings

import pytest
from click.testing import CliRunner
from conftest import DATA, REPO

import kinectdata
from kinectdata.align import aligned as aligned_module
from kinectdata.align.aligned import AlignedRecording
from kinectdata.align.recipe import align_files
from kinectdata.cli import main
from kinectdata.core.errors import ConfigError, FormatError, KinectDataError, KinectDataWarning
from kinectdata.features import StftConfig
from kinectdata.oni.reader import OniFile
from kinectdata.targets.normalization import Normalizer, NormStats

SAMPLES = REPO / "sample_data"


def test_bad_settings_are_config_errors_and_value_errors():
    for make in (
        lambda: StftConfig(n_fft=64, frame_samples=160),
        lambda: Normalizer.fit(NormStats.from_arrays([[0.0, 1.0], [1.0, 2.0]]), method="standard"),
        lambda: kinectdata.BuildConfig.from_pipeline("yalta2016", compression="zip"),
    ):
        with pytest.raises(ConfigError) as caught:
            make()
        assert isinstance(caught.value, KinectDataError) and isinstance(caught.value, ValueError)


def _package_modules():
    for info in pkgutil.walk_packages(kinectdata.__path__, "kinectdata."):
        if info.name.endswith("__main__"):  # runs the command line when imported
            continue
        try:
            yield importlib.import_module(info.name)
        except ImportError:  # an optional dependency this machine lacks
            continue


def test_every_warning_class_is_a_kinectdata_warning():
    found = []
    for module in _package_modules():
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, Warning) and cls.__module__ == module.__name__:
                found.append(cls)
                assert issubclass(cls, KinectDataWarning), f"{cls.__module__}.{cls.__name__}"
    assert {c.__name__ for c in found} >= {"KinectDataWarning", "OniWarning"}


def test_kinectdata_warnings_can_be_made_errors(tmp_path):
    cut = tmp_path / "cut.oni"
    data = (DATA / "oni" / "openni2_dummy_depth.oni").read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.3)])  # ends inside a frame record
    with warnings.catch_warnings():
        warnings.simplefilter("error", KinectDataWarning)
        with pytest.raises(KinectDataWarning, match="cut.oni: byte .*: the file ends inside"):
            OniFile(cut).close()


def test_a_damaged_aligned_file_is_one_clear_error_and_a_bug_is_not_hidden(tmp_path, monkeypatch):
    path = tmp_path / "a.h5"
    align_files(SAMPLES / "synth_001.csv", SAMPLES / "synth_001.flac", path, offset=-0.8)
    (tmp_path / "junk.h5").write_bytes(b"not hdf5" * 100)
    with pytest.raises(FormatError, match="junk.h5: not a readable HDF5 file"):
        AlignedRecording.load(tmp_path / "junk.h5")

    def broken(*args, **kwargs):
        raise TypeError("a bug in our own code")

    monkeypatch.setattr(aligned_module, "Motion", broken)
    with pytest.raises(TypeError, match="a bug in our own code"):
        AlignedRecording.load(path)


def test_the_cli_prints_one_line_for_a_config_error(tmp_path):
    result = CliRunner().invoke(main, ["build-dataset", str(SAMPLES), "-o", str(tmp_path / "ds"), "--fps", "60"])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "one frame" in lines[0], result.output
    assert "Traceback" not in result.output and not (tmp_path / "ds").exists()
