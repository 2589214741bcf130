"""Reading the depth track of an Azure Kinect ``.mkv`` recording, against FFmpeg's own decode.

A k4arecorder-layout recording (reference/k4a_writer.py) of 300 depth frames in the NFOV
unbinned mode (640 x 576, 30 fps: 10 s) with its IR track and the IMU at 1.6 kHz. Timed, best of
3, in the same run: kinectdata opening the file and decoding every depth frame to uint16 millimetres
(``K4aRecording.frame``), and FFmpeg (imageio-ffmpeg's binary, one thread) decoding the same track
to 16-bit little-endian pixels written to a pipe that is read and dropped (its process start
included, as kinectdata's opening is). Printed: both rates in frames/s and their ratio (goal: at
least 1.0 x FFmpeg).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from kinectdata.mkv import K4aRecording

from .summary import record

sys.path.append(str(Path(__file__).resolve().parent.parent))  # reference/: independent implementations
from reference.k4a_writer import depth_track, imu_samples, write_k4a  # noqa: E402

FRAMES, WIDTH, HEIGHT = 300, 640, 576


def depth_frames(seed: int = 0) -> np.ndarray:
    """uint16 [FRAMES, 576, 640] depth in mm: a wall, the floor, a person swaying, 1 % holes."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    frames = np.empty((FRAMES, HEIGHT, WIDTH), np.uint16)
    for k in range(FRAMES):
        z = 3500.0 + 0.5 * (x - WIDTH / 2)
        floor = y > HEIGHT * 0.65
        z[floor] = 1200 + (HEIGHT - y[floor]) * 10
        cx = WIDTH / 2 + 120 * np.sin(k / 15)
        person = ((x - cx) / 70) ** 2 + ((y - HEIGHT * 0.45) / 170) ** 2 < 1
        z[person] = 2200 + 40 * np.sin(x[person] / 20)
        z += rng.normal(0, 4, z.shape)
        z[rng.random(z.shape) < 0.01] = 0
        frames[k] = np.round(z).astype(np.uint16)
    return frames


def time_kinectdata(path: Path) -> float:
    best = 0.0
    for _ in range(3):
        start = time.perf_counter()
        with warnings.catch_warnings(), K4aRecording(path) as take:
            warnings.simplefilter("ignore")
            depth = take.track("DEPTH")
            for i in range(depth.frame_count):
                take.frame(depth, i)
        best = max(best, depth.frame_count / (time.perf_counter() - start))
    return best


def time_ffmpeg(path: Path) -> float:
    import imageio_ffmpeg

    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-threads", "1", "-i", str(path), "-map", "0:v:0",
               "-f", "rawvideo", "-pix_fmt", "gray16le", "-"]  # fmt: skip
    best, frame_bytes = 0.0, WIDTH * HEIGHT * 2
    for _ in range(3):
        start = time.perf_counter()
        with subprocess.Popen(command, stdout=subprocess.PIPE) as ffmpeg:
            frames = 0
            while chunk := ffmpeg.stdout.read(frame_bytes):
                frames += len(chunk) == frame_bytes
        if ffmpeg.returncode or frames != FRAMES:
            raise RuntimeError(f"FFmpeg decoded {frames} frames (exit {ffmpeg.returncode})")
        best = max(best, frames / (time.perf_counter() - start))
    return best


def main() -> None:
    depth = depth_frames()
    times = [5_000_000_000 + i * 33_333_333 for i in range(FRAMES)]
    imu_times = np.arange(5_000_000_000 - 2_000_000, times[-1], 625_000)
    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "take.mkv"
        write_k4a(
            path,
            [depth_track("DEPTH", depth, times, "NFOV_UNBINNED"), depth_track("IR", depth // 3, times, "ACTIVE")],
            imu_samples(imu_times, rng.normal(0, 1, (len(imu_times), 3)), rng.normal(0, 1, (len(imu_times), 3))),
        )
        ours, theirs = time_kinectdata(path), time_ffmpeg(path)
    ratio = ours / theirs
    print(
        f"  depth track, {WIDTH}x{HEIGHT}, {FRAMES} frames with IR and IMU beside it: kinectdata {ours:,.0f} frames/s, "
        f"FFmpeg {theirs:,.0f} frames/s (one thread, process start included): {ratio:.2f} x FFmpeg "
        f"(goal at least 1.0 x: {'met' if ratio >= 1.0 else 'not met'})"
    )
    record(".mkv", f"decode depth {WIDTH}x{HEIGHT}, one core, vs FFmpeg", f"{ratio:.2f} x")


if __name__ == "__main__":
    main()
