"""Shard layout checks in a child process, so that a damaged file cannot take the caller down.

The HDF5 library can crash (a segmentation fault) or loop forever on some damaged files, which no
exception handling contains; :func:`kinectdata.dataset.shards.validate_shard` therefore reads a
shard's structure in a child process. Starting a Python interpreter with h5py costs about 0.25 s,
more than the check itself, so one child serves every check of a process in turn
(:class:`ShardChecker`): paths go to its standard input, answers come back on its standard
output, one JSON line each. A child that crashes or does not answer within the timeout is killed
and the file is reported as damaged; the next check starts a new child. The child ends when its
parent does (its standard input closes).

POSIX only (the answer is awaited with ``select`` on the pipe); elsewhere each check starts a
child of its own (:func:`check_once`).
"""

from __future__ import annotations

import atexit
import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from kinectdata.core.errors import FormatError, KinectDataError

_PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])  # the child imports this same kinectdata

_SERVE = """
import json, sys
sys.path.insert(0, sys.argv[1])
from kinectdata.dataset.shards import validate_shard
from kinectdata.core.errors import FormatError
for line in sys.stdin:
    try:
        answer = {"sizes": validate_shard(json.loads(line), isolated=False)}
    except FormatError as exc:
        answer = {"reason": exc.reason}
    sys.stdout.write(json.dumps(answer) + "\\n")
    sys.stdout.flush()
"""


def _answer(path: Path, answer: dict[str, Any]) -> dict[str, int]:
    if "reason" in answer:
        raise FormatError(path, answer["reason"])
    return answer["sizes"]


def _hung(path: Path, timeout: float) -> FormatError:
    message = f"the HDF5 library did not finish reading the file's structure in {timeout:g} s"
    return FormatError(path, message + " (a damaged file?)")


def _cannot_start(path: Path, exc: OSError) -> KinectDataError:
    """The interpreter the check runs in would not start: say what was being done, and why."""
    return KinectDataError(
        f"{path}: checking the shard needs a child Python process, and starting {sys.executable} failed "
        f"({exc.strerror or exc}): run kinectdata with a Python interpreter this user may execute"
    )


def _died(path: Path, returncode: int, stderr: str) -> Exception:
    """What a child's death while checking ``path`` means: a bug (a Python traceback) or damage."""
    if "Traceback" in stderr:  # a Python error in the check itself: a bug, not the file
        return RuntimeError(f"checking {path} failed in the child process:\n{stderr}")
    how = f"signal {signal.Signals(-returncode).name}" if returncode < 0 else f"exit {returncode}"
    return FormatError(path, f"reading the file's structure crashed the HDF5 library ({how}): the file is damaged")


class ShardChecker:
    """A child process checking shards one after another (see the module's docstring)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._process: subprocess.Popen | None = None
        self._stderr = None
        self._buffer = b""  # what the child wrote past its last answer line
        self._owner = 0  # the pid that started the child: a forked copy of this object starts its own

    def check(self, path: Path, timeout: float) -> dict[str, int]:
        """The layout sizes of the shard at ``path``, checked in the child.

        Raises:
            FormatError: the file breaks the layout, or crashed or hung the HDF5 library.
        """
        with self._lock:
            process = self._running(path)
            try:
                process.stdin.write((json.dumps(str(Path(path).absolute())) + "\n").encode())  # its folder may differ
                process.stdin.flush()
            except BrokenPipeError:
                pass  # it died before reading: the empty answer below says how
            line = self._read_line(process, time.monotonic() + timeout)
            if line is None:  # no answer in time
                self._stop()
                raise _hung(path, timeout)
            if line == "":  # its output closed: it died (or is dying) without answering
                try:
                    returncode = process.wait(timeout=timeout)
                except subprocess.TimeoutExpired:
                    returncode = -signal.SIGKILL
                stderr = self._read_stderr()
                self._stop()
                raise _died(path, returncode, stderr)
        return _answer(path, json.loads(line))

    def _running(self, path: Path) -> subprocess.Popen:
        """The child, started if none is running (``path``: the shard it is needed for, for errors)."""
        if self._process is not None and self._owner != os.getpid():
            self._process = self._stderr = None  # a forked copy of this object: that child is the parent's
        elif self._process is not None and self._process.poll() is not None:
            self._stop()
        if self._process is None:
            self._stderr = tempfile.TemporaryFile()
            try:
                self._process = subprocess.Popen(
                    [sys.executable, "-c", _SERVE, _PACKAGE_ROOT],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    stderr=self._stderr,
                )
            except OSError as exc:
                self._stderr.close()
                self._stderr = None
                raise _cannot_start(path, exc) from exc
            self._owner = os.getpid()
            self._buffer = b""
        return self._process

    def _read_line(self, process: subprocess.Popen, deadline: float) -> str | None:
        """The child's next answer line; "" if it closed its output first, None if the deadline passed."""
        fd = process.stdout.fileno()
        while b"\n" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                return None
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                return ""
            self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line.decode()

    def _read_stderr(self) -> str:
        self._stderr.seek(0)
        return self._stderr.read().decode(errors="replace")

    def _stop(self) -> None:
        """Kill the child (if running) and forget it; the next check starts another."""
        process, self._process = self._process, None
        if process is not None:
            if process.poll() is None:
                process.kill()
            process.wait()
            process.stdin.close()
            process.stdout.close()
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None

    def close(self) -> None:
        """End the child: its input closes and it exits (killed if it does not within a second)."""
        with self._lock:
            process = self._process
            if process is None or self._owner != os.getpid():
                return
            try:
                process.stdin.close()
                process.wait(timeout=1.0)
            except (OSError, subprocess.TimeoutExpired):
                pass
            self._stop()


def check_once(path: Path, timeout: float) -> dict[str, int]:
    """Check one shard in a child process of its own (where :class:`ShardChecker` cannot run)."""
    command = [sys.executable, "-c", _SERVE, _PACKAGE_ROOT]
    try:
        child = subprocess.run(
            command, input=json.dumps(str(path)) + "\n", capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        raise _hung(path, timeout) from None
    except OSError as exc:
        raise _cannot_start(path, exc) from exc
    if child.returncode == 0 and child.stdout.strip():
        return _answer(path, json.loads(child.stdout.splitlines()[-1]))
    raise _died(path, child.returncode, child.stderr)


_CHECKER = ShardChecker()
atexit.register(_CHECKER.close)


def check_isolated(path: Path, timeout: float) -> dict[str, int]:
    """The layout sizes of the shard at ``path``, read in a child process (see the module)."""
    if os.name != "posix":
        return check_once(path, timeout)
    return _CHECKER.check(path, timeout)
