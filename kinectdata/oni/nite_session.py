"""NiTE2's user tracker over an ``.oni``'s playback, run in its own process by
:func:`kinectdata.oni.skeleton.track_skeleton` (OpenNI2's playback can stall; the parent stops
this process then). Writes one JSON line per tracked frame, [timestamp us, frame index,
{user id: [15, 9] joint rows}], flushed as it goes.

usage: python -m kinectdata.oni.nite_session SETTINGS_JSON OUT.jsonl
"""

from __future__ import annotations

import json
import sys


def main(argv: list[str]) -> None:
    from openni import nite2, openni2

    from kinectdata.oni.skeleton import tracked_users

    settings, out = json.loads(argv[0]), argv[1]
    openni2.initialize(settings["openni2_dir"])
    nite2.initialize(settings["nite_dir"])
    device = openni2.Device.open_file(settings["oni"].encode())
    device.playback.repeat = False
    device.playback.speed = -1.0  # as fast as the tracker can go
    tracker = nite2.UserTracker(device)
    last = None
    with open(out, "w") as f:
        for _ in range(settings["frames"]):
            frame = tracker.read_frame()
            if last is not None and int(frame.frameIndex) <= last:  # playback came round again
                break
            last = int(frame.frameIndex)
            users = {u: rows.tolist() for u, rows in tracked_users(tracker, frame, nite2).items()}
            f.write(json.dumps([int(frame.timestamp), last, users]) + "\n")
            f.flush()


if __name__ == "__main__":
    main(sys.argv[1:])
