"""The whole dataset build on one core, against decoding and resampling its audio alone; peak memory.

Sessions of 2, 10 and 60 minutes are synthesised (44.1 kHz stereo FLAC + a skeleton CSV, canonical
dialect with orientations: the shape of a real Kinect v2 take) and each is built into a dataset
(``--jobs 1``, yalta2016 features, yalta65 targets) in a child process pinned to one CPU core, with
the offset given (and, for 10 minutes, ``--offset auto``: one more pass over the audio). Another
child, pinned likewise, only decodes and resamples the same audio to 16 kHz mono
(:class:`~kinectdata.align.audio.AudioReader`), the floor no build can go under.

Printed per session: the build's seconds and x real time, the decode-and-resample seconds, their
ratio against issue 16's goal (a build within 1.5x of its audio's decoding and resampling), the
build's peak resident memory (VmHWM) and its growth over the imported interpreter, then the growth
per minute of recording between 10 and 60 minutes against the goal of memory flat in length.
Then where the time of the 10-minute build goes, by stage.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import soundfile

from .summary import record

DURATIONS_S = (120.0, 600.0, 3600.0)  # the hour repeats the 10-minute session six times
SYNTH_LIMIT_S = 600.0
AUTO_OFFSET_AT_S = 600.0
BUILD_GOAL = 1.5  # issue 16: a build within 1.5x of decoding and resampling its audio
FLAT_MB_PER_MIN = 0.5  # memory counts as flat in length below this growth per minute of recording

_PRELUDE = """
import os, sys, json, time
os.sched_setaffinity(0, {0})
def vm(field):
    return next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith(field)) / 1024
"""

_DECODE = (
    _PRELUDE
    + """
from kinectdata.align.audio import AudioReader
start = time.perf_counter()
reader = AudioReader(sys.argv[1], 16000)
samples = sum(block.size for block in reader.blocks())
print(json.dumps({"seconds": time.perf_counter() - start, "samples": samples}))
"""
)

_BUILD = (
    _PRELUDE
    + """
import functools
import kinectdata.dataset.prepare as prepare
import kinectdata.dataset.build as build
import kinectdata.features.streaming as streaming
from kinectdata.align.audio import AudioReader
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features.stft import PRESETS
from kinectdata.targets.specs import load_target_spec

STAGES = {}
def timed(owner, name, stage):
    original = getattr(owner, name)
    @functools.wraps(original)
    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            STAGES[stage] = STAGES.get(stage, 0.0) + time.perf_counter() - start
    setattr(owner, name, wrapper)

timed(prepare.RecordingEntry, "read_motion", "read the skeleton CSV")
for name in ("resolve_offset", "plan_timeline", "resample_onto", "summarize"):
    timed(prepare, name, "align the motion onto 30 fps")
for name in ("extract_targets", "orientation_stats", "bone_offsets"):
    timed(prepare, name, "targets and their statistics")
timed(prepare.NormStats, "from_arrays", "targets and their statistics")
timed(streaming, "compute_features", "features")
timed(build, "_write_shards", "normalise and write the shards")
blocks = AudioReader.blocks
def timed_blocks(self):
    stream = blocks(self)
    while True:
        start = time.perf_counter()
        try:
            block = next(stream)
        except StopIteration:
            return
        finally:
            stage = "decode + resample the audio"
            STAGES[stage] = STAGES.get(stage, 0.0) + time.perf_counter() - start
        yield block
AudioReader.blocks = timed_blocks

cfg = BuildConfig(features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("yalta65").to_dict(),
                  split_ratios=(1, 0, 0))
base = vm("VmRSS:")
start = time.perf_counter()
build.build_dataset(sys.argv[1], sys.argv[2], cfg, jobs=1)
seconds = time.perf_counter() - start
# VmHWM: this process's own peak (ru_maxrss would include the parent's, inherited across fork/exec)
print(json.dumps({"seconds": seconds, "peak_mb": vm("VmHWM:"), "base_mb": base, "stages": STAGES}))
"""
)


def _child(code: str, *args: Path) -> dict:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    result = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(result.stdout)


def _synth(folder: Path, name: str, duration: float) -> dict:
    command = [sys.executable, "-m", "kinectdata", "synth", str(folder), "--seed", "3", "--duration", str(duration)]
    command += ["--name", name, "--audio-format", "flac", "--dialect", "canonical"]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return json.loads((folder / f"{name}.truth.json").read_text())


def _tile(folder: Path, piece: str, name: str, copies: int, seconds: float) -> None:
    """``name.flac`` / ``name.csv``: the session ``piece`` (``seconds`` of audio) played ``copies`` times
    in a row, its motion times shifted by ``seconds`` each time (the synthesiser stops at 10 minutes;
    the half-second without motion at each join is a tracking gap like any other)."""
    info = soundfile.info(str(folder / f"{piece}.flac"))
    with soundfile.SoundFile(
        str(folder / f"{name}.flac"), "w", samplerate=info.samplerate, channels=info.channels, subtype=info.subtype
    ) as out:
        for _ in range(copies):
            for block in soundfile.blocks(str(folder / f"{piece}.flac"), blocksize=1 << 18, dtype="int32"):
                out.write(block)
    lines = (folder / f"{piece}.csv").read_text().splitlines(keepends=True)
    first = next(i for i, line in enumerate(lines) if line.startswith("time,")) + 1
    with open(folder / f"{name}.csv", "w") as out:
        out.writelines(lines[:first])
        for k in range(copies):
            for line in lines[first:]:
                t, rest = line.split(",", 1)
                out.write(f"{float(t) + k * seconds:.6f},{rest}")


def main() -> None:
    print("  one core each; 44.1 kHz stereo FLAC + canonical CSV. 'decode' = decoding and resampling the audio")
    print(f"  alone; ratio = build / decode (goal <= {BUILD_GOAL:g}x); growth = peak minus the imported interpreter.")
    print(
        f"  {'recording':>9} {'offset':>6} {'build s':>8} {'x real':>7} {'decode s':>9} {'ratio':>6} "
        f"{'peak MB':>8} {'growth MB':>10}"
    )
    growth: dict[float, float] = {}
    stages: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for duration in DURATIONS_S:
            name = f"s{int(duration)}"
            if duration <= SYNTH_LIMIT_S:
                truth = _synth(tmp, name, duration)
            else:
                piece = f"s{int(SYNTH_LIMIT_S)}"
                _tile(tmp, piece, name, int(duration // SYNTH_LIMIT_S), SYNTH_LIMIT_S)
                truth = json.loads((tmp / f"{piece}.truth.json").read_text())
            audio = tmp / f"{name}.flac"
            decode = _child(_DECODE, audio)["seconds"]
            offsets = [truth["offset_s"]] + (["auto"] if duration == AUTO_OFFSET_AT_S else [])
            for offset in offsets:
                recordings = tmp / f"{name}.json"
                recordings.write_text(json.dumps([{"recording": f"{name}.csv", "audio": audio.name, "offset": offset}]))
                out = tmp / f"ds-{name}-{offset}"
                report = _child(_BUILD, recordings, out)
                build = report["seconds"]
                span = json.loads((out / "manifest.json").read_text())["totals"]["rows"] / 30.0
                label = "auto" if offset == "auto" else "given"
                ratio = build / decode
                extra = report["peak_mb"] - report["base_mb"]
                if label == "given":
                    growth[duration] = extra
                    if duration == AUTO_OFFSET_AT_S:
                        stages = report["stages"] | {"total": build}
                record(
                    "dataset",
                    f"build {duration / 60:.0f} min, offset {label}, one core",
                    f"{span / build:.0f}x real time, {ratio:.2f}x its audio decode, peak {report['peak_mb']:.0f} MB",
                )
                print(
                    f"  {duration / 60:5.0f} min {label:>6} {build:8.2f} {span / build:7.0f} {decode:9.2f} "
                    f"{ratio:5.2f}x {report['peak_mb']:8.0f} {extra:10.0f}  goal {BUILD_GOAL:g}x: "
                    f"{'met' if ratio <= BUILD_GOAL else 'not met'}"
                )
                for path in out.rglob("*"):  # the hour's dataset is large: free the space as soon as it is measured
                    if path.is_file():
                        path.unlink()
    short, long = DURATIONS_S[1], DURATIONS_S[2]
    slope = (growth[long] - growth[short]) / ((long - short) / 60)
    flat = "met" if slope < FLAT_MB_PER_MIN else "not met"
    print(
        f"  memory: {slope:.2f} MB more per minute of recording between {short / 60:.0f} and {long / 60:.0f} min "
        f"(goal: flat, under {FLAT_MB_PER_MIN:g} MB/min: {flat})"
    )
    record("dataset", "build memory growth per minute of recording", f"{slope:.2f} MB/min")
    total = stages.pop("total")
    print(f"  where the {AUTO_OFFSET_AT_S / 60:.0f}-minute build's {total:.2f} s go (offset given):")
    for stage, seconds in sorted(stages.items(), key=lambda kv: -kv[1]):
        print(f"    {stage:<34} {seconds:6.2f} s  {100 * seconds / total:4.0f} %")
    rest = total - sum(stages.values())
    print(f"    {'the rest (hashing, work files, manifest)':<34} {rest:6.2f} s  {100 * rest / total:4.0f} %")


if __name__ == "__main__":
    main()
