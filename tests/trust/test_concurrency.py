"""One writer per dataset folder: the build lock, a real race of two builds, and what a failed
build leaves behind."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from conftest import REPO

from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.build import EmptySplitWarning, build_dataset
from kinectdata.dataset.layout import LOCK_OWNER
from kinectdata.dataset.lock import FolderBusyError, build_lock
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.dataset.verify import verify_dataset

SAMPLES = REPO / "sample_data"


def config(ratios: tuple[float, float, float]) -> BuildConfig:
    from kinectdata.features.stft import PRESETS
    from kinectdata.targets.specs import load_target_spec

    return BuildConfig(PRESETS["yalta2016"].to_dict(), load_target_spec("yalta65").to_dict(), split_ratios=ratios)


def test_a_build_into_a_folder_another_build_holds_fails_at_once_naming_it(tmp_path):
    out = tmp_path / "dataset"
    with build_lock(out):
        result = CliRunner().invoke(main, ["build-dataset", str(SAMPLES), "-o", str(out)])
        assert result.exit_code == 1
        line = result.stderr.strip().splitlines()[-1]
        assert "another build is writing this dataset folder" in line and f"process {os.getpid()}" in line
        assert not (out / "manifest.json").exists() and not (out / ".work").exists()
    assert not (out / LOCK_OWNER).exists()  # released: the next build goes ahead
    build_dataset(SAMPLES, out, config((1 / 3, 1 / 3, 1 / 3)))
    assert verify_dataset(out) == []


def test_a_killed_holder_leaves_no_lock(tmp_path):
    """The lock is the kernel's: it dies with the process that held it (as with kill -9)."""
    out = tmp_path / "dataset"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"from kinectdata.dataset.lock import build_lock\nwith build_lock({str(out)!r}):\n    input()",
        ],
        stdin=subprocess.PIPE,
    )
    try:
        for _ in range(200):
            if (out / LOCK_OWNER).exists():
                break
            subprocess.run(["sleep", "0.05"])
        with pytest.raises(FolderBusyError, match=f"process {holder.pid} on"):
            with build_lock(out):
                pass
    finally:
        holder.kill()
        holder.wait()
    assert (out / LOCK_OWNER).exists()  # a killed build cannot tidy up...
    with build_lock(out):  # ...but its lock went with it
        pass


GATED_BUILD = """
import sys, time
from pathlib import Path
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features.stft import PRESETS
from kinectdata.targets.specs import load_target_spec

source, out, gate = sys.argv[1:]
config = BuildConfig(PRESETS["yalta2016"].to_dict(), load_target_spec("yalta65").to_dict(), split_ratios=(1, 1, 1))

def wait_at_gate(done, total):  # called under the lock, after each recording is prepared
    Path(gate + ".reached").touch()
    while not Path(gate).exists():
        time.sleep(0.02)

build_dataset(source, out, config, progress=wait_at_gate)
"""


def test_a_build_racing_one_that_holds_the_folder_is_refused_and_the_folder_is_the_winners(tmp_path):
    """Two processes, one folder, other options: the one that holds the lock (kept inside its build
    by a gate) wins, the other (the command line) exits 1 at once with one line naming the first
    (pid, host, start), and the folder verifies as the winner's dataset alone."""
    out, gate = tmp_path / "dataset", tmp_path / "gate"
    winner = subprocess.Popen([sys.executable, "-c", GATED_BUILD, str(SAMPLES), str(out), str(gate)])
    try:
        deadline = time.monotonic() + 120
        reached = tmp_path / "gate.reached"
        while not reached.exists() and winner.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert reached.exists() and (out / LOCK_OWNER).exists(), "the first build never took the lock"
        before = sorted(p.name for p in out.rglob("*"))
        started = time.monotonic()
        loser = subprocess.run(
            [sys.executable, "-m", "kinectdata", "build-dataset", str(SAMPLES), "-o", str(out)],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert time.monotonic() - started < 60  # refused, not waiting for the first to finish
        assert winner.poll() is None  # the first was still building all along
        assert loser.returncode == 1 and "Traceback" not in loser.stderr
        errors = [line for line in loser.stderr.splitlines() if not line.startswith("warning: ")]
        assert len(errors) == 1, loser.stderr
        assert f"{out}: another build is writing this dataset folder (process {winner.pid} on " in errors[0]
        assert f"on {socket.gethostname()}, started {time.strftime('%Y-')}" in errors[0]
        assert sorted(p.name for p in out.rglob("*")) == before  # the loser touched nothing
    finally:
        gate.touch()
        assert winner.wait(timeout=300) == 0
    assert verify_dataset(out) == []
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["split_ratios"] == [1, 1, 1]  # the winner's build, not the loser's
    assert not (out / LOCK_OWNER).exists()


def test_two_builds_racing_for_one_folder_leave_one_intact_dataset(tmp_path):
    out = tmp_path / "dataset"
    command = [sys.executable, "-m", "kinectdata", "build-dataset", str(SAMPLES), "-o", str(out), "--jobs", "1"]
    runs = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(run.wait(timeout=300), *run.communicate()) for run in runs]
    codes = sorted(code for code, _, _ in results)
    assert codes[0] == 0, results
    for code, _, stderr in results:
        if code != 0:  # the loser: one line, naming the winner
            errors = [line for line in stderr.splitlines() if not line.startswith("warning: ")]
            assert len(errors) == 1 and "another build is writing this dataset folder" in errors[0], stderr
            assert "Traceback" not in stderr
    assert verify_dataset(out) == []


def test_a_failed_build_leaves_no_folder_it_created(tmp_path, monkeypatch):
    import kinectdata.dataset.build as build

    def broken(*args, **kwargs):
        raise RuntimeError("planted failure while preparing")

    monkeypatch.setattr(build, "_prepare_all", broken)
    out = tmp_path / "new" / "dataset"
    with pytest.raises(RuntimeError, match="planted"):
        build_dataset(SAMPLES, out, config((1 / 3, 1 / 3, 1 / 3)))
    assert not out.exists() and not (tmp_path / "new").exists()  # nor the parent it made
    existing = tmp_path / "existing"
    existing.mkdir()
    with pytest.raises(RuntimeError, match="planted"):
        build_dataset(SAMPLES, existing / "a" / "b", config((1 / 3, 1 / 3, 1 / 3)))
    assert existing.is_dir() and list(existing.iterdir()) == []  # the user's folder stays, emptied of ours
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "notes.txt").write_text("the user's")
    with pytest.raises(RuntimeError, match="planted"):
        build_dataset(SAMPLES, kept, config((1 / 3, 1 / 3, 1 / 3)))
    assert (kept / "notes.txt").read_text() == "the user's" and not (kept / ".work").exists()


def test_an_empty_split_is_warned_about_at_build_time(tmp_path):
    with pytest.warns(EmptySplitWarning, match=r"leave the val split empty .*training has no validation loss"):
        build_dataset(SAMPLES, tmp_path / "d", config((0.8, 0.1, 0.1)))
    shutil.rmtree(tmp_path / "d")


def _children(pid: int) -> set[int]:
    found = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            found |= {int(c) for c in (task / "children").read_text().split()}
        except OSError:
            pass
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux's /proc")
@pytest.mark.slow
def test_workers_exit_when_their_build_is_killed(tmp_path):
    subprocess.run(
        [sys.executable, "-m", "kinectdata", "synth", str(tmp_path / "in"), "--count", "4", "--duration", "30"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    build = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "kinectdata",
            "build-dataset",
            str(tmp_path / "in"),
            "-o",
            str(tmp_path / "d"),
            "--jobs",
            "2",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 60
    workers: set[int] = set()
    while len(workers) < 2 and time.monotonic() < deadline and build.poll() is None:
        workers = _children(build.pid)
        time.sleep(0.02)
    assert len(workers) >= 2, "the build never had two workers"
    os.kill(build.pid, signal.SIGKILL)  # the parent only, as a crash or the OOM killer would
    build.wait()
    deadline = time.monotonic() + 10
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers), "workers outlived their build"


def test_a_rerun_removes_what_a_killed_writer_of_the_same_file_left(tmp_path):
    """``align`` killed mid-write leaves ``.out.h5.PID-XXXX.partial``; the next write of out.h5 removes
    it, and leaves alone a live writer's and another file's."""
    from kinectdata.core.atomic import atomic_output

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    orphan = tmp_path / f".out.h5.{dead.pid}-abc123.partial"
    live = tmp_path / f".out.h5.{os.getppid()}-def456.partial"
    other = tmp_path / f".other.h5.{dead.pid}-ghi789.partial"
    for f in (orphan, live, other):
        f.write_bytes(b"half")
    with atomic_output(tmp_path / "out.h5") as tmp:
        tmp.write_bytes(b"whole")
    assert (tmp_path / "out.h5").read_bytes() == b"whole"
    assert not orphan.exists() and live.exists() and other.exists()


def test_the_lock_files_are_not_taken_for_dataset_files(tmp_path):
    """``.build.lock`` stays after a build, and a killed build's ``.build.owner`` too: verify,
    inspect and a rerun of the build ignore both."""
    from kinectdata.dataset.inspect import inspect
    from kinectdata.dataset.layout import LOCK

    out = tmp_path / "dataset"
    build_dataset(SAMPLES, out, config((1 / 3, 1 / 3, 1 / 3)))
    assert (out / LOCK).is_file()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    record = {"pid": dead.pid, "host": socket.gethostname(), "started": "then", "command": "killed"}
    (out / LOCK_OWNER).write_text(json.dumps(record))
    assert verify_dataset(out) == []
    assert "dataset    " in inspect(out)
    result = CliRunner().invoke(main, ["verify", str(out)])
    assert result.exit_code == 0, result.output
    build_dataset(SAMPLES, out, config((1 / 3, 1 / 3, 1 / 3)))  # the rerun: nothing to do, not refused
    assert verify_dataset(out) == [] and not (out / LOCK_OWNER).exists()


def test_a_refusal_names_a_live_holder_at_once_and_skips_a_killed_ones_record(tmp_path):
    from kinectdata.dataset.lock import describe_owner, wait_for_owner

    folder = tmp_path
    live = {"pid": os.getpid(), "host": socket.gethostname(), "started": "2026-01-01 10:00:00 UTC", "command": "x"}
    (folder / LOCK_OWNER).write_text(json.dumps(live))
    started = time.monotonic()
    assert wait_for_owner(folder, wait=5) == live and time.monotonic() - started < 1
    said = describe_owner(live)
    assert said == f"process {os.getpid()} on {socket.gethostname()}, started 2026-01-01 10:00:00 UTC: x"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (folder / LOCK_OWNER).write_text(json.dumps({**live, "pid": dead.pid}))
    assert wait_for_owner(folder, wait=0.2) is None  # a killed build's record names no holder
    elsewhere = {**live, "pid": dead.pid, "host": "another-host.example"}
    (folder / LOCK_OWNER).write_text(json.dumps(elsewhere))
    assert wait_for_owner(folder, wait=0.2) == elsewhere  # another host's processes cannot be checked
    (folder / LOCK_OWNER).write_text('{"pid": 1')
    assert wait_for_owner(folder, wait=0.2) is None


def test_a_filesystem_without_os_locks_stops_the_build_instead_of_a_soft_lock(tmp_path, monkeypatch):
    """A soft lock (a marker file) would outlive a killed build and block its rerun: filelock's
    fallback to it is turned off, and the ENOSYS it then raises is one clear line."""
    import errno

    import kinectdata.dataset.lock as lock_module

    asked = {}

    class NoFlock:
        def __init__(self, path, **options):
            asked.update(options)

        def acquire(self):
            raise OSError(errno.ENOSYS, "Function not implemented")

    monkeypatch.setattr(lock_module, "FileLock", NoFlock)
    with pytest.raises(KinectDataError, match=r"\.build\.lock: the filesystem does not support file locks"):
        with build_lock(tmp_path / "d"):
            pass
    assert asked.get("fallback_to_soft") is False and asked.get("timeout") == 0
    with pytest.raises(KinectDataError, match="does not support file locks"):
        build_dataset(SAMPLES, tmp_path / "new" / "d", config((1 / 3, 1 / 3, 1 / 3)))
    assert not (tmp_path / "new").exists()  # the folders made for the lock went with the failure


def test_an_older_filelock_that_falls_back_to_a_soft_lock_is_refused_too(tmp_path, monkeypatch):
    """filelock releases from before fallback_to_soft either fall back to a marker file on their own
    (those with the soft fallback) or raise NotImplementedError (older ones): either way the build
    stops and leaves no marker."""
    import filelock

    import kinectdata.dataset.lock as lock_module

    def silently_soft(path, timeout, **options):
        if options:
            raise TypeError(f"unexpected keyword argument {next(iter(options))!r}")
        return filelock.SoftFileLock(path, timeout=timeout)

    monkeypatch.setattr(lock_module, "FileLock", silently_soft)
    with pytest.raises(KinectDataError, match="does not support file locks"):
        with build_lock(tmp_path):
            pass
    assert list(tmp_path.iterdir()) == []  # the marker went with the refusal

    class Unimplemented:
        def __init__(self, path, **options):
            pass

        def acquire(self):
            raise NotImplementedError("FileSystem does not appear to support flock; use SoftFileLock instead")

    monkeypatch.setattr(lock_module, "FileLock", Unimplemented)
    with pytest.raises(KinectDataError, match="does not support file locks"):
        with build_lock(tmp_path):
            pass
