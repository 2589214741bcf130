"""Every command against the three faults users meet first: an output that cannot be written, an
input that does not exist, and a foreign file where a recording, dataset or run should be.

Each must end with exit status non-zero, one ``Error: ...`` line (after click's usage text for a
usage error), no traceback, and nothing new left where the output would have gone. The list of
commands comes from the click group, so a new command fails here until it has its cases.
"""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import DATA, REPO
from corpus_copies import make_bvh_folder

from kinectdata.cli import all_commands, main

SONG = REPO / "sample_data" / "synth_001.flac"
RECORDING = REPO / "sample_data" / "synth_001.csv"
ONI = DATA / "oni" / "openni2_dummy_depth.oni"


def _mkv_take(path):
    """A small k4arecorder-layout recording (depth only)."""
    from reference.k4a_writer import depth_track, write_k4a

    depth = np.full((3, 6, 8), 1500, np.uint16)
    write_k4a(path, [depth_track("DEPTH", depth, [10**9 + i * 33_333_333 for i in range(3)], "NFOV_UNBINNED")])
    return path


NOT_APPLICABLE = {
    "formats": "reads and writes nothing (lists the shipped readers)",
    "capture": "records from a camera; without one it stops before it writes (tested in tests/capture)",
}
"""Commands with no case here, and why."""


def cases(paths: dict) -> dict[str, dict[str, list]]:
    """Per command, per fault, the arguments; ``out`` is a folder that must stay empty, ``block`` a
    regular file that no output can be written under (even by root, for whom chmod stops nothing)."""
    out, block, missing = paths["out"], paths["block"], paths["missing"]
    junk_file, junk_dir, ds, run = paths["junk_file"], paths["junk_dir"], paths["dataset"], paths["run"]
    return {
        "align": {
            "unwritable": [RECORDING, SONG, "-o", block / "a.h5"],
            "missing": [missing / "take.csv", SONG, "-o", out / "a.h5"],
            "foreign": [junk_file, SONG, "-o", out / "a.h5"],
        },
        "build-dataset": {
            "unwritable": [REPO / "sample_data", "-o", block / "ds"],
            "missing": [missing, "-o", out / "ds"],
            "foreign": [junk_dir, "-o", out / "ds"],
            "a binary manifest": [junk_file, "-o", out / "ds"],
        },
        "evaluate": {
            "unwritable": ["--run", run, "--data", ds, "--out", block / "ev"],
            "missing": ["--run", run, "--data", missing],
            "foreign": ["--run", run, "--data", junk_dir, "--out", out / "ev"],
        },
        "export": {
            "unwritable": ["--run", run, "-o", block / "s.ts"],
            "missing": ["--run", missing, "-o", out / "s.ts"],
            "foreign": ["--run", junk_dir, "-o", out / "s.ts"],
        },
        "generate": {
            "unwritable": ["--run", run, SONG, "-o", block / "g.csv"],
            "missing": ["--run", run, missing / "song.wav", "-o", out / "g.csv"],
            "foreign": ["--run", run, junk_file.with_suffix(".wav"), "-o", out / "g.csv"],
        },
        "info": {"missing": [missing / "take.csv"], "foreign": [junk_file]},
        "live": {  # checked before a frame is danced: nothing waits for the song to end to fail
            "unwritable": ["--run", run, "--input", SONG, "--record", block / "live.h5"],
            "missing": ["--run", missing / "run", "--input", SONG],
            "foreign": ["--run", run, "--input", junk_file.with_suffix(".wav")],
        },
        "inspect": {"missing": [missing], "foreign": [junk_dir]},
        "oni": {
            "unwritable": ["export", ONI, "-o", block / "d.h5"],
            "missing": ["info", missing / "take.oni"],
            "foreign": ["info", junk_file.with_suffix(".oni")],
        },
        "mkv": {
            "unwritable": ["export", paths["mkv_take"], "-o", block / "d.h5"],
            "missing": ["info", missing / "take.mkv"],
            "foreign": ["info", junk_file.with_suffix(".mkv")],
            "a take without calibration, for points": ["export", paths["mkv_take"], "--points", "-o", out / "d.h5"],
        },
        "quickstart": {"unwritable": ["--out", block / "q"]},
        "render": {
            "unwritable": [RECORDING, "-o", block / "r.gif"],
            "missing": [missing / "take.csv", "-o", out / "r.gif"],
            "foreign": [junk_file, "-o", out / "r.gif"],
        },
        "report": {
            "unwritable": [ds, "-o", block / "r.html"],
            "missing": [missing, "-o", out / "r.html"],
            "foreign": [junk_dir, "-o", out / "r.html"],
        },
        "score": {
            "unwritable": [RECORDING, RECORDING, "-o", block / "m.json"],
            "missing": [missing / "gen", RECORDING, "-o", out / "m.json"],
            "foreign": [junk_file.with_suffix(".npy"), RECORDING, "-o", out / "m.json"],
        },
        "folds": {"missing": [missing / "recordings.yaml"], "foreign": [junk_file]},
        "prepare": {
            "unwritable": ["bvh-folder", paths["bvh_corpus"], "-o", block / "r.yaml"],
            "missing": ["aistpp", missing, "-o", out / "r.yaml"],
            "foreign": ["aistpp", junk_dir, "-o", out / "r.yaml"],
        },
        "clean": {
            "unwritable": [RECORDING, "-o", block / "take.csv"],
            "missing": [missing / "take.csv", "-o", out / "take.csv"],
            "foreign": [junk_file, "-o", out / "take.csv"],
        },
        "convert": {
            "unwritable": [RECORDING, "-o", block / "take.bvh"],
            "missing": [missing / "take.csv", "-o", out / "take.bvh"],
            "foreign": [junk_file, "-o", out / "take.npz"],
        },
        "smpl24": {
            "unwritable": [RECORDING, "-o", block / "j.npy"],
            "missing": [missing / "take.csv", "-o", out / "j.npy"],
            "foreign": [junk_file, "-o", out / "j.npy"],
        },
        "sweep": {
            "unwritable": ["--data", ds, "--out", block / "sw"],
            "missing": ["--data", missing, "--out", out / "sw"],
            "foreign": ["--data", junk_dir, "--out", out / "sw"],
        },
        "synth": {"unwritable": [block / "s"]},
        "train-baseline": {
            "unwritable": ["--data", ds, "--out", block / "run"],
            "missing": ["--data", missing, "--out", out / "run"],
            "foreign": ["--data", junk_dir, "--out", out / "run"],
            "unmirrorable": ["--data", ds, "--out", out / "run", "--mirror-share", "0.5"],  # yalta65: orientations
        },
        "verify": {"missing": [missing], "foreign": [junk_dir], "a file": [junk_file]},
    }


@pytest.fixture(scope="module")
def paths(tmp_path_factory, sample_dataset, trained_run):
    root = tmp_path_factory.mktemp("faults")
    rng = np.random.default_rng(7)
    junk = rng.integers(0, 256, 4000, dtype=np.uint8).tobytes()
    junk_dir = root / "foreign"
    junk_dir.mkdir()
    for name in ("foreign.csv", "foreign.wav", "foreign.oni", "foreign.mkv", "foreign.npy"):
        (root / name).write_bytes(junk)
    for name in ("manifest.json", "config.json", "model.pt", "photo.png"):
        (junk_dir / name).write_bytes(junk)
    (root / "block").write_text("a regular file: nothing can be written under it\n")
    return {
        "root": root,
        "out": root / "out",
        "block": root / "block",
        "missing": root / "no_such_thing",
        "junk_file": root / "foreign.csv",
        "junk_dir": junk_dir,
        "dataset": sample_dataset,
        "run": trained_run[0],
        "bvh_corpus": make_bvh_folder(root, seconds=1.0),
        "mkv_take": _mkv_take(root / "take.mkv"),
    }


def test_every_command_has_its_cases():
    assert set(all_commands()) == set(cases(PLACEHOLDERS)) | set(NOT_APPLICABLE)


def test_the_table_of_commands_is_the_modules_own():
    """The CLI imports a command's module when it runs: its table names each module's commands, all of them."""
    import importlib
    import pkgutil

    import kinectdata.cli as cli

    found = {}
    for info in pkgutil.iter_modules(cli.__path__):
        module = importlib.import_module(f"kinectdata.cli.{info.name}")
        found |= {command.name: info.name for command in getattr(module, "COMMANDS", [])}
    assert found == cli.COMMAND_MODULES


PLACEHOLDERS = dict.fromkeys(
    ["out", "block", "missing", "junk_file", "junk_dir", "dataset", "run", "bvh_corpus", "mkv_take"], REPO
)
ALL = [(command, fault) for command, faults in cases(PLACEHOLDERS).items() for fault in faults]


@pytest.mark.parametrize(("command", "fault"), ALL, ids=[f"{c}-{f}" for c, f in ALL])
def test_a_fault_is_one_line_and_leaves_nothing(command, fault, paths):
    out = paths["out"]
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    before = sorted(os.listdir(paths["root"]))
    args = [command, *map(str, cases(paths)[command][fault])]
    result = CliRunner().invoke(main, args)
    assert result.exit_code != 0, (args, result.output)
    assert isinstance(result.exception, SystemExit), (args, repr(result.exception))  # handled, not raised
    errors = [line for line in result.stderr.splitlines() if not line.startswith("warning: ")]
    assert "Traceback" not in result.output and "Traceback" not in result.stderr
    if result.exit_code == 2:  # click's usage error: usage text, then one Error line
        assert errors[-1].startswith("Error: "), result.stderr
    else:
        assert len(errors) == 1 and errors[0].startswith("Error: "), (args, result.stderr)
        assert "internal error" not in errors[0], errors[0]  # a fault of the input, not a bug
    if fault == "a file":
        assert "a file, not a dataset folder" in result.output
    assert os.listdir(out) == [], f"{args} left {os.listdir(out)}"
    assert sorted(os.listdir(paths["root"])) == before


def test_an_unexpected_exception_is_one_line_naming_its_saved_traceback(monkeypatch, tmp_path):
    import kinectdata.cli.info as info

    def broken():
        raise ZeroDivisionError("planted")

    monkeypatch.setattr(info, "readers", broken)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # gettempdir() reads TMPDIR again
    result = CliRunner().invoke(main, ["formats"])
    assert result.exit_code == 70 and isinstance(result.exception, SystemExit)
    line = result.stderr.strip()
    assert "\n" not in line and "internal error, a bug in kinectdata" in line and "ZeroDivisionError: planted" in line
    saved = list(tmp_path.glob("kinectdata-crash-*.txt"))
    assert len(saved) == 1 and str(saved[0]) in line
    text = saved[0].read_text()
    assert "Traceback (most recent call last)" in text and "in broken" in text and "ZeroDivisionError: planted" in text


def test_an_os_error_names_its_path_and_reason(monkeypatch):
    import kinectdata.cli.info as info

    def full_disk():
        raise OSError(28, "No space left on device", "/data/out.h5")

    monkeypatch.setattr(info, "readers", full_disk)
    result = CliRunner().invoke(main, ["formats"])
    assert result.exit_code == 1
    assert result.stderr.strip() == "Error: /data/out.h5: No space left on device"
