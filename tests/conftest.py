"""Shared test fixtures: paths to the bundled real files and small generated recordings."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# pytest-xdist runs one worker per core (pyproject's addopts): each worker computes on one thread,
# as do the commands it starts, since two workers of several threads each on two cores spend their
# time waiting for each other (torch's OpenMP threads spin). Set before torch is imported.
if os.environ.get("PYTEST_XDIST_WORKER"):
    for variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[variable] = "1"

# The suite's outputs are thrown away: written atomically as always, but not flushed to disk
# (kinectdata.core.atomic.durable), which on a virtual disk was about 45 s of a 6-minute run.
# Set here, so that the commands the tests start inherit it; tests/core/test_atomic.py checks both ways.
os.environ.setdefault("KINECTDATA_FSYNC", "0")

# CI runs the property tests on a fixed set of examples, so a landing does not depend on luck;
# a local run explores new examples each time (and keeps failures in .hypothesis/).
settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI"):
    settings.load_profile("ci")

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).parent.parent
if str(REPO) not in sys.path:  # the independent references in reference/ (not shipped)
    sys.path.append(str(REPO))  # appended: the installed kinectdata still comes first
# the fuzz tests (trust/) write files with the readers' test builders (formats/test_*.py): importable
# by name whichever test runs first or alone
if str(DATA.parent / "formats") not in sys.path:
    sys.path.append(str(DATA.parent / "formats"))


@pytest.fixture
def fixture_csv() -> Path:
    """A real Kinect v2 recording in the KinectReader dialect (MIT, see tests/data/kinect_v2_csv)."""
    return DATA / "kinect_v2_csv" / "Ges01_wavehand.csv"


TINY_TRAINING = {
    "units": 32,
    "sequence": 30,
    "stride": 30,
    "batch_size": 8,
    "epochs": 2,
    "lr": 3e-3,
    "noise_eta": 0.0,
    "free_weight": 0.0,
    "silence_share": 0.0,
    "keep": "last",
    "precision": "float32",  # the same arithmetic on every machine
}
"""A training small enough for tests (about a second): 32 units, 30-frame sequences, no noise, the
teacher-forced loss alone (tests/training/test_real_dance_recipe.py trains the rest)."""


@pytest.fixture
def one_thread():
    """torch on one thread for the test: small tensors compute fastest so, and two threads stall
    badly when the other core is busy."""
    torch = pytest.importorskip("torch")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def sample_dataset(tmp_path_factory) -> Path:
    """The three bundled sample sessions as a dataset, one per split: train synth_003, val synth_001,
    test synth_002 (yalta2016 features, yalta65 targets)."""
    from kinectdata.dataset.build import build_dataset
    from kinectdata.dataset.prepare import BuildConfig
    from kinectdata.features.stft import PRESETS
    from kinectdata.targets.specs import load_target_spec

    out = tmp_path_factory.mktemp("sample_dataset") / "dataset"
    config = BuildConfig(
        features=PRESETS["yalta2016"].to_dict(),
        target=load_target_spec("yalta65").to_dict(),
        split_ratios=(1 / 3, 1 / 3, 1 / 3),
    )
    manifest = build_dataset(REPO / "sample_data", out, config)
    assert {s: v["recordings"] for s, v in manifest["splits"].items()} == {
        "train": ["synth_003"],
        "val": ["synth_001"],
        "test": ["synth_002"],
    }
    return out


@pytest.fixture(scope="session")
def trained_run(sample_dataset, tmp_path_factory):
    """(run folder, log rows) of a TINY_TRAINING run (predicted feedback) on the sample dataset."""
    pytest.importorskip("torch")
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    run = tmp_path_factory.mktemp("trained") / "run"
    history = train(sample_dataset, run, TrainConfig(**TINY_TRAINING))
    return run, history


HARDWARE = "hardware:"
"""Skip reasons starting with this name hardware a CI machine cannot have (an audio input device)."""


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Under CI, a skipped test fails unless its reason names missing hardware: ``.ci/run`` installs
    every package and system library the tests use, so any other skip is a broken install that
    would otherwise pass unseen."""
    outcome = yield
    _fail_a_ci_skip(outcome.get_result())


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """The same for a whole module skipped while collected (``pytest.importorskip`` at its top)."""
    outcome = yield
    _fail_a_ci_skip(outcome.get_result())


def _fail_a_ci_skip(report) -> None:
    if not (os.environ.get("CI") and report.skipped) or hasattr(report, "wasxfail"):
        return
    reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
    if not reason.removeprefix("Skipped: ").startswith(HARDWARE):
        report.outcome = "failed"
        report.longrepr = f"skipped under CI, where .ci/run installs every dependency: {reason}"


def pytest_addoption(parser):
    parser.addoption(
        "--slow",
        action="store_true",
        help="also run the long end-to-end tests (marked slow): what CI=1 (.ci/run) runs",
    )


@pytest.fixture(scope="module")
def centred_run(tmp_path_factory):
    """(run, dataset): a tiny yalta run on the sample sessions' joint positions centred on the root,
    its turning and travel fitted (the tests of what a run draws at generation)."""
    pytest.importorskip("torch")
    from kinectdata.dataset.build import build_dataset
    from kinectdata.dataset.config import BuildConfig
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    out = tmp_path_factory.mktemp("centred")
    config = BuildConfig.from_pipeline(
        "yalta2016", target="kinect_v2_positions", normalisation="maxabs", root_centre=True,
        split_ratios=(1 / 3, 1 / 3, 1 / 3),
    )  # fmt: skip
    build_dataset(REPO / "sample_data", out / "dataset", config)
    train(out / "dataset", out / "run", TrainConfig(**{**TINY_TRAINING, "epochs": 1}))
    return out / "run", out / "dataset"


@pytest.fixture(scope="module")
def sample_song(tmp_path_factory):
    """The first 6 s of a sample session's song (a WAV file): long enough for every drawn process,
    short to dance to."""
    import soundfile as sf

    samples, sr = sf.read(REPO / "sample_data" / "synth_001.flac", dtype="float32")
    path = tmp_path_factory.mktemp("song") / "song.wav"
    sf.write(path, samples[: 6 * sr], sr)
    return path


def _slow_tests_run(config) -> bool:
    """The long end-to-end tests (marked ``slow``) run under CI, with ``--slow``, when ``-m``
    chooses by marker, or when tests are named (``file.py::test``); a plain ``pytest`` leaves them
    out, to stay within minutes."""
    named = any("::" in arg for arg in config.args)
    return bool(os.environ.get("CI") or config.getoption("--slow") or config.getoption("markexpr") or named)


def stale_install(installed: Path, source: Path) -> str:
    """Why the ``installed`` kinectdata package folder is not the checkout's ``source`` one ("" when
    it is the same folder, or holds every module of it byte for byte): the tests import the
    installed package first, and an install made before the last change tests the code before it."""
    if installed.resolve() == source.resolve():
        return ""
    for path in sorted(source.rglob("*.py")):
        other = installed / path.relative_to(source)
        if not other.is_file() or other.read_bytes() != path.read_bytes():
            name = path.relative_to(source.parent)
            said = (
                f"which lacks this checkout's {name}" if not other.is_file() else f"whose {name} is not this checkout's"
            )
            return f"the tests would import kinectdata from {installed}, {said}: install it again (pip install -e .)"
    return ""


def pytest_configure(config):
    """Stop before collecting when the kinectdata the tests import is not this checkout's."""
    found = importlib.util.find_spec("kinectdata")
    if found is not None and found.origin is not None:
        why = stale_install(Path(found.origin).parent, REPO / "kinectdata")
        if why:
            pytest.exit(why, returncode=4)


def pytest_collection_modifyitems(config, items):
    """Without :func:`_slow_tests_run`, the long tests are deselected. With it, they run first, the
    others in their order: each core's worker takes work from the other when idle (``--dist
    worksteal``), so the run ends with short tests on both cores instead of one long test begun last
    on one."""
    if not _slow_tests_run(config):
        slow = [item for item in items if item.get_closest_marker("slow") is not None]
        if slow:
            config.hook.pytest_deselected(items=slow)
            items[:] = [item for item in items if item.get_closest_marker("slow") is None]
        return
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


def pytest_terminal_summary(terminalreporter, config):
    if not _slow_tests_run(config):
        terminalreporter.write_line(
            "the long end-to-end tests (marked slow) were not run: `pytest --slow` runs them, as CI does (CI=1)"
        )
