"""Decoding speed of ``.oni`` depth recordings, against OpenNI's own player.

A 640x480 depth recording in OpenNI's default codec (16zT), 150 frames (5 s at 30 fps) of a
Kinect-like scene: a back wall, the floor, a person moving, 1 % holes and the sensor's blind
band, depth quantised like the Kinect's 11-bit disparity with disparity noise (so it compresses
about as real Kinect depth does, to roughly a fifth). When OpenNI 1.x is installed the recording
is written by OpenNI's recorder and also decoded by OpenNI's player (fastest playback, one
thread); otherwise kinectdata's reference writer makes it and only kinectdata is timed.

Printed: frames/s of kinectdata (open + decode every frame, one core, best of 3), of OpenNI,
their ratio (target: at least 200 frames/s), the same for 16zP (no value table) and for a
640x480 RGB stream in Im8z, and the time to open the file.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from kinectdata.oni import OniFile

from .summary import record

sys.path.append(str(Path(__file__).resolve().parent.parent))  # reference/: independent implementations
from reference import openni as openni_ref  # noqa: E402
from reference.oni_python import StreamSpec, write_oni  # noqa: E402

FRAMES, WIDTH, HEIGHT = 150, 640, 480
BASE = Path(__file__).resolve().parent.parent / "tests/data/oni/openni2_dummy_depth_color.oni"  # OpenNI's mocks copy it


def depth_frame(k: int, seed: int = 0) -> np.ndarray:
    """uint16 [480, 640] depth in mm of a Kinect-like scene at frame k."""
    rng = np.random.default_rng(seed + k)
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    z = 3500.0 + 0.6 * (x - WIDTH / 2)
    floor = y > HEIGHT * 0.6
    z[floor] = 1200 + (HEIGHT - y[floor]) * 12
    cx, cy = WIDTH / 2 + 120 * np.sin(k / 15), HEIGHT * 0.45
    person = (((x - cx) / 70) ** 2 + ((y - cy) / 160) ** 2 < 1) | (
        ((x - cx) / 28) ** 2 + ((y - cy + 190) / 32) ** 2 < 1
    )
    person |= (np.abs(y - (cy - 60 + 40 * np.sin(k / 5))) < 12) & (np.abs(x - cx) < 160)
    z[person] = 2200 + 40 * np.sin(x[person] / 20)
    disparity = np.round((3.3309495161 - 1000.0 / z) / 0.0030711016 + rng.normal(0, 0.35, z.shape))
    depth = 1000.0 / (-0.0030711016 * disparity + 3.3309495161)
    depth[rng.random(z.shape) < 0.01] = 0
    depth[:, :8] = 0
    return np.round(depth).astype(np.uint16)


def image_frame(k: int) -> np.ndarray:
    """uint8 [480, 640, 3] a smooth moving colour image (what Im8z is made for)."""
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    return np.stack(
        [128 + 100 * np.sin((x + 4 * k) / 50), 128 + 100 * np.cos(y / 40), 128 + 60 * np.sin((x + y) / 70 + k / 10)], -1
    ).astype(np.uint8)


def time_kinectdata(path: Path, kind: str) -> tuple[float, float]:
    """(frames per second decoding every frame, seconds to open), best of 3."""
    best, opened = 0.0, float("inf")
    for _ in range(3):
        start = time.perf_counter()
        with warnings.catch_warnings(), OniFile(path) as oni:
            warnings.simplefilter("ignore")
            opened = min(opened, time.perf_counter() - start)
            s = oni.stream(kind)
            for _frame in oni.frames(s):
                pass
            best = max(best, s.n_frames / (time.perf_counter() - start))
    return best, opened


def main() -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    depth = np.stack([depth_frame(k) for k in range(FRAMES)])
    image = np.stack([image_frame(k) for k in range(30)])
    missing = openni_ref.openni1_missing()
    with tempfile.TemporaryDirectory() as tmp:
        files = {}
        for codec in ("16zT", "16zP"):
            path = Path(tmp) / f"depth-{codec}.oni"
            if missing is None:
                openni_ref.record(BASE, path, [("depth", depth, codec)])
            else:
                write_oni(path, [StreamSpec("Depth", "depth", codec, depth)])
            files[codec] = path
        im8z = Path(tmp) / "image-Im8z.oni"
        if missing is None:
            openni_ref.record(BASE, im8z, [("image", image, "Im8z")])
        else:
            write_oni(im8z, [StreamSpec("Image", "image", "Im8z", image)])
        print(
            f"{WIDTH}x{HEIGHT}, {FRAMES} depth frames; recordings written by "
            + ("OpenNI 1.x's recorder" if missing is None else f"kinectdata's reference writer ({missing})")
        )
        raw = depth[0].nbytes
        for label, path, kind in (
            ("16zT depth", files["16zT"], "depth"),
            ("16zP depth", files["16zP"], "depth"),
            ("Im8z RGB", im8z, "image"),
        ):
            with OniFile(path) as oni:
                s = oni.stream(kind)
                size = oni.read_frame(s, 0).data.nbytes
                compressed = (path.stat().st_size - 2000) / s.n_frames  # about 2 kB of header and tables
                node = s.name
            fps, opened = time_kinectdata(path, kind)
            share = compressed / (raw if kind == "depth" else size)
            line = f"  {label:<11} {share:5.1%} of raw; kinectdata {fps:7.1f} frames/s"
            if missing is None:
                frames, seconds = openni_ref.bench(path, node, 3)
                theirs = frames / seconds
                line += f", OpenNI {theirs:7.1f} frames/s, ratio {fps / theirs:.2f}"
            line += f"; open {opened * 1000:.1f} ms"
            ratio = f", {fps / theirs:.2f}x OpenNI" if missing is None else ""
            record(".oni", f"decode {label} {WIDTH}x{HEIGHT}, one core", f"{fps:.1f} frames/s{ratio}")
            if label == "16zT depth":
                line += "  (target: >= 200 frames/s)"
            print(line)


if __name__ == "__main__":
    main()
