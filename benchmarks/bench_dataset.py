"""The whole dataset build on one core: x real time and peak memory against recording length.

Sessions of 2, 5 and 10 minutes are synthesised (44.1 kHz stereo WAV + a skeleton CSV) and each
is built into a dataset (``--jobs 1``: audio decode + resample + align + features + targets +
shard writing) in a child process pinned to one CPU core, with the offset given and with
``--offset auto`` (one more streaming pass over the audio). The build's own wall time, the whole
process's, and its peak resident memory (VmHWM) are printed: memory should not grow with the length.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .summary import record

DURATIONS_S = (120.0, 300.0, 600.0)
_CHILD = """
import os, sys, json
os.sched_setaffinity(0, {0})
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features.stft import PRESETS
from kinectdata.targets.specs import load_target_spec
cfg = BuildConfig(features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("yalta65").to_dict(),
                  split_ratios=(1, 0, 0))
import time
start = time.perf_counter()
build_dataset(sys.argv[1], sys.argv[2], cfg, jobs=1)
seconds = time.perf_counter() - start
# VmHWM: this process's own peak (ru_maxrss would include the parent's, inherited across fork/exec)
peak_kb = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM:"))
print(json.dumps({"seconds": seconds, "peak_mb": peak_kb / 1024}))
"""


def _run_child(recordings: Path, out: Path) -> tuple[float, float, float]:
    """(seconds of the build, seconds of the whole process, peak resident MB) of a child build."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-c", _CHILD, str(recordings), str(out)], env=env, capture_output=True, text=True, check=True
    )
    elapsed = time.perf_counter() - start
    report = json.loads(result.stdout)
    return report["seconds"], elapsed, report["peak_mb"]


def main() -> None:
    print("  one core, --jobs 1; 44.1 kHz stereo WAV + canonical CSV. 'build' is build_dataset itself;")
    print("  'process' adds the interpreter start-up and imports of a command-line run (a constant).")
    print(
        f"  {'recording':>9} {'offset':>7} {'build s':>8} {'x real time':>12} {'process s':>10} {'x real time':>12}"
        f" {'peak MB':>8}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for duration in DURATIONS_S:
            name = f"s{int(duration)}"
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "kinectdata",
                    "synth",
                    str(tmp),
                    "--seed",
                    "3",
                    "--duration",
                    str(duration),
                    "--name",
                    name,
                    "--audio-format",
                    "wav",
                    "--dialect",
                    "canonical",
                ],
                check=True,
                stdout=subprocess.DEVNULL,
            )
            truth = json.loads((tmp / f"{name}.truth.json").read_text())
            for offset in (truth["offset_s"], "auto"):
                recordings = tmp / f"{name}.json"
                recordings.write_text(
                    json.dumps([{"recording": f"{name}.csv", "audio": f"{name}.wav", "offset": offset}])
                )
                out = tmp / f"ds-{name}-{offset}"
                build, process, peak = _run_child(recordings, out)
                span = json.loads((out / "manifest.json").read_text())["totals"]["rows"] / 30.0
                label = "auto" if offset == "auto" else "given"
                what = f"build {duration / 60:.0f} min, offset {label}, one core"
                record("dataset", what, f"{span / build:.0f}x real time, peak {peak:.0f} MB")
                print(
                    f"  {duration / 60:7.0f} min {label:>7} {build:8.2f} {span / build:12.0f} {process:10.2f}"
                    f" {span / process:12.0f} {peak:8.0f}"
                )


if __name__ == "__main__":
    main()
