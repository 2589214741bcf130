"""The OpenNI2 side of a capture, run in its own process (``python -m kinectdata.capture.openni_session
SETTINGS.json``): OpenNI2 drivers may crash while the library unloads at process exit, after
the recording is complete, and that must not take the capture command down with it (nor keep
it waiting: the process exits without unloading once the take and its status are written).

It opens the device, records depth (and colour) to the ``.oni`` with OpenNI2's recorder, reads
every depth frame to note when it arrived on the monotonic clock, runs NiTE2's user tracker
when asked and available, and writes a status JSON: the frames it saw (device timestamps and
arrival times), the skeleton's tracked frames, and what went wrong. The parent
(:mod:`.openni`) turns that into the take's ``oni`` entry; :mod:`.child` runs it.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

from kinectdata.capture.child import session_main

# OpenNI2 2.2's recorder can deadlock when destroyed right after being stopped (2 of 40 dummy
# recordings on a loaded 2-core machine); a pause between the two avoided it in every later trial.
STOP_TO_DESTROY_S = 0.3
FINISH_TIMEOUT_S = 20.0  # a recorder still finishing after this has hung: the take is reported lost


def _finish_recording(recorder: Any) -> bool:
    """Stop and destroy OpenNI2's recorder, which writes the file's seek table and END record;
    False when that hangs (the process then exits without waiting for it)."""
    recorder.stop()
    time.sleep(STOP_TO_DESTROY_S)
    closing = threading.Thread(target=recorder.close, daemon=True)
    closing.start()
    closing.join(FINISH_TIMEOUT_S)
    return not closing.is_alive()


def run(settings: dict[str, Any]) -> dict[str, Any]:
    from openni import openni2

    from kinectdata.oni.skeleton import tracked_users

    status: dict[str, Any] = {"frames": [], "skeleton": None, "skeleton_problem": None}
    openni2.initialize(settings["openni2_dir"])
    uri = settings.get("device")
    device = openni2.Device(uri.encode() if uri else None)
    info = device.get_device_info()
    status["device"] = {
        "uri": info.uri.decode("latin-1"),
        "vendor": info.vendor.decode("latin-1"),
        "name": info.name.decode("latin-1"),
    }
    depth = device.create_depth_stream()
    streams = [depth]
    if settings.get("color"):
        streams.append(device.create_color_stream())
    recorder = openni2.Recorder(settings["oni"].encode())
    for i, stream in enumerate(streams):
        recorder.attach(stream, allow_lossy_compression=bool(settings.get("lossy")) and i > 0)
    tracker = nite2 = None
    if settings.get("nite_dir"):
        try:
            from openni import nite2 as _nite2

            _nite2.initialize(settings["nite_dir"])
            nite2, tracker = _nite2, _nite2.UserTracker(device)
        except Exception as exc:  # NiTE2's own errors (missing data files, licence...)
            status["skeleton_problem"] = f"NiTE2 could not start: {exc}"
    recorder.start()  # before the streams: the first frame read is then the first recorded
    for stream in streams:
        stream.start()
    tracked = []
    started = time.monotonic()
    while time.monotonic() - started < settings["duration"]:
        if tracker is not None:
            frame = tracker.read_frame()
            arrived = time.monotonic()
            stamp, index = int(frame.timestamp), int(frame.frameIndex)
            users = {u: rows.tolist() for u, rows in tracked_users(tracker, frame, nite2).items()}
            tracked.append([stamp, index, users])
        else:
            frame = depth.read_frame()
            arrived = time.monotonic()
            stamp, index = int(frame.timestamp), int(frame.frameIndex)
        status["frames"].append([stamp, index, arrived])
    if not _finish_recording(recorder):  # now, not when the library unloads
        return {"error": f"OpenNI2's recorder hung while finishing {settings['oni']} (no END record written)"}
    for stream in streams:
        stream.stop()
    if tracker is not None:
        status["skeleton"] = tracked
    return status


def main(argv: list[str]) -> None:
    # everything is written when run returns: exit without unloading OpenNI2, whose drivers can
    # crash or hang there (a hang would keep the capture command waiting, then lose a complete take)
    session_main(argv, run, hard_exit=True)


if __name__ == "__main__":
    main(sys.argv[1:])
