"""A sensor's side of a capture, run in its own process.

Sensor libraries misbehave in ways a capture must survive: OpenNI2's drivers can crash while the
library unloads (after the file is complete), and pyk4a holds Python's lock during each blocking
call to the Azure Kinect SDK, which would starve the audio callback beside it. So each sensor
records in a child process (``python -m kinectdata.capture.<sensor>_session SETTINGS.json``) that
writes a status JSON (the frames it saw, the device, or ``{"error": ...}``) and the parent reads it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataError


def run_session(module: str, settings: dict[str, Any], what: str, timeout_s: float, recording: Path) -> dict[str, Any]:
    """Run ``python -m module`` with ``settings`` (a ``status`` path is added) and return its status.

    Args:
        what: names the device in every error ("OpenNI2 device Dummy", "Azure Kinect device 0").
        recording: the file the session writes; removed when the session fails.

    Raises:
        KinectDataError: the process could not start, did not finish within ``timeout_s``, died
            before reporting, or reported an error.
    """
    with tempfile.TemporaryDirectory() as tmp:
        status_path = Path(tmp) / "status.json"
        settings_path = Path(tmp) / "settings.json"
        settings_path.write_text(json.dumps({**settings, "status": str(status_path)}))
        try:
            done = subprocess.run(
                [sys.executable, "-m", module, str(settings_path)],
                capture_output=True,
                text=True,
                timeout=timeout_s,
            )
        except subprocess.TimeoutExpired:
            recording.unlink(missing_ok=True)
            raise KinectDataError(f"{what}: the recording did not finish") from None
        except OSError as exc:
            raise KinectDataError(
                f"{what}: could not start the recording process (Python at {sys.executable}: {exc.strerror or exc})"
            ) from None
        if not status_path.exists():  # crashed before reporting (a crash after it is a library's unload)
            recording.unlink(missing_ok=True)
            raise KinectDataError(
                f"{what}: the recording process failed (exit {done.returncode}): {done.stderr.strip()[-400:]}"
            )
        status = json.loads(status_path.read_text())
    if "error" in status:
        recording.unlink(missing_ok=True)
        raise KinectDataError(f"{what}: {status['error']}")
    return status


def session_main(argv: list[str], run: Callable[[dict[str, Any]], dict[str, Any]], *, hard_exit: bool) -> None:
    """The child's entry point: run ``run(settings)``, write its status (or the error it raised)
    atomically where the settings say, and exit; ``hard_exit``: without unloading the libraries
    (``os._exit``), for those whose unload can crash or hang once everything is written."""
    settings = json.loads(Path(argv[0]).read_text())
    try:
        status = run(settings)
    except Exception as exc:  # reported to the parent, which names the device and the take
        status = {"error": f"{type(exc).__name__}: {exc}"}
    out = Path(settings["status"])
    tmp = out.with_suffix(".partial")
    tmp.write_text(json.dumps(status, default=lambda o: o.tolist() if isinstance(o, np.ndarray) else str(o)))
    tmp.replace(out)
    print("captured", flush=True)
    if hard_exit:
        os._exit(0)
