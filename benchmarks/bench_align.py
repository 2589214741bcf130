"""Reading and aligning a 10-minute session: every step of ``kinectdata align``, timed.

Prints seconds, x real time and throughput for: CSV reading in the long (DumpKinectSkeleton,
450 000 rows) and wide (LSL-Kinect) layouts, audio loading (44.1 kHz stereo FLAC -> 16 kHz
mono), offset estimation (clap), resampling onto the 30 fps grid, writing the HDF5 file; and
the peak resident memory of those steps (the session is synthesised in a child process, so its
cost is not counted).
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from kinectdata.align.audio import load_audio
from kinectdata.align.offset import estimate_offset
from kinectdata.align.recipe import align
from kinectdata.formats import read_motion
from kinectdata.formats.csv_writer import write_csv

from .summary import record

DURATION_S = 600.0


def _timed(label: str, fn, seconds_of_media: float, frames: int | None = None):
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    extra = f", {frames / dt:,.0f} frames/s" if frames else ""
    print(f"  {label:<44} {dt:7.3f} s   {seconds_of_media / dt:8.0f}x real time{extra}")
    record("align", label, f"{seconds_of_media / dt:.0f}x real time")
    return out


def main() -> None:
    import scipy.signal  # noqa: F401  (offset estimation imports it lazily; keep that out of its timing)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        print(f"  making a {DURATION_S / 60:.0f}-minute synthetic session (child process)...")
        cmd = [
            sys.executable,
            "-m",
            "kinectdata",
            "synth",
            str(tmp),
            "--seed",
            "0",
            "--duration",
            str(DURATION_S),
            "--name",
            "long",
        ]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        skeleton, flac = tmp / "long.csv", tmp / "long.flac"
        truth = json.loads((tmp / "long.truth.json").read_text())
        rows = sum(1 for _ in open(skeleton)) - 1
        print(f"  {rows // 25} frames, {rows} rows in the long CSV ({skeleton.stat().st_size / 1e6:.0f} MB)")

        motion = _timed(
            "read long CSV (dumpkinectskeleton)", lambda: read_motion(skeleton), truth["motion_duration_s"], rows // 25
        )
        n, span = motion.n_frames, motion.duration
        wide = tmp / "wide.csv"
        write_csv(motion, wide, "lsl_kinect")
        _timed("read wide CSV (lsl_kinect)", lambda: read_motion(wide), span, n)
        audio = _timed("load audio (FLAC 44.1k stereo -> 16k mono)", lambda: load_audio(flac), DURATION_S)
        _timed("estimate offset (clap)", lambda: estimate_offset(motion, audio), span)
        aligned = _timed(
            "align (resample onto 30 fps, gaps)", lambda: align(motion, audio, offset=truth["offset_s"]), span, n
        )
        _timed("write aligned HDF5 (gzip)", lambda: aligned.save(tmp / "out.h5"), span)
        print(f"  aligned file: {(tmp / 'out.h5').stat().st_size / 1e6:.1f} MB")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"  peak resident memory of the steps above: {peak:.0f} MB")
    record("align", "peak resident memory, 10-minute session", f"{peak:.0f} MB")


if __name__ == "__main__":
    main()
