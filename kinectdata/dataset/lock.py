"""One writer per dataset folder: a build holds an operating-system lock on ``DATASET/.build.lock``
(:mod:`filelock`) from its first write to its manifest.

A second build of the same folder fails at once, naming the build that holds the lock (process,
host, start time and command, from the companion file ``.build.owner``). The lock is the kernel's
(``flock``; on Windows ``LockFileEx``): it goes with the process that held it, so a build killed
with ``kill -9`` leaves no lock behind, only an owner file that the next build overwrites. On a
filesystem without ``flock`` the build stops rather than fall back to a marker file, which a killed
build would leave to block every rerun.

Neither file is part of the dataset: ``verify`` and ``inspect`` read only ``manifest.json`` and the
shards it lists, and the build's clean-up removes only shards of its own.
"""

from __future__ import annotations

import errno
import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from filelock import FileLock, SoftFileLock, Timeout

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.layout import LOCK, LOCK_OWNER

OWNER_WAIT_S = 1.0
"""How long a refused build waits for the holder's owner file when it is not written yet (the holder
writes it right after taking the lock) or is a killed build's: the refusal itself does not wait."""


class FolderBusyError(KinectDataError):
    """Another build is writing the dataset folder."""


@contextmanager
def build_lock(folder: str | Path) -> Iterator[None]:
    """Hold the build lock of ``folder`` (created if needed) for the ``with`` block.

    Raises:
        FolderBusyError: another process holds it; the message names that build.
        KinectDataError: the folder's filesystem has no operating-system locks.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    no_flock = KinectDataError(
        f"{folder / LOCK}: the filesystem does not support file locks (flock), which keep two builds from "
        "writing one dataset folder: build into a folder on a local disk, then move it"
    )
    # never a soft lock: its marker file outlives a killed build and would block the rerun
    try:
        lock = FileLock(str(folder / LOCK), timeout=0, fallback_to_soft=False)
    except TypeError:  # a filelock from before fallback_to_soft: a fallback is caught after acquiring
        lock = FileLock(str(folder / LOCK), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise FolderBusyError(
            f"{folder}: another build is writing this dataset folder ({describe_owner(wait_for_owner(folder))}); "
            "wait for it to finish, or build into another folder"
        ) from None
    except NotImplementedError:  # filelock before its soft fallback, on ENOSYS
        raise no_flock from None
    except OSError as exc:
        if exc.errno != errno.ENOSYS:
            raise
        raise no_flock from None
    if isinstance(lock, SoftFileLock):  # fell back (or the platform has no fcntl)
        lock.release()
        raise no_flock
    owner = folder / LOCK_OWNER
    try:
        record = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "started": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
            "command": " ".join(sys.argv),
        }
        with atomic_output(owner) as tmp:  # a refused build never reads half a record
            tmp.write_text(json.dumps(record) + "\n", encoding="utf-8")
        yield
    finally:
        owner.unlink(missing_ok=True)
        lock.release()


def read_owner(folder: str | Path) -> dict[str, Any] | None:
    """The owner record of a dataset folder's lock (``pid``, ``host``, ``started``, ``command``), or
    None when there is none or it cannot be read."""
    try:
        record = json.loads((Path(folder) / LOCK_OWNER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or not {"pid", "host", "started", "command"} <= record.keys():
        return None
    return record


def wait_for_owner(folder: Path, wait: float = OWNER_WAIT_S) -> dict[str, Any] | None:
    """The record of the build holding ``folder``'s lock: at once when it is there and its process
    is alive, else after at most ``wait`` seconds (the holder may have taken the lock but not yet
    written its record over a killed build's); None when none appears."""
    deadline = time.monotonic() + wait
    while True:
        record = read_owner(folder)
        if record is not None and not _dead_here(record):
            return record
        if time.monotonic() >= deadline:
            return None
        time.sleep(0.02)


def describe_owner(record: dict[str, Any] | None) -> str:
    """An owner record in words, for the refusal."""
    if record is None:
        return "a build that has not said who it is"
    return f"process {record['pid']} on {record['host']}, started {record['started']}: {record['command']}"


def _dead_here(record: dict[str, Any]) -> bool:
    """Whether the record is a killed build's: its process, on this host, is gone."""
    if record["host"] != socket.gethostname() or not isinstance(record["pid"], int):
        return False
    try:
        os.kill(record["pid"], 0)
    except ProcessLookupError:
        return True
    except (PermissionError, OSError):
        return False
    return False
