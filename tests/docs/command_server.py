"""Runs ``kinectdata`` commands as processes of their own without paying for the imports each time.

A server process imports the command line and its heavy libraries once (torch alone takes over a
second), then forks one child per command: the child is a fresh process (its own exit code, file
descriptors, working folder, environment and interpreter state) that starts where the console
script's ``main()`` would be called. The documents' ~90 commands cost a minute less this way. The
console script itself is run by tests/cli (``python -m kinectdata``) and by every shell example whose
command is not ``kinectdata``.

POSIX only (``os.fork``); :func:`start` returns None elsewhere and the caller starts real processes.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

SERVER = r"""
import json, os, sys
import kinectdata.cli as cli
for name in cli.COMMAND_MODULES:
    cli.main.get_command(None, name)
# what the training, evaluating, generating and drawing commands import (torch._dynamo: Adam's
# first construction imports it, another second)
import torch, torch._dynamo, matplotlib.pyplot
import kinectdata.training.train, kinectdata.evaluation.evaluate, kinectdata.inference.generate
import kinectdata.viz.render, kinectdata.viz.report, kinectdata.dataset.build
# librosa compiles its numba kernels when these are imported (about 5 s in every process that tracks
# beats: evaluate, the metre, the listen-to-dance pulse), which its own cache does not save
import librosa.beat, librosa.onset

requests = os.fdopen(0, "r")
replies = os.fdopen(int(sys.argv[1]), "w", buffering=1)
for line in requests:
    asked = json.loads(line)
    pid = os.fork()
    if pid == 0:
        code = 70
        try:
            os.setpgid(0, 0)
            os.chdir(asked["cwd"])
            os.environ.clear()
            os.environ.update(asked["env"])
            written = os.O_WRONLY | os.O_CREAT | os.O_TRUNC
            opened = ((0, os.devnull, os.O_RDONLY), (1, asked["stdout"], written), (2, asked["stderr"], written))
            for fd, path, flags in opened:
                os.dup2(os.open(path, flags, 0o644), fd)
            sys.stdin = open(0, "r", closefd=False)
            sys.stdout = open(1, "w", closefd=False)
            sys.stderr = open(2, "w", closefd=False)
            sys.argv = ["kinectdata", *asked["args"]]
            try:
                cli.main(asked["args"], prog_name="kinectdata")
                code = 0
            except SystemExit as stop:
                code = stop.code if isinstance(stop.code, int) else 0 if stop.code is None else 1
                if not isinstance(stop.code, (int, type(None))):
                    print(stop.code, file=sys.stderr)
        except BaseException:
            import traceback
            traceback.print_exc()
        finally:
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except Exception:
                    pass
            os._exit(code)
    replies.write(json.dumps({"pid": pid}) + "\n")
    _, status = os.waitpid(pid, 0)
    replies.write(json.dumps({"code": os.waitstatus_to_exitcode(status)}) + "\n")
"""


class CommandServer:
    """One server process; :meth:`run` is ``subprocess.run(["kinectdata", *args], ...)`` for it."""

    def __init__(self, env: dict[str, str]) -> None:
        reply_read, reply_write = os.pipe()
        self._process = subprocess.Popen(
            [sys.executable, "-c", SERVER, str(reply_write)],
            stdin=subprocess.PIPE,
            pass_fds=(reply_write,),
            env=env,
            text=True,
        )
        os.close(reply_write)
        self._replies = os.fdopen(reply_read, "r")
        self._lock = threading.Lock()

    def run(self, args: list[str], cwd: Path, env: dict[str, str], timeout: float) -> subprocess.CompletedProcess:
        with self._lock, tempfile.TemporaryDirectory() as captured:
            out, err = Path(captured) / "stdout", Path(captured) / "stderr"
            asked = {"args": args, "cwd": str(cwd), "env": env, "stdout": str(out), "stderr": str(err)}
            self._process.stdin.write(json.dumps(asked) + "\n")
            self._process.stdin.flush()
            pid = json.loads(self._replies.readline())["pid"]
            timer = threading.Timer(timeout, lambda: os.killpg(pid, signal.SIGKILL))
            timer.start()
            try:
                reply = self._replies.readline()
            finally:
                timer.cancel()
            if not reply:
                raise RuntimeError(f"the command server stopped while running kinectdata {' '.join(args)}")
            code = json.loads(reply)["code"]
            return subprocess.CompletedProcess(
                ["kinectdata", *args],
                code,
                out.read_text(encoding="utf-8", errors="replace"),
                err.read_text(encoding="utf-8", errors="replace"),
            )

    def close(self) -> None:
        self._process.stdin.close()
        self._process.wait(timeout=30)


def start(env: dict[str, str]) -> CommandServer | None:
    """A server whose children get ``env``'s threads and backend (imports happen before the first
    command), or None where processes cannot fork."""
    return CommandServer(env) if hasattr(os, "fork") else None
