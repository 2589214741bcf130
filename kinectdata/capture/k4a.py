"""An Azure Kinect's (or Orbbec Femto's, through Orbbec's K4A wrapper) part of a take:
``take.mkv`` in k4arecorder's layout by the SDK's own recorder through pyk4a, and the file's time
0 on the take's clock.

The device stamps each image with its own clock (microseconds, :attr:`device`); the SDK also
stamps it on the host when its last byte arrives (on Linux ``CLOCK_MONOTONIC``, the clock of
``time.monotonic()``: src/image/image.c, src/usbcommand/usbstreaming.c of the Azure Kinect Sensor
SDK). The device clock's zero on the take's clock is the least of host time less device time
over the captures (the image that waited least; the estimator of the Azure Kinect ROS driver's
``updateTimestampOffset``), and the file's time 0 is the device time ``K4A_START_OFFSET_NS``. Host
stamps that do not precede their capture's arrival by less than a second are not on this
clock (Orbbec's wrapper stamps the wall clock, in milliseconds: OrbbecSDK-K4A-Wrapper
src/orbbec/ob_k4a_impl.cpp); the arrival times in the session stand in for them then, which err
by the SDK's processing too (a few milliseconds), and ``take.json`` says which was used.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from kinectdata.capture.child import run_session
from kinectdata.capture.k4a_session import KINDS
from kinectdata.capture.sensor import SensorTake
from kinectdata.core.errors import KinectDataError
from kinectdata.mkv.calibration import COLOR_MODES, DEPTH_MODES
from kinectdata.mkv.recording import K4aRecording, MkvError, MkvWarning

MKV, BODY = "take.mkv", "take_body.json"
FPS_CHOICES = (5, 15, 30)
HOST_LEAD_S = 1.0  # a host stamp is on the take's clock when its capture arrives within this after it
HOST_SHARE = 0.9  # ... for at least this share of the captures


@dataclass(frozen=True)
class K4aSensor:
    """An Azure Kinect (or Femto through Orbbec's K4A wrapper) to record from, through pyk4a.

    Attributes:
        device_index: the SDK's device index (0: the first connected).
        depth_mode: ``NFOV_UNBINNED``, ``NFOV_2X2BINNED``, ``WFOV_UNBINNED``, ``WFOV_2X2BINNED``,
            ``PASSIVE_IR`` or ``OFF`` (the SDK's names).
        color_resolution: ``OFF``, ``720P``, ``1080P``, ``1440P``, ``1536P``, ``2160P``, ``3072P``
            (recorded as the camera's MJPEG, as k4arecorder does).
        fps: 5, 15 or 30 frames per second (WFOV_UNBINNED and 3072P run at most 15).
        module: the Python module that provides pyk4a's API (``pyk4a``; tests give a fake).
    """

    device_index: int = 0
    depth_mode: str = "NFOV_UNBINNED"
    color_resolution: str = "OFF"
    fps: int = 30
    module: str = "pyk4a"

    kind: ClassVar[str] = "k4a"
    files: ClassVar[tuple[str, ...]] = (MKV,)

    def __post_init__(self) -> None:
        depth_modes = ("OFF", *DEPTH_MODES)
        resolutions = ("OFF", *(f"{height}P" for height in COLOR_MODES))
        if self.depth_mode not in depth_modes:
            raise KinectDataError(f"depth mode {self.depth_mode!r}: not one of {', '.join(depth_modes)}")
        if self.color_resolution not in resolutions:
            raise KinectDataError(f"colour resolution {self.color_resolution!r}: not one of {', '.join(resolutions)}")
        if self.fps not in FPS_CHOICES:
            raise KinectDataError(f"{self.fps} fps: an Azure Kinect runs at 5, 15 or 30")
        if self.depth_mode == "OFF" and self.color_resolution == "OFF":
            raise KinectDataError("depth mode OFF and colour OFF: nothing to record")
        too_fast = [m for m in (self.depth_mode, self.color_resolution) if m in ("WFOV_UNBINNED", "3072P")]
        if too_fast and self.fps == 30:
            raise KinectDataError(f"{too_fast[0]} runs at most at 15 fps (the SDK refuses 30)")

    @property
    def what(self) -> str:
        return f"Azure Kinect device {self.device_index}"

    @property
    def clock_image(self) -> str:
        """The image kind whose timestamps place the file on the clock: depth when recorded."""
        if self.depth_mode == "PASSIVE_IR":
            return "ir"
        return "depth" if self.depth_mode != "OFF" else "color"

    def record(self, take: Path, duration_s: float, problems: list[str]) -> SensorTake:
        """Record ``duration_s`` seconds into ``take/take.mkv`` (see the module docstring)."""
        settings = {
            "module": self.module,
            "device_index": self.device_index,
            "depth_mode": self.depth_mode,
            "color_resolution": self.color_resolution,
            "fps": self.fps,
            "mkv": str(take / MKV),
            "duration": duration_s,
        }
        status = run_session("kinectdata.capture.k4a_session", settings, self.what, duration_s + 60, take / MKV)
        track = self.clock_image.upper()  # the SDK's track names: DEPTH, IR, COLOR
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", MkvWarning)
                with K4aRecording(take / MKV) as mkv:
                    if mkv.problems:
                        raise KinectDataError(f"{take / MKV}: the recording is incomplete ({'; '.join(mkv.problems)})")
                    tracks = list(mkv.tracks)
                    file_device_us = mkv.device_times_us(mkv.track(track))
                    start_offset_us = float(mkv.start_offset_us)
        except (MkvError, KinectDataError):
            (take / MKV).unlink(missing_ok=True)
            raise
        column = KINDS.index(self.clock_image)
        with_image = [frame for frame in status["frames"] if frame[column]]
        stamps = np.array([frame[column] for frame in with_image], np.float64).reshape(-1, 2)
        arrival = np.array([frame[-1] for frame in with_image], np.float64)
        if not len(stamps):
            (take / MKV).unlink(missing_ok=True)
            raise KinectDataError(f"{self.what}: no {self.clock_image} image arrived in {duration_s:g} s")
        placed = device_clock_zero(stamps[:, 0], stamps[:, 1], arrival)
        matched = int(np.isin(np.round(stamps[:, 0]), np.round(file_device_us)).sum())
        if matched < len(stamps):
            problems.append(
                f"{len(stamps) - matched} of the {len(stamps)} {self.clock_image} images the session read are "
                f"not in {MKV}"
            )
        if placed.source == "arrival":
            problems.append(
                "the SDK's host timestamps are not on this machine's monotonic clock (Orbbec's K4A wrapper stamps "
                "the wall clock): the file is placed by the captures' arrival times, which err by the SDK's "
                "processing delay too"
            )
        if status.get("timeouts"):
            problems.append(f"{status['timeouts']} waits for a capture timed out")
        entry = {
            "file": MKV,
            "tracks": tracks,
            "clock_track": track,
            "frames": int(len(file_device_us)),
            "start_offset_us": start_offset_us,
            "zero_clock_s": placed.zero_clock_s + start_offset_us / 1e6,
            "device_zero_clock_s": placed.zero_clock_s,
            "placed_by": placed.source,
            "host_delay_ms": placed.delay_ms,
            "frames_read": len(status["frames"]),
            "frames_matched_to_clock": matched,
            "settings": {
                "depth_mode": self.depth_mode,
                "color_resolution": self.color_resolution,
                "fps": self.fps,
            },
        }
        return SensorTake(status["device"], "mkv", entry, None, problems)

    def describe(self, doc: dict[str, Any], take: str) -> list[str]:
        mkv = doc["mkv"]
        return [
            f"wrote {take}/{MKV}: {mkv['frames']} {mkv['clock_track'].lower()} frames ({', '.join(mkv['tracks'])}) "
            f"from Azure Kinect {doc['device']['serial']}; body tracking: run the Azure Kinect Body Tracking SDK's "
            f"offline processor on it and save its JSON as {take}/{BODY}"
        ]


@dataclass(frozen=True)
class ClockPlacement:
    """Where the device clock's zero is on the take's clock.

    Attributes:
        zero_clock_s: the take's clock (``time.monotonic()``) at device time 0, seconds.
        source: ``host`` (the SDK's host timestamps) or ``arrival`` (the session's arrival times).
        delay_ms: the median time from a host stamp to its capture's arrival in the session, ms
            (None when the host stamps were not used).
    """

    zero_clock_s: float
    source: str
    delay_ms: float | None


def device_clock_zero(device_us: np.ndarray, host_ns: np.ndarray, arrival_s: np.ndarray) -> ClockPlacement:
    """Place a device clock on the take's clock from images' device stamps [N] (us), the SDK's
    host stamps [N] (ns; 0 where the library gave none) and the captures' arrival times [N] (s):
    the least host time less device time, when the host stamps are on the take's clock, else the
    least arrival time less device time."""
    device_s = np.asarray(device_us, np.float64) / 1e6
    host_s = np.asarray(host_ns, np.float64) / 1e9
    arrival_s = np.asarray(arrival_s, np.float64)
    lead = arrival_s - host_s
    on_clock = (host_s > 0) & (lead >= 0) & (lead <= HOST_LEAD_S)
    if on_clock.mean() >= HOST_SHARE:
        return ClockPlacement(
            float(np.min(host_s[on_clock] - device_s[on_clock])), "host", float(np.median(lead[on_clock]) * 1e3)
        )
    return ClockPlacement(float(np.min(arrival_s - device_s)), "arrival", None)
