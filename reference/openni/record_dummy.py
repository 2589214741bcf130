"""Record OpenNI2's Dummy device to an .oni file (run as a child process: OpenNI2 may crash or hang
while unloading; the recorder is destroyed first, which completes the file (seek table, END
record), and the process then exits without unloading).

OpenNI2 2.2's recorder can deadlock when it is destroyed right after being stopped (measured here
on a loaded 2-core machine: 2 of 40 recordings hung in oniRecorderDestroy, with a file lacking its
END record); a pause of 0.3 s between the two avoided it in 180 of 180 (same load). The caller still retries on a hang.

usage: record_dummy.py OPENNI2_DIR OUT.oni SECONDS [--color] [--lossy]
"""

import os
import sys
import time

from openni import openni2

STOP_TO_DESTROY_S = 0.3  # lets the recorder's thread take the stop before the destroy (see above)


def main(argv: list[str]) -> None:
    folder, out, seconds = argv[0], argv[1], float(argv[2])
    color, lossy = "--color" in argv, "--lossy" in argv
    openni2.initialize(folder)
    device = openni2.Device(b"Dummy")
    streams = [device.create_depth_stream()] + ([device.create_color_stream()] if color else [])
    recorder = openni2.Recorder(out.encode())
    for i, stream in enumerate(streams):
        recorder.attach(stream, allow_lossy_compression=lossy and i > 0)
        stream.start()
    recorder.start()
    started = time.monotonic()
    while time.monotonic() - started < seconds:
        streams[0].read_frame()
    recorder.stop()
    time.sleep(STOP_TO_DESTROY_S)
    recorder.close()  # destroys the recorder, which writes the seek table and END record; not left to unloading
    for stream in streams:
        stream.stop()
    print("recorded", flush=True)
    os._exit(0)  # the file is complete: skip OpenNI2's unloading, which can hang on a loaded machine


if __name__ == "__main__":
    main(sys.argv[1:])
