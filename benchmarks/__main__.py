"""Run every benchmark module (``bench_*.py``) in this folder, or those named on the command line,
then print the headline figures of all of them as one table (:mod:`.summary`)."""

from __future__ import annotations

import importlib
import platform
import sys
from pathlib import Path

import numpy as np

EXTRAS = {"torch": "train", "onnxruntime": "export", "imageio_ffmpeg": "video", "librosa": "music", "dask": "dask"}
"""Optional packages a benchmark may need, and the extra that installs each."""


def machine() -> str:
    import os

    return (
        f"{platform.python_implementation()} {platform.python_version()}, numpy {np.__version__}, "
        f"{platform.machine()}, {os.cpu_count()} cores, {platform.platform(terse=True)}"
    )


def main(argv: list[str]) -> None:
    from .summary import table

    here = Path(__file__).parent
    names = argv or sorted(p.stem for p in here.glob("bench_*.py"))
    print(f"machine: {machine()}")
    for name in names:
        print(f"\n== {name} ==")
        try:
            module = importlib.import_module(f"benchmarks.{name}")
        except ModuleNotFoundError as exc:
            top = (exc.name or "").split(".")[0]
            if top not in EXTRAS:
                raise
            print(f"  skipped: needs pip install 'kinectdata[{EXTRAS[top]}]' ({top} is not installed)")
            continue
        module.main()
    print(f"\n== summary ==\nmachine: {machine()}\n")
    print(table())


if __name__ == "__main__":
    main(sys.argv[1:])
