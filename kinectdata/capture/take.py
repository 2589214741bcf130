"""A take: sensor, skeleton and music recorded together, on one clock, in one folder.

``capture_take`` writes ``TAKE/``:

- the sensor's recording: ``take.oni`` (an OpenNI2 device, by OpenNI2's recorder:
  :mod:`.openni`) or ``take.mkv`` (an Azure Kinect or Orbbec Femto, by the SDK's recorder through
  pyk4a: :mod:`.k4a`);
- ``take.csv``: the live NiTE2 skeleton (OpenNI2, when NiTE2 is installed; canonical CSV, times =
  the ``.oni``'s depth timestamps in seconds). An Azure Kinect's skeleton comes later, from the
  Body Tracking SDK's offline processor run on ``take.mkv``, saved as ``take_body.json``;
- ``take.wav``: audio from an input device, when one is given;
- ``take.json``: what was recorded and when, on the monotonic clock (``time.monotonic()``, the
  same for every process of the machine): ``sensor`` (``openni2``, ``k4a``), the clock time of the
  recording's time 0 (``oni`` or ``mkv`` → ``zero_clock_s``) and of the audio's first sample, and
  from them the offset ``audio_time = recording_time + offset_s``.

How each sensor's file is placed on the clock, and what that placement errs by, is in its module.
:func:`kinectdata.align.take.align_take` then aligns the take's skeleton with its audio with that
offset: no clap, no estimate.
"""

from __future__ import annotations

import json
import os
import warnings
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from kinectdata.capture.audio import AudioCapture
from kinectdata.capture.openni import OpenNI2Sensor
from kinectdata.capture.sensor import Sensor
from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError, KinectDataWarning

TAKE = "take.json"
WAV = "take.wav"
FORMAT = "kinectdata.take"
FORMAT_VERSION = 2  # 2: ``sensor`` and the ``mkv`` entry; a version 1 take is an OpenNI2 one
CLOCK = "monotonic (time.monotonic), seconds"


class CaptureWarning(KinectDataWarning):
    """A take was recorded but something in it is doubtful (timing, dropped frames)."""


def capture_take(
    out_dir: str | os.PathLike,
    sensor: Sensor | None = None,
    *,
    duration_s: float = 10.0,
    audio_device: int | str | None = None,
    sample_rate: int = 48000,
    audio_stream_factory=None,
) -> dict[str, Any]:
    """Record a take into ``out_dir`` (see the module docstring); returns ``take.json``'s content.

    Args:
        sensor: the device and its settings (:class:`~kinectdata.capture.openni.OpenNI2Sensor`,
            the default, or :class:`~kinectdata.capture.k4a.K4aSensor`).
        duration_s: seconds of recording.
        audio_device: sounddevice input (index or name); None: no audio.
        audio_stream_factory: the audio input stream class (default ``sounddevice.InputStream``).

    Doubts about the take (no skeleton, frames the recorder and the session saw differently, the
    clock placed by arrival times) are in ``problems`` and emitted as :class:`CaptureWarning`.

    Raises:
        KinectDataError: the folder already holds a take, the device or audio cannot record, or
            the recording came out incomplete; partial files are removed.
    """
    sensor = sensor if sensor is not None else OpenNI2Sensor()
    take = Path(out_dir)
    written = [take / name for name in (*sensor.files, WAV)]
    existing = [path.name for path in [take / TAKE, *written] if path.exists()]
    if existing:
        raise KinectDataError(f"{take}: already holds a take ({', '.join(existing)}); choose another folder")
    take.mkdir(parents=True, exist_ok=True)
    problems: list[str] = []
    audio = None
    try:
        try:
            if audio_device is not None:
                audio = AudioCapture(take / WAV, audio_device, sample_rate, stream_factory=audio_stream_factory)
                audio.start()
            started = datetime.now(timezone.utc).isoformat(timespec="seconds")
            recorded = sensor.record(take, duration_s, problems)
        finally:
            if audio is not None:
                audio.stop()
        doc: dict[str, Any] = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "started": started,
            "clock": CLOCK,
            "sensor": sensor.kind,
            "device": recorded.device,
            recorded.key: recorded.entry,
            "skeleton": recorded.skeleton,
            "audio": None,
            "offset_s": None,
            "problems": problems,
        }
        if audio is not None:
            doc["audio"] = {
                "file": WAV,
                "device": str(audio_device),
                "sample_rate": sample_rate,
                "frames": audio.frames,
                "first_sample_clock_s": audio.first_sample_clock_s,
                "overflows": audio.overflows,
            }
            doc["offset_s"] = recorded.zero_clock_s - audio.first_sample_clock_s
        with atomic_output(take / TAKE) as tmp:
            tmp.write_text(json.dumps(doc, indent=2) + "\n")
    except BaseException:  # no half take: remove what this capture wrote
        for path in written:
            path.unlink(missing_ok=True)
        raise
    for problem in problems:
        warnings.warn(problem, CaptureWarning, stacklevel=2)
    return doc


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
    if doc.get("format_version", 1) > FORMAT_VERSION:
        raise KinectDataError(
            f"{path}: a take of format version {doc['format_version']}, newer than this kinectdata reads "
            f"({FORMAT_VERSION}); update kinectdata"
        )
    doc.setdefault("sensor", "openni2")  # version 1 takes were all OpenNI2's
    return doc


def describe_take(take_dir: str | os.PathLike) -> list[str]:
    """The lines ``kinectdata info TAKE/`` prints: the sensor and its recording, the audio, the offset
    between them, the skeleton (or how to make one) and the take's doubts."""
    take = Path(take_dir)
    doc = read_take(take)
    lines = [f"take            {take} ({doc['sensor']}, started {doc.get('started', '?')})"]
    if doc["sensor"] == "k4a":
        mkv = doc["mkv"]
        lines.append(
            f"recording       {mkv['file']}: {mkv['frames']} {mkv['clock_track'].lower()} frames "
            f"({', '.join(mkv['tracks'])}) from Azure Kinect {doc['device'].get('serial', '?')}; placed on the clock "
            f"by {'the SDK host timestamps' if mkv['placed_by'] == 'host' else 'arrival times'}"
        )
        skeleton = "take_body.json"
        make = f"the Azure Kinect Body Tracking SDK's offline processor on {mkv['file']}, its JSON saved as {skeleton}"
    else:
        oni = doc["oni"]
        lines.append(
            f"recording       {oni['file']}: {oni['depth_frames']} depth frames ({', '.join(oni['streams'])}) "
            f"from {doc['device'].get('uri', '?')}"
        )
        skeleton = doc["skeleton"]["file"] if doc.get("skeleton") else "take.csv"
        make = f"kinectdata oni skeleton {take / oni['file']} -o {take / skeleton}"
    if (take / skeleton).is_file():
        lines.append(f"skeleton        {skeleton}")
    else:
        lines.append(f"skeleton        none yet ({make})")
    audio = doc.get("audio")
    if audio:
        seconds = audio["frames"] / audio["sample_rate"]
        lines.append(
            f"audio           {audio['file']}: {seconds:.2f} s at {audio['sample_rate']} Hz from input "
            f"{audio['device']}, {audio.get('overflows', 0)} overflows"
        )
        lines.append(f"offset          {doc['offset_s']:+.4f} s (audio_time = recording_time + offset), from the clock")
    else:
        lines.append("audio           none (captured without --audio-device)")
    lines += [f"doubt           {problem}" for problem in doc.get("problems", [])]
    if audio and (take / skeleton).is_file():
        lines.append(f"next            kinectdata align {take} -o take.h5")
    return lines


def is_take(path: str | os.PathLike) -> bool:
    return Path(path).is_dir() and (Path(path) / TAKE).is_file()
