"""One writer per dataset folder: a build holds an operating-system lock on ``DATASET/.build.lock``
(:mod:`filelock`) from its first write to its manifest.

A second build of the same folder fails at once, naming the build that holds the lock (process,
host, start time, from ``.build.owner``). The lock is the kernel's (``flock``): it goes with the
process that held it, so a build killed with ``kill -9`` leaves no lock behind, only an owner file
that the next build overwrites.
"""

from __future__ import annotations

import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from filelock import FileLock, Timeout

from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.layout import LOCK, LOCK_OWNER


class FolderBusyError(KinectDataError):
    """Another build is writing the dataset folder."""


@contextmanager
def build_lock(folder: str | Path) -> Iterator[None]:
    """Hold the build lock of ``folder`` (created if needed) for the ``with`` block.

    Raises:
        FolderBusyError: another process holds it; the message names that build.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lock = FileLock(str(folder / LOCK), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise FolderBusyError(
            f"{folder}: another build is writing this dataset folder ({_owner(folder)}); wait for it to finish, "
            "or build into another folder"
        ) from None
    owner = folder / LOCK_OWNER
    try:
        record = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "started": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
            "command": " ".join(sys.argv),
        }
        owner.write_text(json.dumps(record) + "\n", encoding="utf-8")
        yield
    finally:
        owner.unlink(missing_ok=True)
        lock.release()


def _owner(folder: Path) -> str:
    """Who holds the lock, as the owner file says."""
    try:
        record = json.loads((folder / LOCK_OWNER).read_text(encoding="utf-8"))
        return f"process {record['pid']} on {record['host']}, started {record['started']}: {record['command']}"
    except (OSError, ValueError, KeyError, TypeError):
        return "a build that has not written who it is yet"
