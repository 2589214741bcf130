"""An OpenNI2 sensor's part of a take: ``take.oni`` by OpenNI2's recorder (depth, and colour), the
live NiTE2 skeleton as ``take.csv`` when NiTE2 is installed, and the ``.oni``'s time 0 on the
take's clock.

The ``.oni``'s time 0 is placed on the clock by the depth frames the session read: each one's
arrival time minus its device timestamp, the earliest of them (the frame that waited least); the
device timestamps are matched to the file's, which OpenNI2 rebases to start at 0. Sensor
latency before arrival is not known, so the placement errs by that (a few milliseconds for USB
depth cameras).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from kinectdata.capture.child import run_session
from kinectdata.capture.sensor import SensorTake
from kinectdata.core.errors import KinectDataError
from kinectdata.oni.reader import OniFile, OniWarning
from kinectdata.oni.skeleton import TrackedFrame, find_nite, nite_motion, openni2_dir

ONI, CSV = "take.oni", "take.csv"


@dataclass(frozen=True)
class OpenNI2Sensor:
    """An OpenNI2 device to record from.

    Attributes:
        device: OpenNI2 device URI (``Dummy`` for OpenNI2's test device); None: the first one.
        color: record the colour stream too; lossy: let OpenNI2 store it as JPEG.
        skeleton: track the skeleton live with NiTE2 when it is installed (a problem noted when not).
        nite_dir: where NiTE2 is (None: the usual places, :func:`kinectdata.oni.skeleton.find_nite`).
    """

    device: str | None = None
    color: bool = False
    lossy: bool = False
    skeleton: bool = True
    nite_dir: str | None = None

    kind: ClassVar[str] = "openni2"
    files: ClassVar[tuple[str, ...]] = (ONI, CSV)

    @property
    def what(self) -> str:
        return _device_name(self.device)

    def record(self, take: Path, duration_s: float, problems: list[str]) -> SensorTake:
        """Record ``duration_s`` seconds into ``take``; ``problems`` gathers what is doubtful."""
        nite_folder = None
        if self.skeleton:
            try:
                nite_folder = str(find_nite(self.nite_dir))
            except KinectDataError as exc:
                problems.append(f"no skeleton: {exc}")
        status = _run_session(take, self.device, duration_s, self.color, self.lossy, nite_folder)
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
        entry = {
            "file": ONI,
            "streams": streams,
            "depth_frames": n_frames,
            "zero_clock_s": zero_clock,
            "frames_read": len(status["frames"]),
            "frames_matched_to_clock": matched,
        }
        skeleton = None
        if status.get("skeleton") is not None:
            try:  # the device's timestamps, rebased like the .oni's
                skeleton = _write_skeleton(take, status["skeleton"], shift)
            except KinectDataError as exc:  # nobody tracked: the recording and the music are kept
                problems.append(f"no skeleton: {exc}")
        elif status.get("skeleton_problem"):
            problems.append(status["skeleton_problem"])
        return SensorTake(status["device"], "oni", entry, skeleton, problems)

    def describe(self, doc: dict[str, Any], take: str) -> list[str]:
        """The lines ``kinectdata capture`` prints about this sensor's files."""
        oni = doc["oni"]
        lines = [
            f"wrote {take}/{ONI}: {oni['depth_frames']} depth frames ({', '.join(oni['streams'])}) "
            f"from {doc['device']['uri']}"
        ]
        if doc["skeleton"]:
            lines.append(f"wrote {take}/{doc['skeleton']['file']}: {doc['skeleton']['frames']} skeleton frames")
        return lines


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


def _run_session(take: Path, device, duration_s, color, lossy, nite_folder) -> dict[str, Any]:
    """Record with OpenNI2 in a child process (:mod:`.openni_session`); its status."""
    settings = {
        "openni2_dir": str(openni2_dir()),
        "device": device,
        "oni": str(take / ONI),
        "duration": duration_s,
        "color": color,
        "lossy": lossy,
        "nite_dir": nite_folder,
    }
    name = _device_name(device)
    return run_session("kinectdata.capture.openni_session", settings, name, duration_s + 120, take / ONI)


def _device_name(device: str | None) -> str:
    """How messages name an OpenNI2 device (by its URI; None: the first)."""
    return f"OpenNI2 device {device or '(first)'}"


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
