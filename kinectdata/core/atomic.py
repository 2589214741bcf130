"""Write files atomically and durably: readers never see a half-written output.

Output goes to a temporary file in the destination folder (``.NAME.PID-XXXX.partial``), is flushed
to disk and then renamed over the destination in one step (``os.replace``); the folder is flushed
after the rename, so that a finished output survives a power cut and outputs become durable in the
order they were renamed (a dataset's shards before its manifest). A process killed at any point
(``kill -9`` included) leaves the old destination or the new one, and at worst a ``.partial`` file,
which the next write of the same destination removes (its process is gone: :func:`remove_orphans`).

On any error the temporary file is removed and the destination is left as it was; a write that
fails because the disk is full (or the file outgrows what the process may write) is raised as a
:class:`~kinectdata.core.errors.KinectDataError` naming the destination.

``KINECTDATA_FSYNC=0`` in the environment skips the flushes (:func:`durable`): the writes stay
atomic (a killed process still leaves the old output or the new one), but a power cut may leave a
renamed output empty. For scratch disks and test suites, where the flushes are most of the time of
writing many small files (the test suite sets it).
"""

from __future__ import annotations

import errno
import glob
import os
import re
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import h5py

from kinectdata.core.errors import KinectDataError

DISK_FULL = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})
"""Error numbers of a write refused for lack of room: no space, over quota, file too large."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_failure(path: str | os.PathLike[str], exc: BaseException) -> KinectDataError | None:
    """The error to raise when ``exc`` is a write to ``path`` refused for lack of room, else None.

    h5py reports some refused writes as a RuntimeError whose message holds ``errno = 28``; the
    error number is read from there when the exception has none.
    """
    code = getattr(exc, "errno", None)
    if code is None and isinstance(exc, (OSError, RuntimeError)):
        found = re.search(r"errno = (\d+)", str(exc))
        code = int(found.group(1)) if found else None
    if code not in DISK_FULL:
        return None
    return KinectDataError(
        f"{path}: could not be written: the disk is full or the file is larger than allowed "
        f"({os.strerror(code)}); nothing was left in its place, free some space and run again"
    )


def durable() -> bool:
    """Whether writes are flushed to disk: True unless ``KINECTDATA_FSYNC`` is ``0``, ``off`` or
    ``false`` (read at each call, so that a process can change it)."""
    return os.environ.get("KINECTDATA_FSYNC", "1").strip().lower() not in ("0", "off", "false")


def flush_file(path: str | os.PathLike[str]) -> None:
    """Flush a written file's contents to disk (a no-op when not :func:`durable`)."""
    if not durable():
        return
    with open(path, "rb") as f:
        os.fsync(f.fileno())


def sync_folder(folder: str | os.PathLike[str]) -> None:
    """Flush a folder's entries (renames, removals) to disk; a no-op where folders cannot be opened
    and when not :func:`durable`."""
    if os.name != "posix" or not durable():
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def remove(path: str | os.PathLike[str]) -> None:
    """Delete ``path`` if it exists, durably: the removal reaches the disk before what follows."""
    path = Path(path)
    try:
        path.unlink()
    except FileNotFoundError:
        return
    sync_folder(path.parent)


def remove_orphans(path: Path) -> list[Path]:
    """Remove the temporary files of ``path`` left by killed writers (``.NAME.PID-XXXX.partial``
    whose process is gone); a live writer's file is kept. Returns what was removed."""
    removed = []
    for partial in path.parent.glob(f".{glob.escape(path.name)}.*.partial"):
        pid = partial.name[len(path.name) + 2 :].split("-", 1)[0]
        if pid.isdigit() and not _alive(int(pid)):
            partial.unlink(missing_ok=True)
            removed.append(partial)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


@contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path to write; on success it replaces ``path``, on error it is removed."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_orphans(path)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}-", suffix=".partial", dir=path.parent)
    except OSError as exc:
        raise KinectDataError(f"{path}: cannot write here ({exc.strerror or exc})") from exc
    os.close(fd)
    tmp = Path(tmp_name)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs should follow the user's umask
    try:
        yield tmp
        flush_file(tmp)
        os.replace(tmp, path)
        sync_folder(path.parent)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        failure = write_failure(path, exc)
        if failure is not None:
            raise failure from exc
        raise


@contextmanager
def atomic_hdf5(path: str | os.PathLike[str]) -> Iterator[h5py.File]:
    """:func:`atomic_output` for a new HDF5 file: yields it open for writing.

    The file has no chunk cache: HDF5 crashes the process (a segmentation fault) when it closes a
    file whose cached chunks it could not write, as on a full disk; without the cache every write
    reaches the file at once and a refused one is an ordinary error where it is made.
    """
    with atomic_output(path) as tmp, h5py.File(tmp, "w", rdcc_nbytes=0) as f:
        yield f
