"""The real OpenNI, as a reference for kinectdata's ``.oni`` reader.

- OpenNI 1.x (Debian ``libopenni0`` + ``libopenni-dev``): ``onitool.cpp``, compiled on first use,
  plays recordings back with OpenNI's player (:func:`dump`, :func:`bench`) and records new ones
  from mock nodes fed with any frames (:func:`record`);
- OpenNI2 (Debian ``libopenni2-0`` + the PyPI ``openni`` bindings): :func:`record_dummy` records
  from OpenNI2's ``Dummy`` device in a child process (OpenNI2 may crash while unloading, after
  the file is complete).

Each ``*_missing()`` returns why that part cannot run here, or None.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
SOURCE = HERE / "onitool.cpp"
INCLUDE = Path("/usr/include/ni")
CACHE = Path(tempfile.gettempdir()) / "kinectdata-reference"


def openni1_missing() -> str | None:
    """Why OpenNI 1.x cannot be used here (None: it can)."""
    if shutil.which("g++") is None:
        return "no C++ compiler (g++) to build the OpenNI 1.x reference tool"
    if not (INCLUDE / "XnCppWrapper.h").is_file():
        return "OpenNI 1.x headers missing (apt-get install libopenni-dev)"
    modules = Path("/var/lib/ni/modules.xml")
    if not modules.is_file() or "nimRecorder" not in modules.read_text():
        return "OpenNI 1.x modules not registered (niReg -r /usr/lib/libnimRecorder.so, ...)"
    return None


def tool() -> Path:
    """The compiled onitool (built once per source version)."""
    digest = hashlib.sha256(SOURCE.read_bytes()).hexdigest()[:12]
    exe = CACHE / f"onitool-{digest}"
    if not exe.is_file():
        CACHE.mkdir(parents=True, exist_ok=True)
        tmp = exe.with_suffix(f".{os.getpid()}.tmp")
        subprocess.run(
            ["g++", "-O2", "-std=c++14", str(SOURCE), f"-I{INCLUDE}", "-lOpenNI", "-o", str(tmp)],
            check=True,
            capture_output=True,
            text=True,
        )
        os.replace(tmp, exe)
    return exe


def dump(path: str | os.PathLike) -> dict[str, dict[str, np.ndarray]]:
    """What OpenNI 1.x's player decodes from a recording, per node name: ``frames`` [N, H, W]
    uint16 (depth, IR) or [N, H, W, 3] uint8 (image), ``frame_id`` [N], ``timestamp_us`` [N]."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([str(tool()), "dump", str(path), tmp], check=True, capture_output=True, text=True)
        for txt in sorted(Path(tmp).glob("*.txt")):
            rows = np.loadtxt(txt, dtype=np.int64, ndmin=2)
            raw = np.fromfile(txt.with_suffix(".raw"), np.uint8)
            if rows.size == 0:
                continue
            size, width, height = int(rows[0, 2]), int(rows[0, 3]), int(rows[0, 4])
            per_pixel = size // (width * height)
            frames = raw.reshape(len(rows), height, width, per_pixel)
            if per_pixel == 2:
                frames = frames.view("<u2")[..., 0]
            out[txt.stem] = {"frames": frames, "frame_id": rows[:, 0], "timestamp_us": rows[:, 1].astype(np.uint64)}
    return out


def bench(path: str | os.PathLike, node: str, repeats: int = 1) -> tuple[int, float]:
    """(frames, seconds) OpenNI 1.x's player takes to decode a node's frames ``repeats`` times."""
    done = subprocess.run(
        [str(tool()), "bench", str(path), node, str(repeats)], check=True, capture_output=True, text=True
    )
    frames, seconds = done.stdout.split()
    return int(frames), float(seconds)


def record(
    base: str | os.PathLike, out: str | os.PathLike, feeds: list[tuple[str, np.ndarray, str]], fps: int = 30
) -> None:
    """Record ``out`` with OpenNI 1.x's recorder: per feed (kind ``depth``/``image``, frames
    [N, H, W] uint16 or [N, H, W, 3] uint8, codec FourCC), a mock node based on ``base``'s node
    of that kind (``base`` must hold a depth and an image stream)."""
    with tempfile.TemporaryDirectory() as tmp:
        args = []
        for i, (kind, frames, codec) in enumerate(feeds):
            raw = Path(tmp) / f"{i}.raw"
            np.ascontiguousarray(frames).tofile(raw)
            n, h, w = frames.shape[:3]
            args.append(f"{kind}:{raw}:{w}:{h}:{n}:{codec}:{fps}")
        done = subprocess.run([str(tool()), "record", str(base), str(out), *args], capture_output=True, text=True)
        if done.returncode:
            raise RuntimeError(f"onitool record failed: {done.stderr.strip()}")


def openni2_missing() -> str | None:
    """Why OpenNI2's Dummy device cannot be used here (None: it can)."""
    from kinectdata.core.errors import KinectDataError
    from kinectdata.oni.skeleton import openni2_dir

    try:
        folder = openni2_dir()
    except KinectDataError as exc:
        return str(exc)
    drivers = folder / "OpenNI2" / "Drivers"
    if not any((drivers / name).exists() for name in ("libDummyDevice.so", "libDummyDevice.so.0")):  # Debian: .so.0
        return "OpenNI2's Dummy device driver missing (libopenni2-0)"
    try:
        import openni  # noqa: F401
    except ImportError:
        return "the openni Python bindings are missing (pip install openni)"
    return None


def record_dummy(
    out: str | os.PathLike, seconds: float = 1.0, *, color: bool = False, lossy: bool = False, attempts: int = 3
) -> None:
    """Record OpenNI2's Dummy device (depth 320x240 16zT; with ``color`` also RGB, JPEG when
    ``lossy``) for about ``seconds`` into ``out``, in a child process. A child that hangs (OpenNI2's
    recorder can deadlock while it finishes the file, see record_dummy.py) is killed and the
    recording made again, up to ``attempts`` times."""
    from kinectdata.oni.skeleton import openni2_dir

    command = [sys.executable, str(HERE / "record_dummy.py"), str(openni2_dir()), str(out), str(seconds)]
    command += (["--color"] if color else []) + (["--lossy"] if lossy else [])
    for attempt in range(1, attempts + 1):
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=30 + 2 * seconds)
        except subprocess.TimeoutExpired:
            if attempt == attempts:
                raise RuntimeError(f"OpenNI2 recording hung {attempts} times (record_dummy.py)") from None
            continue
        if "recorded" not in done.stdout:
            raise RuntimeError(f"OpenNI2 recording failed (exit {done.returncode}): {done.stderr.strip()[-500:]}")
        return
