"""A stand-in for pyk4a (github.com/etiennedub/pyk4a, 1.5.0's API, MIT) with a simulated Azure
Kinect behind it: what the capture tests drive instead of a device, as the OpenNI2 tests drive
OpenNI2's Dummy device. The Azure Kinect SDK has no virtual device, so this stands in for the
library: the names and behaviour kinectdata's session uses, written from pyk4a's sources
(pyk4a/config.py, pyk4a.py, capture.py, record.py, errors.py) and the SDK's timing documentation.

The simulated camera: frame k is exposed at clock time ``t0 + k / fps`` (``t0`` when started, on
``time.monotonic()``), stamped on the device clock ``d0 + k * 1e6 / fps`` us (a few us of jitter),
stamped on the host ``HOST_DELAY_S`` (plus up to 2 ms) later, as the SDK does on Linux with
``CLOCK_MONOTONIC``, and handed to ``get_capture`` 1-3 ms after that. ``PyK4ARecord`` writes the
takes it is given as a real ``.mkv`` in k4arecorder's layout (:mod:`reference.k4a_writer`) when
closed: depth and IR tracks (colour as MJPEG when on), the calibration attachment and serial
number when given the device, no IMU track (pyk4a cannot write one).

Set by environment variables, so that a session in a child process sees them:

- ``FAKE_K4A_DEVICES``: how many devices are connected (default 1);
- ``FAKE_K4A_HOST_CLOCK``: ``monotonic`` (the SDK on Linux) or ``wall`` (Orbbec's K4A wrapper:
  host stamps from the wall clock in whole milliseconds, device times synced to the epoch);
- ``FAKE_K4A_LOST_AFTER``: ``get_capture`` raises ``K4AException`` after this many captures (USB lost);
- ``FAKE_K4A_STALL_AFTER``: captures stop coming after this many (timeouts);
- ``FAKE_K4A_CRASH_AFTER``: the process dies after this many captures (the file never closed).
"""

from __future__ import annotations

import io
import json
import os
import time
from enum import IntEnum
from pathlib import Path

import numpy as np

from reference.k4a_writer import VideoTrack, depth_track, write_k4a

HOST_DELAY_S = 0.004  # exposure's middle to the host stamp (readout and USB)
DEVICE_START_US = 345_678  # the device clock when the cameras start (it restarts with them)
SERIAL = "000123412345"
CALIBRATION = {"CalibrationInformation": {"Cameras": [], "InertialSensors": []}}
DEPTH_SIZES = {"NFOV_2X2BINNED": (320, 288), "NFOV_UNBINNED": (640, 576), "WFOV_2X2BINNED": (512, 512),
               "WFOV_UNBINNED": (1024, 1024), "PASSIVE_IR": (1024, 1024)}  # fmt: skip
COLOR_HEIGHTS = {1: 720, 2: 1080, 3: 1440, 4: 1536, 5: 2160, 6: 3072}


class FPS(IntEnum):
    FPS_5 = 0
    FPS_15 = 1
    FPS_30 = 2


class ImageFormat(IntEnum):
    COLOR_MJPG = 0
    COLOR_NV12 = 1
    COLOR_YUY2 = 2
    COLOR_BGRA32 = 3
    DEPTH16 = 4
    IR16 = 5


class DepthMode(IntEnum):
    OFF = 0
    NFOV_2X2BINNED = 1
    NFOV_UNBINNED = 2
    WFOV_2X2BINNED = 3
    WFOV_UNBINNED = 4
    PASSIVE_IR = 5


class ColorResolution(IntEnum):
    OFF = 0
    RES_720P = 1
    RES_1080P = 2
    RES_1440P = 3
    RES_1536P = 4
    RES_2160P = 5
    RES_3072P = 6


class K4AException(Exception):
    pass


class K4ATimeoutException(K4AException):
    pass


class Config:
    def __init__(
        self,
        color_resolution=ColorResolution.RES_720P,
        color_format=ImageFormat.COLOR_BGRA32,
        depth_mode=DepthMode.NFOV_UNBINNED,
        camera_fps=FPS.FPS_30,
        synchronized_images_only=True,
        **others,
    ):
        self.color_resolution, self.color_format = ColorResolution(color_resolution), ImageFormat(color_format)
        self.depth_mode, self.camera_fps = DepthMode(depth_mode), FPS(camera_fps)
        self.synchronized_images_only = synchronized_images_only

    @property
    def fps(self) -> int:
        return (5, 15, 30)[self.camera_fps]


def _setting(name: str) -> int | None:
    value = os.environ.get(name)
    return None if value is None else int(value)


def connected_device_count() -> int:
    return _setting("FAKE_K4A_DEVICES") if "FAKE_K4A_DEVICES" in os.environ else 1


def _jpeg(width: int, height: int) -> np.ndarray:
    from PIL import Image

    out = io.BytesIO()
    Image.new("RGB", (width, height), (40, 90, 160)).save(out, "JPEG", quality=50)
    return np.frombuffer(out.getvalue(), np.uint8)


class PyK4ACapture:
    """One capture: images (None where absent) and their device (us) and host (ns) stamps."""

    def __init__(self, device: PyK4A, k: int, device_us: int, host_ns: int) -> None:
        config = device._config
        self.depth = self.ir = self.color = None
        self.depth_timestamp_usec = self.ir_timestamp_usec = self.color_timestamp_usec = 0
        self.depth_system_timestamp_nsec = self.ir_system_timestamp_nsec = self.color_system_timestamp_nsec = 0
        if config.depth_mode != DepthMode.OFF:
            w, h = DEPTH_SIZES[config.depth_mode.name]
            ir = np.full((h, w), 100 + k, np.uint16)
            if config.depth_mode != DepthMode.PASSIVE_IR:
                self.depth = np.full((h, w), 1000 + k, np.uint16)
                self.depth_timestamp_usec, self.depth_system_timestamp_nsec = device_us, host_ns
            self.ir, self.ir_timestamp_usec, self.ir_system_timestamp_nsec = ir, device_us, host_ns
        if config.color_resolution != ColorResolution.OFF:
            self.color = device._jpeg
            self.color_timestamp_usec, self.color_system_timestamp_nsec = device_us, host_ns


class PyK4A:
    def __init__(self, config: Config | None = None, device_id: int = 0, thread_safe: bool = True) -> None:
        self._config = config or Config()
        self._device_id = device_id
        self.opened = self.is_running = False
        self.serial = SERIAL
        self.calibration_raw = json.dumps(CALIBRATION)
        self._rng = np.random.default_rng(device_id)

    def start(self) -> None:
        if self._device_id >= connected_device_count():
            raise K4AException()  # pyk4a's, from k4a_device_open: no message
        config = self._config
        if config.color_resolution != ColorResolution.OFF:
            height = COLOR_HEIGHTS[config.color_resolution]
            self._jpeg = _jpeg(height * 4 // 3 if height in (1536, 3072) else height * 16 // 9, height)
        self.opened = self.is_running = True
        self._k = 0
        self._t0 = time.monotonic()
        wall = os.environ.get("FAKE_K4A_HOST_CLOCK") == "wall"
        self._d0 = int(time.time() * 1e6) if wall else DEVICE_START_US  # Orbbec's: synced to the epoch
        self._wall_minus_monotonic = time.time() - time.monotonic() if wall else 0.0

    def stop(self) -> None:
        self.opened = self.is_running = False

    def get_capture(self, timeout: int = -1) -> PyK4ACapture:
        if not self.is_running:
            raise K4AException("Device is not opened")
        k = self._k
        if k == _setting("FAKE_K4A_CRASH_AFTER"):
            os._exit(3)
        if k == _setting("FAKE_K4A_LOST_AFTER"):
            raise K4AException()
        stall = _setting("FAKE_K4A_STALL_AFTER")
        if stall is not None and k >= stall:
            time.sleep(timeout / 1000 if timeout >= 0 else 3600)
            raise K4ATimeoutException()
        exposed = self._t0 + k / self._config.fps
        host = exposed + HOST_DELAY_S + self._rng.uniform(0, 0.002)
        handed = host + self._rng.uniform(0.001, 0.003)
        time.sleep(max(0.0, handed - time.monotonic()))
        self._k += 1
        device_us = self._d0 + round(k * 1e6 / self._config.fps) + int(self._rng.integers(-3, 4))
        if self._wall_minus_monotonic:
            host_ns = int(round((host + self._wall_minus_monotonic) * 1e3)) * 1_000_000  # whole ms
        else:
            host_ns = int(host * 1e9)
        return PyK4ACapture(self, k, device_us, host_ns)

    @property
    def exposure_clock_s(self) -> float:
        """For the tests: the clock time at which device time 0 would have been exposed."""
        return self._t0 - self._d0 / 1e6


class PyK4ARecord:
    def __init__(self, path, config: Config, device: PyK4A | None = None, thread_safe: bool = True) -> None:
        self._path, self._config, self._device = Path(path), config, device
        self._captures: list[PyK4ACapture] = []
        self.created = self.header_written = False

    @property
    def captures_count(self) -> int:
        return len(self._captures)

    @property
    def path(self) -> Path:
        return self._path

    def create(self) -> None:
        if not self._path.parent.is_dir():
            raise K4AException(f"Cannot create record {self._path}")
        self._path.write_bytes(b"")  # the SDK creates the file here and writes as it goes
        self.created = True

    def write_header(self) -> None:
        self.header_written = True

    def write_capture(self, capture: PyK4ACapture) -> None:
        if not self.created:
            raise K4AException("Record not created.")
        self.header_written = True
        self._captures.append(capture)

    def flush(self) -> None:
        if not self.created:
            raise K4AException("Record not created.")

    def close(self) -> None:
        if not self.created:
            raise K4AException("Record not created.")
        config, caps = self._config, self._captures
        videos = []
        if config.color_resolution != ColorResolution.OFF:
            height = COLOR_HEIGHTS[config.color_resolution]
            width = height * 4 // 3 if height in (1536, 3072) else height * 16 // 9
            frames = [c for c in caps if c.color is not None]
            videos.append(
                VideoTrack("COLOR", "MJPG", width, height, [c.color.tobytes() for c in frames],
                           [c.color_timestamp_usec * 1000 for c in frames], {"K4A_COLOR_MODE": f"MJPG_{height}P"})
            )  # fmt: skip
        if config.depth_mode != DepthMode.OFF:
            if config.depth_mode != DepthMode.PASSIVE_IR:
                frames = [c for c in caps if c.depth is not None]
                images = np.stack([c.depth for c in frames])
                videos.append(depth_track("DEPTH", images, [c.depth_timestamp_usec * 1000 for c in frames],
                                          config.depth_mode.name))  # fmt: skip
            frames = [c for c in caps if c.ir is not None]
            mode = "PASSIVE" if config.depth_mode == DepthMode.PASSIVE_IR else "ACTIVE"
            videos.append(depth_track("IR", np.stack([c.ir for c in frames]),
                                      [c.ir_timestamp_usec * 1000 for c in frames], mode))  # fmt: skip
        tags = {"K4A_DEPTH_DELAY_NS": "0", "K4A_WIRED_SYNC_MODE": "STANDALONE"}
        calibration = None
        if self._device is not None:
            tags["K4A_DEVICE_SERIAL_NUMBER"] = self._device.serial
            calibration = json.loads(self._device.calibration_raw)
        if caps:
            write_k4a(self._path, videos, None, fps=config.fps, calibration=calibration, global_tags=tags)
        self.created = False
