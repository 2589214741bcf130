"""The Azure Kinect side of a capture, run in its own process (``python -m
kinectdata.capture.k4a_session SETTINGS.json``; :mod:`.child`).

pyk4a (MIT; github.com/etiennedub/pyk4a) holds Python's lock during each blocking SDK call unless
the device is opened with ``thread_safe=False``; in its own process, used from one thread, it
cannot starve the audio callback of the parent. The session opens the device, records every
capture with the SDK's own recorder (``PyK4ARecord`` = ``k4a_record_*``: the k4arecorder layout,
calibration attachment included, but no IMU track: pyk4a does not bind it), and notes for each
capture its images' device timestamps (microseconds), the SDK's host timestamps (nanoseconds;
on Linux ``CLOCK_MONOTONIC``, the clock of ``time.monotonic()``) and its arrival time on
``time.monotonic()``. The parent (:mod:`.k4a`) places the file on the take's clock from them.

``settings["module"]`` names the module that provides pyk4a's API: ``pyk4a``, or a stand-in
(the tests' fake device).
"""

from __future__ import annotations

import importlib
import sys
import time
from typing import Any

from kinectdata.capture.child import session_main

KINDS = ("depth", "ir", "color")
"""The images noted per capture, in the order of each row of the status's ``frames``."""
TIMEOUT_MS = 1000  # one capture waited for at most this long (a 5 fps camera delivers every 200 ms)
MAX_TIMEOUTS = 3  # in a row: the camera stopped delivering


def _stamps(capture: Any, kind: str) -> list | None:
    """[device us, host ns] of one image of ``capture`` (``depth``, ``ir``, ``color``), None when absent."""
    if getattr(capture, kind) is None:
        return None
    return [int(getattr(capture, f"{kind}_timestamp_usec")), int(getattr(capture, f"{kind}_system_timestamp_nsec"))]


def run(settings: dict[str, Any], k4a: Any = None) -> dict[str, Any]:
    """Record; the status: ``device`` (serial, index), ``frames`` (per capture: depth, ir and
    color as [device us, host ns] or None, then the arrival time in s), ``timeouts``, or ``error``."""
    if k4a is None:
        try:
            k4a = importlib.import_module(settings.get("module", "pyk4a"))
        except ImportError as exc:
            return {
                "error": f"pyk4a cannot be imported ({exc}); it needs the Azure Kinect Sensor SDK (or Orbbec's "
                "K4A wrapper) and `pip install 'kinectdata[k4a]'`"
            }
    color_on = settings["color_resolution"] != "OFF"
    depth_on = settings["depth_mode"] != "OFF"
    config = k4a.Config(
        color_resolution=getattr(k4a.ColorResolution, "OFF" if not color_on else "RES_" + settings["color_resolution"]),
        color_format=k4a.ImageFormat.COLOR_MJPG,  # as k4arecorder records it: the camera's own JPEG, no host decode
        depth_mode=getattr(k4a.DepthMode, settings["depth_mode"]),
        camera_fps=getattr(k4a.FPS, f"FPS_{settings['fps']}"),
        synchronized_images_only=color_on and depth_on,  # the SDK refuses it with one camera off
    )
    device = k4a.PyK4A(config=config, device_id=settings["device_index"], thread_safe=False)
    try:
        device.start()
    except k4a.K4AException as exc:
        reason = str(exc) or "no such device, or another program is using it"
        return {"error": f"cannot be started ({reason})"}
    status: dict[str, Any] = {
        "device": {"serial": str(device.serial), "index": settings["device_index"]},
        "frames": [],
        "timeouts": 0,
    }
    record = k4a.PyK4ARecord(path=settings["mkv"], config=config, device=device, thread_safe=False)
    try:
        record.create()
        in_a_row = 0
        started = time.monotonic()
        while time.monotonic() - started < settings["duration"]:
            try:
                capture = device.get_capture(timeout=TIMEOUT_MS)
            except k4a.K4ATimeoutException:
                status["timeouts"] += 1
                in_a_row += 1
                if in_a_row >= MAX_TIMEOUTS:
                    return {"error": f"no capture for {MAX_TIMEOUTS * TIMEOUT_MS / 1000:g} s: the camera stopped"}
                continue
            arrived = time.monotonic()
            in_a_row = 0
            record.write_capture(capture)
            status["frames"].append([_stamps(capture, kind) for kind in KINDS] + [arrived])
        record.flush()
    except k4a.K4AException as exc:
        return {"error": f"stopped after {len(status['frames'])} captures: {str(exc) or 'the device was lost'}"}
    finally:
        if record.created:
            record.close()  # the SDK writes the file's index and start offset here
        device.stop()
    return status


def main(argv: list[str]) -> None:
    session_main(argv, run, hard_exit=False)


if __name__ == "__main__":
    main(sys.argv[1:])
