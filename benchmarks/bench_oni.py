"""Decoding speed of ``.oni`` recordings, against OpenNI's own player.

A 640x480 depth recording in OpenNI's default codec (16zT), 150 frames (5 s at 30 fps) of a
Kinect-like scene: a back wall, the floor, a person moving, 1 % holes and the sensor's blind
band, depth quantised like the Kinect's 11-bit disparity with disparity noise (so it compresses
about as real Kinect depth does, to roughly a fifth). When OpenNI 1.x is installed the recording
is written by OpenNI's recorder and also decoded by OpenNI's player (fastest playback, one
thread); otherwise kinectdata's reference writer makes it and only kinectdata is timed.

Printed, for 16zT, 16zP (no value table) and a 640x480 RGB stream in Im8z: OpenNI's frames/s, and
kinectdata's (open + decode every frame, one core, best of 3) with each decoder path in the same
run, the compiled byte loops (numba, ``kinectdata[fast]``) and the numpy ones (``KINECTDATA_JIT=0``),
each as a ratio to OpenNI next to the goal (at least 1.0x OpenNI); for the compiled path also the
two parts of a frame's time, each timed alone: the reader's (record header, payload view) and the
decoder's. Then the compiled decoders' costs: the first decode of each codec in a new process with
an empty numba cache (compiling) and with the cache filled (loading), numba's import time, and the
size of numba and llvmlite installed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from kinectdata.oni import OniFile, codecs

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


def time_parts(path: Path, kind: str) -> tuple[float, float]:
    """Seconds per frame of the two parts of reading a frame, each alone, best of 3: the reader's
    (the frame's record header, then a view of its payload in the mapped file, as
    ``OniFile.read_frame`` takes it) and the decoder's (from payloads copied out beforehand)."""
    from kinectdata.oni import records

    with OniFile(path) as oni:
        s = oni.stream(kind)
        count = int(np.prod(s.frame_layout[0]))
        table = s.codec == "16zT"
        reader = decoder = float("inf")
        payloads = []
        for position in s.positions:
            rec = oni.layout.read(oni._data, int(position), oni.source)
            payloads.append(oni._data[rec.payload_position : rec.end])
        for _ in range(3):
            start = time.perf_counter()
            for position in s.positions:  # each payload dropped before the next, as in a reading loop
                rec = oni.layout.read(oni._data, int(position), oni.source)
                records.parse_new_data(rec, oni.source)
                payload = memoryview(oni._data)[rec.payload_position : rec.end]
                del payload
            reader = min(reader, (time.perf_counter() - start) / len(payloads))
            start = time.perf_counter()
            for payload in payloads:
                if s.codec == "Im8z":
                    codecs.decode_8z(payload, count)
                else:
                    codecs.decode_16z(payload, count, table=table)
            decoder = min(decoder, (time.perf_counter() - start) / len(payloads))
    return reader, decoder


def jit_setting(value: str | None) -> None:
    """Set (or, None, unset) ``KINECTDATA_JIT``: the decoders read it at every call."""
    if value is None:
        os.environ.pop("KINECTDATA_JIT", None)
    else:
        os.environ["KINECTDATA_JIT"] = value


FIRST_DECODES = """
import json, sys, time
start = time.perf_counter()
import numba
took = {"import numba": time.perf_counter() - start}
import numpy as np
from kinectdata.oni import codecs
assert codecs.jit_available()
frame = np.arange(640 * 480, dtype=np.uint16) % 1000
depth = frame.astype("<u2").tobytes()[:2] + bytes([0x66]) * (frame.size // 2)  # a valid 16z stream
table = (1000).to_bytes(2, "little") + np.arange(1000, dtype="<u2").tobytes()
for name, decode in (
    ("16zT", lambda: codecs.decode_16z(table + depth, frame.size, table=True)),
    ("16zP", lambda: codecs.decode_16z(depth, frame.size, table=False)),
    ("Im8z", lambda: codecs.decode_8z(bytes([7]) + bytes([0x66]) * (frame.size // 2), frame.size)),
):
    start = time.perf_counter()
    decode()
    took[name] = time.perf_counter() - start
print(json.dumps(took))
"""


def first_decodes() -> tuple[dict[str, float], dict[str, float]]:
    """Seconds of each codec's first decode in a new process: (with an empty numba cache, with
    the cache that run filled), and numba's import time, in a NUMBA_CACHE_DIR of their own."""
    runs = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        env.pop("KINECTDATA_JIT", None)
        for _ in range(2):
            done = subprocess.run(
                [sys.executable, "-c", FIRST_DECODES], env=env, capture_output=True, text=True, check=True
            )
            runs.append(json.loads(done.stdout))
    return runs[0], runs[1]


def installed_mb(package: str) -> float:
    """Disk use of an installed package's folder in MB, as ``du`` counts it (allocated blocks)."""
    import importlib.util

    folder = Path(importlib.util.find_spec(package).origin).parent
    blocks = sum(os.lstat(os.path.join(root, name)).st_blocks for root, _, names in os.walk(folder) for name in names)
    return blocks * 512 / 1e6


def verdict(ratio: float) -> str:
    return f"goal >= 1.0x OpenNI: {'met' if ratio >= 1.0 else 'not met'}"


def main() -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    depth = np.stack([depth_frame(k) for k in range(FRAMES)])
    image = np.stack([image_frame(k) for k in range(30)])
    missing = openni_ref.openni1_missing()
    jit_missing = codecs.jit_missing()
    saved = os.environ.get("KINECTDATA_JIT")
    paths = [("compiled (numba)", None), ("numpy", "0")] if jit_missing is None else [("numpy", "0")]
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
        if jit_missing is not None:
            print(f"  compiled decoders not timed: {jit_missing}")
        raw = depth[0].nbytes
        try:
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
                share = compressed / (raw if kind == "depth" else size)
                line = f"  {label:<11} {share:5.1%} of raw"
                theirs = None
                if missing is None:
                    frames, seconds = openni_ref.bench(path, node, 3)
                    theirs = frames / seconds
                    line += f"; OpenNI {theirs:7.1f} frames/s"
                print(line)
                for name, setting in paths:
                    jit_setting(setting)
                    fps, opened = time_kinectdata(path, kind)
                    line = f"    kinectdata, {name:<16} {fps:7.1f} frames/s"
                    figure = f"{fps:.1f} frames/s"
                    if theirs is not None:
                        line += f", {fps / theirs:5.2f}x OpenNI ({verdict(fps / theirs)})"
                        figure += f", {fps / theirs:.2f}x OpenNI"
                    line += f"; open {opened * 1000:.1f} ms"
                    if setting is None:
                        reader, decoder = time_parts(path, kind)
                        line += f"; alone: reader {reader * 1000:.2f} ms/frame, decoder {decoder * 1000:.2f} ms/frame"
                    print(line)
                    record(".oni", f"decode {label} {WIDTH}x{HEIGHT}, one core, {name}", figure)
        finally:
            jit_setting(saved)
    if jit_missing is None:
        cold, warm = first_decodes()
        codec_names = ("16zT", "16zP", "Im8z")
        print(
            "  compiled decoders, first decode in a new process (s): "
            + ", ".join(f"{c} {cold[c]:.2f}" for c in codec_names)
            + " compiling (empty numba cache); "
            + ", ".join(f"{c} {warm[c]:.3f}" for c in codec_names)
            + f" from the cache; import numba {warm['import numba']:.2f} s"
        )
        sizes = {p: installed_mb(p) for p in ("numba", "llvmlite")}
        print(
            f"  numba installed: numba {sizes['numba']:.0f} MB + llvmlite {sizes['llvmlite']:.0f} MB "
            f"= {sum(sizes.values()):.0f} MB"
        )
        record(
            ".oni",
            "numba: first decode of a codec, compiling / from cache",
            f"{max(cold[c] for c in codec_names):.2f} s / {max(warm[c] for c in codec_names):.3f} s",
        )
        record(".oni", "numba + llvmlite installed", f"{sum(sizes.values()):.0f} MB")


if __name__ == "__main__":
    main()
