"""A take: sensor, skeleton and music recorded together, on one clock, in one folder.

``capture_take`` writes ``TAKE/``:

- ``take.oni``: depth (and colour) from an OpenNI2 device, by OpenNI2's recorder;
- ``take.csv``: the NiTE2 skeleton (canonical CSV, times = the ``.oni``'s depth timestamps in
  seconds), when NiTE2 is installed;
- ``take.wav``: audio from an input device, when one is given;
- ``take.json``: what was recorded and when, on the monotonic clock (``time.monotonic()``, the
  same for every process of the machine): the clock time of the ``.oni``'s time 0 (its first
  depth frame's timestamp) and of the audio's first sample, and from them the offset
  ``audio_time = oni_time + offset_s``.

The ``.oni``'s time 0 is placed on the clock by the depth frames the session read: each one's
arrival time minus its device timestamp, the earliest of them (the frame that waited least); the
device timestamps are matched to the file's, which OpenNI2 rebases to start at 0. Sensor
latency before arrival is not known, so the offset errs by that (a few milliseconds for USB
depth cameras) and by the audio driver's own timestamp accuracy.

:func:`kinectdata.align.take.align_take` then aligns the take's skeleton with its audio with that
offset: no clap, no estimate.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import warnings
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.capture.audio import AudioCapture
from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError, KinectDataWarning
from kinectdata.oni.reader import OniFile, OniWarning
from kinectdata.oni.skeleton import TrackedFrame, find_nite, nite_motion, openni2_dir

TAKE = "take.json"
ONI, CSV, WAV = "take.oni", "take.csv", "take.wav"
FORMAT = "kinectdata.take"
CLOCK = "monotonic (time.monotonic), seconds"


class CaptureWarning(KinectDataWarning):
    """A take was recorded but something in it is doubtful (timing, dropped frames)."""


def _oni_zero_clock(frames: list[list], oni_stamps: np.ndarray, source: str) -> tuple[float, int, float]:
    """(clock seconds of the .oni's time 0, frames matched, device timestamp in us of the .oni's
    first frame): the session's frames (device timestamp us, index, arrival clock s) matched to
    the file's depth timestamps, which OpenNI2 rebases to start at 0.

    The shift between the two timestamp series is the one that lines up the most frames (frame
    j read = file frame k, for the first 30 of each); ties go to the earliest pairing, which is
    right because the session starts the recorder before the streams, so the first frame it
    reads is the first recorded. With a perfectly regular device clock a session that missed
    the first frames could not be told apart from one that did not; real clocks jitter.
    """
    device = np.array([f[0] for f in frames], np.float64)
    arrival = np.array([f[2] for f in frames], np.float64)
    file_us = oni_stamps.astype(np.float64)
    if device.size == 0 or file_us.size == 0:
        raise KinectDataError(f"{source}: no depth frame was recorded")
    pairs = sorted(((j, k) for j in range(min(30, device.size)) for k in range(min(30, file_us.size))), key=sum)
    best, shift = -1, device[0] - file_us[0]
    for j, k in pairs:
        candidate = device[j] - file_us[k]
        matched = int(np.isin(np.round(device - candidate), np.round(file_us)).sum())
        if matched > best:
            best, shift = matched, candidate
    return float(np.min(arrival - (device - shift) / 1e6)), best, float(shift)


def capture_take(
    out_dir: str | os.PathLike,
    *,
    device: str | None = None,
    duration_s: float = 10.0,
    audio_device: int | str | None = None,
    sample_rate: int = 48000,
    color: bool = False,
    lossy: bool = False,
    skeleton: bool = True,
    nite_dir: str | os.PathLike | None = None,
    audio_stream_factory=None,
) -> dict[str, Any]:
    """Record a take into ``out_dir`` (see the module docstring); returns ``take.json``'s content.

    Args:
        device: OpenNI2 device URI (``Dummy`` for OpenNI2's test device); None: the first one.
        duration_s: seconds of recording.
        audio_device: sounddevice input (index or name); None: no audio.
        skeleton: track the skeleton with NiTE2 when it is installed (a warning when it is not).
        audio_stream_factory: the audio input stream class (default ``sounddevice.InputStream``).

    Raises:
        KinectDataError: the folder already holds a take, the device or audio cannot record, or
            the recording came out incomplete; partial files are removed.
    """
    take = Path(out_dir)
    existing = [name for name in (TAKE, ONI, WAV, CSV) if (take / name).exists()]
    if existing:
        raise KinectDataError(f"{take}: already holds a take ({', '.join(existing)}); choose another folder")
    take.mkdir(parents=True, exist_ok=True)
    problems: list[str] = []
    nite_folder = None
    if skeleton:
        try:
            nite_folder = str(find_nite(nite_dir))
        except KinectDataError as exc:
            problems.append(f"no skeleton: {exc}")
            warnings.warn(problems[-1], CaptureWarning, stacklevel=2)
    audio = None
    written = [take / ONI, take / WAV, take / CSV]
    try:
        try:
            if audio_device is not None:
                audio = AudioCapture(take / WAV, audio_device, sample_rate, stream_factory=audio_stream_factory)
                audio.start()
            started = datetime.now(timezone.utc).isoformat(timespec="seconds")
            status = _run_session(take, device, duration_s, color, lossy, nite_folder)
        finally:
            if audio is not None:
                audio.stop()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OniWarning)
            with OniFile(take / ONI) as oni:
                if oni.truncated:
                    raise KinectDataError(f"{take / ONI}: the recording is incomplete ({'; '.join(oni.problems)})")
                depth = oni.stream("depth")
                stamps, n_frames, streams = depth.timestamps_us.copy(), depth.n_frames, [s.kind for s in oni.streams]
        zero_clock, matched, shift = _oni_zero_clock(status["frames"], stamps, str(take / ONI))
        if len(status["frames"]) != n_frames:
            problems.append(
                f"the session read {len(status['frames'])} depth frames, the recorder wrote {n_frames}: "
                "the clock placement assumes they begin with the same frame"
            )
        doc: dict[str, Any] = {
            "format": FORMAT,
            "format_version": 1,
            "started": started,
            "clock": CLOCK,
            "device": status["device"],
            "oni": {
                "file": ONI,
                "streams": streams,
                "depth_frames": n_frames,
                "zero_clock_s": zero_clock,
                "frames_read": len(status["frames"]),
                "frames_matched_to_clock": matched,
            },
            "skeleton": None,
            "audio": None,
            "offset_s": None,
            "problems": problems,
        }
        if status.get("skeleton") is not None:
            try:  # the device's timestamps, rebased like the .oni's
                doc["skeleton"] = _write_skeleton(take, status["skeleton"], shift)
            except KinectDataError as exc:  # nobody tracked: the recording and the music are kept
                problems.append(f"no skeleton: {exc}")
        elif status.get("skeleton_problem"):
            problems.append(status["skeleton_problem"])
        if audio is not None:
            doc["audio"] = {
                "file": WAV,
                "device": str(audio_device),
                "sample_rate": sample_rate,
                "frames": audio.frames,
                "first_sample_clock_s": audio.first_sample_clock_s,
                "overflows": audio.overflows,
            }
            doc["offset_s"] = zero_clock - audio.first_sample_clock_s
        with atomic_output(take / TAKE) as tmp:
            tmp.write_text(json.dumps(doc, indent=2) + "\n")
    except BaseException:  # no half take: remove what this capture wrote
        for path in written:
            path.unlink(missing_ok=True)
        raise
    return doc


def _run_session(take: Path, device, duration_s, color, lossy, nite_folder) -> dict[str, Any]:
    """Record with OpenNI2 in a child process; its status, or an error naming the device."""
    with tempfile.TemporaryDirectory() as tmp:
        settings = {
            "openni2_dir": str(openni2_dir()),
            "device": device,
            "oni": str(take / ONI),
            "duration": duration_s,
            "color": color,
            "lossy": lossy,
            "nite_dir": nite_folder,
            "status": str(Path(tmp) / "status.json"),
        }
        (Path(tmp) / "settings.json").write_text(json.dumps(settings))
        try:
            done = subprocess.run(
                [sys.executable, "-m", "kinectdata.capture.openni_session", str(Path(tmp) / "settings.json")],
                capture_output=True,
                text=True,
                timeout=duration_s + 120,
            )
        except subprocess.TimeoutExpired:
            (take / ONI).unlink(missing_ok=True)
            raise KinectDataError(f"OpenNI2 device {device or '(first)'}: the recording did not finish") from None
        status_path = Path(tmp) / "status.json"
        if not status_path.exists():  # crashed before reporting (a crash after it is OpenNI2's unload)
            (take / ONI).unlink(missing_ok=True)
            raise KinectDataError(
                f"OpenNI2 device {device or '(first)'}: the recording process failed "
                f"(exit {done.returncode}): {done.stderr.strip()[-400:]}"
            )
        status = json.loads(status_path.read_text())
    if "error" in status:
        (take / ONI).unlink(missing_ok=True)
        raise KinectDataError(f"OpenNI2 device {device or '(first)'}: {status['error']}")
    return status


def _write_skeleton(take: Path, tracked: list, shift_us: float) -> dict[str, Any]:
    """take.csv from the live tracker's frames, whose device timestamps minus ``shift_us`` are
    the .oni's."""
    from kinectdata.formats.csv_writer import write_csv

    frames = [
        TrackedFrame(int(round(t - shift_us)), int(i), {int(u): np.array(j) for u, j in users.items()})
        for t, i, users in tracked
    ]
    motion = nite_motion(frames, str(take / ONI))
    origin_s = motion.metadata["time_origin"]["value"] / 1e6
    write_csv(motion, take / CSV, "canonical", time_origin=origin_s, comments={"tracked_by": "NiTE2 (live)"})
    return {"file": CSV, "user": motion.metadata["user"], "frames": motion.n_frames}


def read_take(take_dir: str | os.PathLike) -> dict[str, Any]:
    """A take folder's ``take.json``."""
    path = Path(take_dir) / TAKE
    try:
        doc = json.loads(path.read_text())
    except OSError as exc:
        raise KinectDataError(f"{take_dir}: not a take (no readable {TAKE}: {exc.strerror or exc})") from exc
    except ValueError as exc:
        raise KinectDataError(f"{path}: not valid JSON ({exc})") from exc
    if doc.get("format") != FORMAT:
        raise KinectDataError(f"{path}: not a kinectdata take (format {doc.get('format')!r})")
    return doc


def is_take(path: str | os.PathLike) -> bool:
    return Path(path).is_dir() and (Path(path) / TAKE).is_file()
