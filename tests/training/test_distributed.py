"""Beyond one machine: train-baseline under torchrun (two gloo processes) reaches the losses of one
process with the same global batch; build-dataset on a Dask cluster (a LocalCluster of two worker
processes, started after the training tests so it does not compete with them) gives the bytes of a
local build and resumes like one."""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import socket
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner
from conftest import REPO, TINY_TRAINING

from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.executors import DaskExecutor, LocalExecutor
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features.stft import PRESETS
from kinectdata.targets.specs import load_target_spec

torch = pytest.importorskip("torch")
from torch.utils.data import DataLoader, Dataset  # noqa: E402

from kinectdata.models.run import load_checkpoint  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402
from kinectdata.training.distributed import (  # noqa: E402
    World,
    check_replicas,
    from_main,
    per_rank_batch,
    share_of_batch,
    sum_over_ranks,
)
from kinectdata.training.train import _training_batches, train  # noqa: E402

SESSIONS = [f"synth_00{i}.{ext}" for i in (1, 2, 3) for ext in ("csv", "flac")]
THIRDS = (1 / 3, 1 / 3, 1 / 3)
DOCS = [{"recording": f"synth_00{i}.csv", "audio": f"synth_00{i}.flac"} for i in (1, 2, 3)]


class _Numbered(Dataset):
    """n windows that say which they are, all valid."""

    def __init__(self, n: int):
        self.n = n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i: int) -> dict:
        return {"index": torch.tensor(i), "mask": torch.ones(3, dtype=torch.bool)}


def _epochs(windows, world, epochs: int = 3, batch_size: int = 8, seed: int = 5) -> list[list[list[tuple[int, bool]]]]:
    """Per epoch, this rank's batches as (window, valid) pairs, from a generator seeded with ``seed``."""
    order = torch.Generator().manual_seed(seed)
    config = TrainConfig(batch_size=batch_size)
    epochs_batches = []
    for _ in range(epochs):
        batches = _training_batches(windows, config, order, world)
        epochs_batches.append([list(zip(b["index"].tolist(), b["mask"].all(dim=1).tolist())) for b in batches])
    return epochs_batches


@pytest.mark.parametrize("n", [21, 24, 3])
def test_the_ranks_batches_together_are_the_one_process_batches(n):
    """The reference is a plain shuffled DataLoader with the same generator: with one process the
    batches are its batches; with two, the ranks' k-th batches (4 windows each) together are its
    k-th batch, the padding that evens out an odd count masked out."""
    order = torch.Generator().manual_seed(5)
    reference = [
        [b["index"].tolist() for b in DataLoader(_Numbered(n), batch_size=8, shuffle=True, generator=order)]
        for _ in range(3)
    ]
    alone = _epochs(_Numbered(n), World())
    assert [[[w for w, _ in b] for b in epoch] for epoch in alone] == reference
    assert all(valid for epoch in alone for b in epoch for _, valid in b)

    ranks = [_epochs(_Numbered(n), World(rank, 2, rank)) for rank in (0, 1)]
    for epoch, (first, second) in enumerate(zip(*ranks)):
        assert len(first) == len(second) == len(reference[epoch])
        for k, (a, b) in enumerate(zip(first, second)):
            assert len(a) == len(b) <= 4
            assert sorted(w for w, valid in a + b if valid) == sorted(reference[epoch][k])
        padding = [w for b in first + second for w, valid in b if not valid]
        assert len(padding) == n % 2 and set(padding) <= set(range(n))


def test_the_world_comes_from_torchrun_s_environment():
    assert World.from_environment({}) == World(0, 1, 0)
    assert World.from_environment({"RANK": "1", "WORLD_SIZE": "2", "LOCAL_RANK": "1"}) == World(1, 2, 1)
    with pytest.raises(KinectDataError, match="WORLD_SIZE is set .* but RANK / LOCAL_RANK are missing"):
        World.from_environment({"WORLD_SIZE": "2"})
    with pytest.raises(KinectDataError, match=r"RANK 2 is outside 0..1 \(WORLD_SIZE 2\)"):
        World.from_environment({"RANK": "2", "WORLD_SIZE": "2"})
    assert per_rank_batch(8, World(1, 2)) == 4
    with pytest.raises(KinectDataError, match="batch size 7 does not divide among 2 processes"):
        per_rank_batch(7, World(0, 2))


def _replica_worker(rank: int, port: int) -> None:
    """Rank ``rank`` of two gloo processes: sums, rank 0's values, loss shares, and replica checks."""
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    torch.distributed.init_process_group("gloo", rank=rank, world_size=2)
    world = World(rank, 2, rank)
    assert sum_over_ranks([1.0 + rank, 10.0], world) == [3.0, 20.0]
    assert from_main([float(rank), math.nan], world)[0] == 0.0
    assert share_of_batch([30.0, 10.0][rank], world) == [1.5, 0.5][rank]  # 2 x own / all valid values
    same = [torch.nn.Parameter(torch.arange(6.0))]
    check_replicas(same, world, epoch=1)
    check_replicas([torch.nn.Parameter(torch.tensor([math.nan, 1.0]))], world, epoch=1)  # diverged alike
    drifted = [torch.nn.Parameter(torch.arange(6.0) + torch.tensor([0, 0, 0, 0, 0, rank * 1e-6]))]
    with pytest.raises(KinectDataError, match=r"after epoch 2 the 2 training processes hold different weights \(1 of"):
        check_replicas(drifted, world, epoch=2)
    torch.distributed.destroy_process_group()


@pytest.mark.slow
def test_replicas_are_checked_across_two_processes():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    torch.multiprocessing.spawn(_replica_worker, args=(port,), nprocs=2)


def _options(settings: dict, **changes) -> list[str]:
    return [f"--{k.replace('_', '-')}={v}" for k, v in {**settings, **changes}.items()]


@pytest.mark.slow
def test_two_torchrun_processes_reach_the_losses_of_one(sample_dataset, tmp_path):
    """Global batch 8 (4 per rank) with gradient noise (the same on both ranks, or the replicas'
    check stops the run); the two-process run is trained one epoch, then resumed for the second.

    The tolerance, from what differs: each rank's batch normalisation uses the statistics of its 4
    windows (one process: all 8), and float sums run in another order. Measured: losses within 4e-6
    relative, weights 1e-7 apart on average. Ranks given contiguous halves of the shuffled windows
    instead (other batches, the same epoch) move the losses by 1e-4 to 2e-3 relative. Without
    gradient noise Adam's normalised steps amplify the differences: losses then agree to 2e-4. The
    running statistics of batch normalisation are rank 0's (DDP broadcasts its buffers): they
    differ by up to 15 % from one process's and are not compared."""
    settings = {**TINY_TRAINING, "noise_eta": 1e-4}
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as each torchrun process (OMP_NUM_THREADS=1); and no contention with them
    try:
        one = train(sample_dataset, tmp_path / "one", TrainConfig(**settings))
    finally:
        torch.set_num_threads(threads)
    two = tmp_path / "two"
    torchrun = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2", "-m", "kinectdata"]
    command = [*torchrun, "train-baseline", f"--data={sample_dataset}", f"--out={two}", "--device=cpu"]
    first = subprocess.run([*command, *_options(settings, epochs=1)], capture_output=True, text=True, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    second = subprocess.run([*command, "--resume", "--epochs=2"], capture_output=True, text=True, cwd=tmp_path)
    assert second.returncode == 0, second.stderr
    assert first.stdout.count("epoch   1: train loss") == 1 and second.stdout.count("epoch   2: train loss") == 1

    with open(two / "log.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["epoch"]) for r in rows] == [1, 2] and [int(r["step"]) for r in rows] == [3, 6]
    for mine, theirs in zip(rows, one):
        assert float(mine["train_loss"]) == pytest.approx(theirs["train_loss"], rel=2e-5, abs=0)
        assert float(mine["val_loss"]) == pytest.approx(theirs["val_loss"], rel=2e-5, abs=0)
    alone, together = (load_checkpoint(run / "model.pt")["model"] for run in (tmp_path / "one", two))
    weights = [name for name in alone if "running_" not in name and "num_batches" not in name]
    apart = torch.cat([(together[name] - alone[name]).abs().flatten() for name in weights])
    assert apart.mean() < 1e-6
    assert {p.name for p in two.iterdir()} >= {"config.json", "checkpoint.pt", "log.csv", "model.pt", "stream.ts"}


def _config() -> BuildConfig:
    """What build-dataset's defaults give with --split-ratios of thirds (one recording per split)."""
    return BuildConfig(
        features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("yalta65").to_dict(), split_ratios=THIRDS
    )


def _copy_sessions(folder):
    folder.mkdir()
    for name in SESSIONS:
        shutil.copy(REPO / "sample_data" / name, folder / name)
    return folder


def _files_bytes(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def _run(*args):
    return CliRunner().invoke(main, list(map(str, args)))


@pytest.fixture(scope="module")
def cluster():
    """The address of a Dask cluster of two single-threaded worker processes on this machine."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as local:
        yield local.scheduler_address


@pytest.fixture(scope="module")
def local_build(tmp_path_factory):
    """(sessions folder, dataset folder) of a --jobs 1 build of copies of the three sample sessions."""
    root = tmp_path_factory.mktemp("local")
    sessions = _copy_sessions(root / "sessions")
    build_dataset(sessions, root / "dataset", _config(), jobs=1)
    return sessions, root / "dataset"


def test_a_dask_build_gives_the_bytes_of_a_local_build(cluster, local_build, tmp_path):
    sessions, local = local_build
    thirds = ",".join(repr(r) for r in THIRDS)
    args = ["build-dataset", sessions, "-o", tmp_path / "dask", "--split-ratios", thirds]
    result = _run(*args, "--executor", "dask", "--scheduler", cluster)
    assert result.exit_code == 0, result.output
    assert _files_bytes(tmp_path / "dask") == _files_bytes(local)
    assert not (tmp_path / "dask" / ".work").exists()


def test_a_failing_recording_on_a_worker_is_named_and_the_rerun_resumes(cluster, tmp_path):
    """synth_003's audio is too short: the error names it; the others' work files stay and are
    reused when the correct manifest is built into the same folder, which gives a local build's bytes."""
    folder = _copy_sessions(tmp_path / "sessions")
    sf.write(folder / "short.wav", np.zeros(16000, np.float32), 16000)  # 1 s, shorter than the motion
    (folder / "bad.json").write_text(json.dumps(DOCS[:2] + [{**DOCS[2], "audio": "short.wav", "offset": 0.0}]))
    (folder / "good.json").write_text(json.dumps(DOCS))
    out = tmp_path / "dataset"
    with pytest.raises(KinectDataError, match=r"recording 'synth_003' of .*bad\.json: .*short\.wav.*covers only"):
        build_dataset(folder / "bad.json", out, _config(), executor=DaskExecutor(cluster))
    assert not (out / "manifest.json").exists()
    kept = {p.name: p.stat().st_mtime_ns for p in (out / ".work").glob("*.h5")}
    assert set(kept) == {"synth_001.h5", "synth_002.h5"}

    build_dataset(folder / "good.json", out, _config(), executor=DaskExecutor(cluster), keep_work=True)
    assert {p.name: p.stat().st_mtime_ns for p in (out / ".work").glob("*.h5") if p.name in kept} == kept
    shutil.rmtree(out / ".work")
    build_dataset(folder / "good.json", tmp_path / "local", _config(), jobs=1)
    assert _files_bytes(out) == _files_bytes(tmp_path / "local")


def test_a_local_worker_that_dies_is_a_clear_error():
    """A worker process that exits mid-task (killed, out of memory, a script without a main guard)
    is one KinectDataError saying so, not the pool's BrokenProcessPool."""
    with pytest.raises(KinectDataError, match=r"a worker process died before its task was done \(0 of 2 done\)"):
        LocalExecutor(2).map(os._exit, [3, 3], ["a", "b"])


def test_other_failures_on_the_cluster_name_the_task(cluster):
    with pytest.raises(KinectDataError, match=r"^task -1: failed on the Dask cluster at tcp://.*ValueError"):
        DaskExecutor(cluster).map(math.sqrt, [4.0, -1.0], ["task 4", "task -1"])
    assert DaskExecutor(cluster).map(math.sqrt, [4.0, 9.0], ["a", "b"]) == LocalExecutor().map(
        math.sqrt, [4.0, 9.0], ["a", "b"]
    )


def test_an_unreachable_scheduler_is_a_clear_error(local_build, tmp_path):
    pytest.importorskip("distributed")
    sessions, _ = local_build
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    with pytest.raises(KinectDataError, match=f"cannot reach a Dask scheduler at {address} .*is it running"):
        build_dataset(sessions, tmp_path / "ds", _config(), executor=DaskExecutor(address, timeout=0.5))
    with pytest.raises(KinectDataError, match="'nowhere' is not a Dask scheduler address"):
        build_dataset(sessions, tmp_path / "ds", _config(), executor=DaskExecutor("nowhere", timeout=0.5))


def test_a_worker_that_cannot_share_the_dataset_folder_is_caught(local_build, tmp_path):
    """An executor whose workers write elsewhere (no shared filesystem) fails with the reason."""
    sessions, _ = local_build

    class Elsewhere(LocalExecutor):
        def map(self, function, tasks, names, progress=None):
            (tmp_path / "elsewhere").mkdir(exist_ok=True)
            return super().map(function, [(*t[:2], str(tmp_path / "elsewhere"), *t[3:]) for t in tasks], names)

    with pytest.raises(KinectDataError, match=r"\.work: the workers wrote synth_00\d\.h5.* workers share, at the same"):
        build_dataset(sessions, tmp_path / "ds", _config(), executor=Elsewhere())


@pytest.mark.parametrize(
    "options, message",
    [
        (["--scheduler", "tcp://127.0.0.1:8786"], "--scheduler tcp://127.0.0.1:8786 is for --executor dask"),
        (["--executor", "dask"], "--executor dask needs --scheduler ADDRESS"),
        (["--executor", "dask", "--scheduler", "tcp://a:1", "--jobs", "2"], "--jobs 2 is for --executor local"),
    ],
)
def test_executor_options_are_checked(options, message, tmp_path):
    result = _run("build-dataset", REPO / "sample_data", "-o", tmp_path / "ds", *options)
    assert result.exit_code == 1 and message in result.output
    assert not (tmp_path / "ds").exists()
