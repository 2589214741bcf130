"""Faults: kill -9 of build-dataset and train-baseline at random points, a full disk, and verify."""

from __future__ import annotations

import csv
import errno
import json
import os
import pathlib
import random
import resource
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from kinectdata.cli import main
from kinectdata.core.atomic import write_failure
from kinectdata.core.errors import FormatError, SchemaError
from kinectdata.dataset.prepare import WORK_FORMAT
from kinectdata.dataset.shards import validate_shard
from kinectdata.dataset.verify import verify_dataset

BUILD_OPTIONS = ["--augment-snr", "5,10,20", "--shard-size", "3"]  # 9 variants in 4 shards: work to interrupt
ONE_THREAD = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}  # fast on shared cores, same sums


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def sessions(tmp_path_factory) -> Path:
    """Three synthetic 10 s sessions (Kinect v2 CSV + 16 kHz FLAC)."""
    folder = tmp_path_factory.mktemp("fault_sessions")
    result = run("synth", folder, "--count", 3, "--duration", 10, "--sample-rate", 16000)
    assert result.exit_code == 0, result.output
    return folder


@pytest.fixture(scope="module")
def reference(sessions, tmp_path_factory) -> Path:
    """The uninterrupted build of ``sessions`` with BUILD_OPTIONS (work files kept, to size them)."""
    out = tmp_path_factory.mktemp("fault_reference") / "dataset"
    result = run("build-dataset", sessions, "-o", out, *BUILD_OPTIONS, "--keep-work")
    assert result.exit_code == 0, result.output
    return out


def _build_command(sessions: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "kinectdata", "build-dataset", str(sessions), "-o", str(out), *BUILD_OPTIONS, *extra]


def _manifest(folder: Path) -> dict:
    return json.loads((folder / "manifest.json").read_text())


def _assert_nothing_damaged(out: Path) -> None:
    """What an interrupted build may leave: complete shards and work files, hidden ``.partial`` files,
    and a manifest only when the whole dataset is there."""
    for shard in out.glob("*.h5"):
        validate_shard(shard)
    for work in (out / ".work").glob("*.h5"):
        with h5py.File(work, "r") as f:
            assert f.attrs["format"] == WORK_FORMAT, work
            n = f["targets"].shape[0]
            assert f["input"][()].shape[0] == f["mask"][()].shape[0] == f["audio_padded"][()].shape[0] == n, work
    if (out / "manifest.json").exists():
        assert verify_dataset(out) == []


def _arrays(shard: Path) -> dict[str, np.ndarray]:
    found: dict[str, np.ndarray] = {}
    with h5py.File(shard, "r") as f:
        f.visititems(lambda name, item: found.update({name: item[()]}) if isinstance(item, h5py.Dataset) else None)
    return found


def _assert_same_dataset(out: Path, reference: Path) -> None:
    """Same manifest (so the same SHA-256 per shard) and the same arrays in every shard."""
    manifest = _manifest(out)
    assert manifest == _manifest(reference)
    for shard in manifest["shards"]:
        ours, theirs = _arrays(out / shard["file"]), _arrays(reference / shard["file"])
        assert ours.keys() == theirs.keys()
        for name in ours:
            assert ours[name].dtype == theirs[name].dtype and np.array_equal(ours[name], theirs[name]), name
    assert not list(out.rglob("*.partial")) and not (out / ".work").exists()


def _kill_when(command: list[str], ready: Callable[[], bool], after: float = 0.0, env=None) -> int | None:
    """Run ``command`` in its own process group and kill -9 the group once ``ready()`` holds and
    ``after`` more seconds passed; returns the exit status if it ended first, else None."""
    proc = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True, env=env
    )
    try:
        deadline = time.monotonic() + 120
        while not ready() and proc.poll() is None:
            assert time.monotonic() < deadline, f"{command} never reached the point to kill it at"
            time.sleep(0.002)
        time.sleep(after)
        if proc.poll() is not None:
            return proc.returncode
        os.killpg(proc.pid, signal.SIGKILL)  # the workers of --jobs too
        proc.wait()
        return None
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


@pytest.mark.slow
def test_kill_9_at_any_point_leaves_no_damaged_file_and_a_rerun_gives_the_same_arrays(sessions, reference, tmp_path):
    out = tmp_path / "dataset"
    rng = random.Random(8)
    points: list[tuple[str, Callable[[], bool], float]] = [
        ("while writing a work file", lambda: any((out / ".work").glob(".synth_*.h5.*.partial")), 0.0),
        ("while writing a shard", lambda: any(out.glob(".train-*.h5.*.partial")), 0.0),
        ("just after a shard was renamed into place", lambda: any(out.glob("*.h5")), 0.0),
    ]
    points += [
        (f"{delay:.2f} s after the start", lambda: True, delay) for delay in (rng.uniform(0.3, 3) for _ in range(3))
    ]
    killed = []
    for i, (where, ready, after) in enumerate(points):
        jobs = ["--jobs", "2"] if i % 2 else []
        status = _kill_when(_build_command(sessions, out, *jobs), ready, after)
        _assert_nothing_damaged(out)
        if status is None:
            killed.append(where)
        else:  # it finished before the kill: start again from nothing
            assert status == 0
            _assert_same_dataset(out, reference)
            shutil.rmtree(out)
    assert len(killed) >= 3, killed  # at least the three chosen points
    result = subprocess.run(_build_command(sessions, out), capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    _assert_same_dataset(out, reference)


def _file_size_limit(limit: int) -> Callable[[], None]:
    def apply() -> None:  # in the child: writes past `limit` bytes fail with EFBIG, as on a full disk
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


def test_a_full_disk_is_a_clear_error_and_leaves_no_partial_output(sessions, reference, tmp_path):
    """Writes refused at the audio cache, a work file and a shard in turn (each limit between the sizes
    of the files written before and that one); the work files that were completed stay, as resuming needs."""
    import soundfile as sf

    cache = 4 * max(sf.info(p).frames for p in sessions.glob("*.flac"))  # float32 at the 16 kHz of the build
    work = sorted(p.stat().st_size for p in (reference / ".work").glob("*.h5"))
    first_shard = (reference / "train-00000.h5").stat().st_size
    assert cache < work[0] and work[-1] < first_shard
    out = tmp_path / "dataset"
    for limit, written in [
        (cache // 2, out / ".work" / ".synth_000.audio-f32."),
        ((cache + work[0]) // 2, out / ".work" / "synth_000.h5"),
        ((work[-1] + first_shard) // 2, out / "train-00000.h5"),
    ]:
        result = subprocess.run(
            _build_command(sessions, out), capture_output=True, text=True, preexec_fn=_file_size_limit(limit)
        )
        assert result.returncode == 1, result.stderr
        assert f"{written}" in result.stderr and "could not be written: the disk is full" in result.stderr
        assert "Traceback" not in result.stderr
        assert not list(out.rglob("*.partial")) and not (out / "manifest.json").exists()
        _assert_nothing_damaged(out)
    assert len(list((out / ".work").glob("*.h5"))) == len(work)  # all prepared before the shards failed
    result = run("build-dataset", sessions, "-o", out, *BUILD_OPTIONS)
    assert result.exit_code == 0, result.output
    _assert_same_dataset(out, reference)


def test_a_full_disk_at_the_manifest_keeps_no_manifest(sessions, reference, tmp_path, monkeypatch):
    out = tmp_path / "dataset"
    shutil.copytree(reference, out)
    (out / "manifest.json").unlink()  # the shards and work files are there: only the manifest is left to write
    real = pathlib.Path.write_text

    def full_disk(self, *args, **kwargs):
        if self.name.startswith(".manifest.json."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "write_text", full_disk)
    result = run("build-dataset", sessions, "-o", out, *BUILD_OPTIONS)
    assert result.exit_code == 1
    assert f"{out / 'manifest.json'}: could not be written: the disk is full" in result.output
    assert "No space left on device" in result.output
    assert not (out / "manifest.json").exists() and not list(out.rglob("*.partial"))
    _assert_nothing_damaged(out)
    monkeypatch.setattr(pathlib.Path, "write_text", real)
    assert run("build-dataset", sessions, "-o", out, *BUILD_OPTIONS).exit_code == 0
    _assert_same_dataset(out, reference)


def test_write_failure_recognises_full_disks_only():
    h5py_style = RuntimeError("Can't decrement id ref count (unable to extend file, errno = 28, error message = '')")
    assert "x.h5: could not be written" in str(write_failure("x.h5", h5py_style))
    assert "File too large" in str(write_failure("x.h5", OSError(errno.EFBIG, "File too large")))
    assert write_failure("x.h5", OSError(errno.EACCES, "Permission denied")) is None
    assert write_failure("x.h5", RuntimeError("errno = 2, no such file")) is None
    assert write_failure("x.h5", ValueError("errno = 28")) is None


def _damage(dataset: Path, into: Path) -> Path:
    """A copy of ``dataset`` with four problems: one shard's bytes changed, one gone, one row more
    in the totals and a recording's frames misstated."""
    copy = into / "damaged"
    shutil.copytree(dataset, copy, ignore=shutil.ignore_patterns(".work"))
    manifest = _manifest(copy)
    first, second = manifest["shards"][0]["file"], manifest["shards"][1]["file"]
    with h5py.File(copy / first, "a") as f:
        f["current"][0, 0] += 0.5
    (copy / second).unlink()
    manifest["totals"]["rows"] += 1
    manifest["recordings"][-1]["frames"] += 3
    (copy / "manifest.json").write_text(json.dumps(manifest))
    return copy


def test_verify_reports_every_problem_each_naming_its_file(reference, tmp_path):
    result = run("verify", reference)
    assert result.exit_code == 0 and "intact, 4 shards" in result.output
    damaged = _damage(reference, tmp_path)
    manifest = _manifest(damaged)
    shards = [s["file"] for s in manifest["shards"]]
    last = manifest["recordings"][-1]
    problems = [str(p) for p in verify_dataset(damaged)]
    assert problems == [
        f"{damaged / 'manifest.json'}: totals.rows is {manifest['totals']['rows']}, the shards hold "
        f"{manifest['totals']['rows'] - 1}",
        f"{damaged / shards[0]}: checksum differs from the manifest's: the shard was changed or damaged",
        f"{damaged / shards[1]}: missing: manifest.json lists it (train split, {manifest['shards'][1]['frames']} rows)",
        f"{damaged / 'manifest.json'}: its recordings in {last['shard']} ([('{last['name']}', 0, "
        f"{last['frames']})]...) differ from the shard's own index ([('{last['name']}', 0, {last['frames'] - 3})]...)",
    ]
    result = run("verify", damaged)
    assert result.exit_code == 1
    assert all(p in result.output for p in problems) and "4 problems found" in result.output
    with pytest.raises(FormatError, match=r"totals\.rows .* \(and 3 more problems: kinectdata verify .* lists them\)"):
        from kinectdata.dataset.inspect import inspect

        inspect(damaged)


def test_verify_lists_every_schema_violation_and_still_checks_the_shards(reference, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(reference, copy, ignore=shutil.ignore_patterns(".work"))
    manifest = _manifest(copy)
    del manifest["totals"]
    manifest["shards"][0]["sha256"] = "not a checksum"
    (copy / "manifest.json").write_text(json.dumps(manifest))
    with h5py.File(copy / manifest["shards"][1]["file"], "a") as f:
        del f["mask"]
    problems = verify_dataset(copy)
    assert [type(p) for p in problems] == [SchemaError, SchemaError, FormatError]
    assert "at (top level): 'totals' is a required property" in str(problems[0])
    assert "at shards/0/sha256: 'not a checksum' does not match" in str(problems[1])
    assert str(problems[2]) == f"{copy / manifest['shards'][1]['file']}: missing dataset 'mask'"
    (copy / "manifest.json").write_text("{")
    assert [str(p) for p in verify_dataset(copy)][0].startswith(f"{copy / 'manifest.json'}: not valid JSON")
    (copy / "manifest.json").unlink()
    assert "no manifest.json: not a dataset" in str(verify_dataset(copy)[0])
    result = run("verify", tmp_path / "nowhere")
    assert result.exit_code == 1 and "nowhere: not a dataset folder" in result.output


def _train_command(data: Path, run_dir: Path, *extra: str) -> list[str]:
    settings = ["--units", "32", "--sequence", "30", "--batch-size", "8", "--epochs", "2", "--lr", "3e-3"]
    noise = ["--noise-eta", "1e-4", "--clip-norm", "1.0", "--device", "cpu"]  # every random generator in play
    return [sys.executable, "-m", "kinectdata", "train-baseline", "--data", str(data), "--out", str(run_dir)] + (
        list(extra) if extra else settings + noise
    )


def _log(run_dir: Path) -> list[dict[str, str]]:
    with open(run_dir / "log.csv", newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_training_killed_in_its_second_epoch_resumes_to_the_same_weights(sample_dataset, tmp_path):
    torch = pytest.importorskip("torch")
    from kinectdata.models.run import load_checkpoint

    whole = subprocess.Popen(  # the uninterrupted run, alongside
        _train_command(sample_dataset, tmp_path / "whole"), env=ONE_THREAD, stdout=subprocess.DEVNULL
    )
    run_dir = tmp_path / "killed"
    checkpoint = run_dir / "checkpoint.pt"

    def into_the_second_epoch(share: float) -> Callable[[], bool]:
        def ready() -> bool:  # once epoch 1's checkpoint is written, a share of epoch 1's duration later
            if not checkpoint.exists():
                return False
            time.sleep(share * float(_log(run_dir)[0]["seconds"]))  # log.csv is written before the checkpoint
            return True

        return ready

    for share in (random.Random(3).uniform(0.2, 0.5), 0.02):  # again, earlier, if the first kill came too late
        shutil.rmtree(run_dir, ignore_errors=True)
        status = _kill_when(_train_command(sample_dataset, run_dir), into_the_second_epoch(share), env=ONE_THREAD)
        assert status is None, "the training ended before the kill"
        if len(json.loads(load_checkpoint(checkpoint)["history"])) == 1:
            break
    assert len(json.loads(load_checkpoint(checkpoint)["history"])) == 1, "never killed within the second epoch"
    assert not (run_dir / "model.pt").exists()
    resumed = subprocess.run(
        _train_command(sample_dataset, run_dir, "--resume"), env=ONE_THREAD, capture_output=True, text=True
    )
    assert resumed.returncode == 0, resumed.stderr
    assert whole.wait() == 0
    a = torch.load(tmp_path / "whole" / "model.pt", weights_only=True)["model"]
    b = torch.load(run_dir / "model.pt", weights_only=True)["model"]
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    losses = ("epoch", "step", "train_loss", "val_loss", "val_smape")
    assert [[r[k] for k in losses] for r in _log(run_dir)] == [[r[k] for k in losses] for r in _log(tmp_path / "whole")]
