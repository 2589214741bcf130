"""Every shell example in README.md and docs/*.md runs, as written, and succeeds.

Each document's examples run in order in a folder of their own, as a reader would paste them:
``kinectdata`` commands each in a process of their own forked by command_server.py (the console
script's ``main``, its imports made once), other programs from PATH. The files an example names but does not
make (``take.csv``, ``song.wav``, ``take.oni``...) are made first, by :data:`STAGE`, from the
bundled samples and generated data, so that each command runs as the document prints it.

Some commands run with a few options appended (:data:`SHRINK`; click takes the last value given),
so that training for 30 minutes takes seconds; the command as written must parse and run all the
same. Commands that cannot run here are listed by name in :data:`NOT_RUN`, with why. A block of
commands must be marked ``sh`` (or ``bash``, ``console``); an unmarked block holding a
``kinectdata`` command fails here, so a new example cannot escape this test.
"""

from __future__ import annotations

import atexit
import functools
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import command_server
import numpy as np
import pytest
import soundfile
from conftest import REPO
from corpus_copies import make_aistpp_copy, make_bvh_folder, make_finedance_copy, make_tang2018_copy

DOCUMENTS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
SHELL = {"sh", "bash", "shell", "console"}
PROGRAMS = ("kinectdata", "pip", "pytest", "python", "dask", "torchrun")

NOT_RUN = {
    "kinectdata live --run runs/dancer --osc": "listens to the microphone: this machine has no input device",
    "kinectdata capture --sensor k4a": "needs an Azure Kinect (pyk4a, the Azure Kinect SDK) and an audio input: "
    "tests/capture/test_k4a_capture.py runs the command with a stand-in for pyk4a",
    "pip install": "installs the package: .ci/run does it before the suite runs",
    "pytest": "the test suite itself",
    "kinectdata quickstart --corpus": "tests/apps/test_real_quickstart.py runs it on a copy made in the corpus's shape "
    "(one epoch of a small model; the corpus itself cannot be shipped)",
    "kinectdata quickstart": "tests/cli/test_cli.py runs it (one epoch of a small model)",
    "torchrun": "four processes on a two-core machine: tests/training/test_distributed.py runs train-baseline "
    "under torchrun with two, and checks their losses against one process's",
    "dask scheduler": "starts a server that runs until stopped (tests/training/test_distributed.py builds on a "
    "dask cluster)",
    "dask worker": "starts a server on each machine of a cluster, HOST being the scheduler's machine",
    "kinectdata build-dataset /shared/recordings.yaml": "needs the dask cluster above (HOST; /shared on every "
    "machine): tests/training/test_distributed.py runs --executor dask on a local cluster",
}
"""Commands not run here (by how they start), and why."""

TRAIN_SHRINK = ["--epochs", "1", "--sequence", "30", "--stride", "300", "--max-minutes", "1"]
SHRINK = {
    "kinectdata train-baseline": [*TRAIN_SHRINK, "--units", "16"],
    "kinectdata train-baseline --data ltd_dataset": [
        *TRAIN_SHRINK,
        "--channels",
        "64",
        "--decoder-channels",
        "64",
        "--context",
        "30",
    ],
    "kinectdata render": ["--fps", "5", "--size", "160x120"],
    "kinectdata render take_body.json --over": [],  # the take's 60 depth frames at their own rate and size
    "kinectdata render s1.h5 --view": [],  # played at its own pace: no frame rate or size to shrink
    "kinectdata synth ltd": ["--duration", "10"],
}
"""Options appended to commands that start so (the last value of an option wins), to keep the
suite short: one epoch of short sequences instead of a full training, 10 s songs instead of 30 s
for the OpenPose sessions the listen-to-dance examples train and evaluate on."""


@dataclass(frozen=True)
class Example:
    """One command of a document: its text (continuation lines joined) and 1-based line."""

    document: Path
    line: int
    text: str

    @property
    def argv(self) -> list[str]:
        return shlex.split(self.text, comments=True)

    def __str__(self) -> str:
        return f"{self.document.relative_to(REPO)}:{self.line}: {self.text}"


def shell_examples(document: Path) -> list[Example]:
    """The commands of a document's shell blocks, in order.

    Raises:
        AssertionError: an unmarked block holds a kinectdata command.
    """
    text = document.read_text(encoding="utf-8")
    examples = []
    for block in re.finditer(r"^```(\w*)\n(.*?)^```", text, re.S | re.M):
        first = text[: block.start(2)].count("\n") + 1
        lines = block.group(2).splitlines()
        if block.group(1) not in SHELL:
            commands = [s for s in lines if s.startswith("kinectdata ")]
            assert not commands or block.group(1) not in ("", "text"), (
                f"{document.name}:{first}: a block holding {commands[0]!r} is not marked sh"
            )
            continue
        pending, start = "", 0
        for i, line in enumerate(lines):
            if not pending:
                start = first + i
            pending += line.removeprefix("$ ")
            if pending.endswith("\\"):
                pending = pending[:-1] + " "
                continue
            if pending.strip() and not pending.lstrip().startswith("#"):
                examples.append(Example(document, start, pending.strip()))
            pending = ""
    return examples


def not_run(example: Example) -> str | None:
    return next((why for start, why in NOT_RUN.items() if example.text.startswith(start)), None)


# -- the files the examples name --------------------------------------------------------------------

SAMPLES = REPO / "sample_data"


def _kinectdata(*args, cwd: Path) -> None:
    done = run_program(["kinectdata", *map(str, args)], cwd)
    assert done.returncode == 0, f"staging: kinectdata {' '.join(map(str, args))}\n{done.stderr[-3000:]}"


def _synth_csv(name: str, dialect: str) -> Callable[[Path], None]:
    def make(work: Path) -> None:
        _kinectdata("synth", work / ".synth", "--seed", 5, "--duration", 12, "--dialect", dialect, cwd=work)
        shutil.move(work / ".synth" / "synth_005.csv", work / name)
        shutil.rmtree(work / ".synth")

    return make


def _named_wav(name: str, sample: str) -> Callable[[Path], None]:
    def make(work: Path) -> None:
        audio, rate = soundfile.read(SAMPLES / f"{sample}.flac")
        soundfile.write(work / name, audio, rate)

    return make


def _copy(source: Path, name: str) -> Callable[[Path], None]:
    def make(work: Path) -> None:
        (shutil.copytree if source.is_dir() else shutil.copy)(source, work / name)

    return make


def _ntu_take(work: Path) -> None:
    """A .skeleton file (NTU RGB+D layout) with the body id the README names and a second body."""
    from test_ntu import make_body, skeleton_text

    rng = np.random.default_rng(0)
    frames = [[("72057594037931101", make_body(rng)), ("72057594037931104", make_body(rng))] for _ in range(40)]
    (work / "take.skeleton").write_text(skeleton_text(frames), newline="")


def _oni_take(work: Path) -> None:
    """A 75-second 16zT depth recording as OpenNI's recorder lays it out (small frames)."""
    from reference.oni_python import StreamSpec, write_oni

    n, h, w = 75 * 30, 24, 32
    depth = (1500 + 10 * np.arange(n)[:, None, None] % 900 + np.zeros((n, h, w), int)).astype(np.uint16)
    write_oni(work / "take.oni", [StreamSpec("Depth", "depth", "16zT", depth)])


def _k4a_take(work: Path) -> None:
    """A 2-s Azure Kinect recording as k4arecorder lays it out: NFOV 2x2-binned depth, the IMU,
    and a calibration in the device's shape."""
    from reference.k4a_writer import depth_track, imu_samples, write_k4a

    n, h, w = 60, 288, 320
    depth = (1500 + 10 * np.arange(n)[:, None, None] % 900 + np.zeros((n, h, w), int)).astype(np.uint16)
    times = [9_000_000_000 + i * 33_333_333 for i in range(n)]
    imu_times = np.arange(times[0] - 1_000_000, times[-1], 625_000)
    motion = np.zeros((len(imu_times), 3))
    camera = {
        "Location": "CALIBRATION_CameraLocationD0",
        "Intrinsics": {"ModelType": "CALIBRATION_LensDistortionModelBrownConrady", "ModelParameterCount": 14,
                       "ModelParameters": [0.5, 0.5, 0.49, 0.49, 0.6, -0.06, 0, 0.9, 0.03, -0.01, 0, 0, 0, 0]},
        "MetricRadius": 1.74, "SensorWidth": 1024, "SensorHeight": 1024,
        "Rt": {"Rotation": [1, 0, 0, 0, 1, 0, 0, 0, 1], "Translation": [0, 0, 0]},
    }  # fmt: skip
    write_k4a(
        work / "take.mkv",
        [depth_track("DEPTH", depth, times, "NFOV_2X2BINNED")],
        imu_samples(imu_times, motion, motion),
        calibration={"CalibrationInformation": {"Cameras": [camera]}},
        global_tags={"K4A_DEVICE_SERIAL_NUMBER": "000123456712"},
    )


def _k4a_body(work: Path) -> None:
    """The body tracker's JSON of take.mkv: one body per depth frame, stamped with its device time."""
    from test_azure_json import make_body, make_doc, write

    from kinectdata.mkv import K4aRecording

    if not (work / "take.mkv").exists():
        _k4a_take(work)
    with K4aRecording(work / "take.mkv") as take:
        stamps = take.device_times_us(take.track("DEPTH"))
    rng = np.random.default_rng(0)
    write(work, make_doc([(int(t), [make_body(rng, 1)[0]]) for t in stamps]), "take_body.json")


def _synth_openpose(work: Path, dest: Path) -> None:
    """An OpenPose --write_json folder of a dancer and a passer-by (person "1"), at ``dest``."""
    _kinectdata("synth", work / ".synth", "--format", "openpose", "--duration", 10, "--seed", 2, cwd=work)
    shutil.move(work / ".synth" / "synth_002_openpose", dest)
    shutil.rmtree(work / ".synth")


def _openpose_take(work: Path) -> None:
    _synth_openpose(work, work / "video_openpose")


def _openpose_jsonl(work: Path) -> None:
    """What a cdhc run's generate writes: OpenPose JSON Lines (from a folder of its own: an earlier
    example's video_openpose/ stays as it is)."""
    from kinectdata.formats import read_motion
    from kinectdata.formats.openpose_writer import write_openpose_jsonl

    folder = work / ".jsonl_source"
    _synth_openpose(work, folder)
    write_openpose_jsonl(read_motion(folder, video_fps=30), work / "dance.jsonl")
    shutil.rmtree(folder)


def _openpose_videos(work: Path) -> None:
    _kinectdata("synth", work / "videos", "--format", "openpose", "--count", 3, "--duration", 10, cwd=work)


def _aligned_folder(work: Path) -> None:
    for name in ("synth_001", "synth_002", "synth_003"):
        _kinectdata("align", SAMPLES / f"{name}.csv", SAMPLES / f"{name}.flac", "-o", f"aligned/{name}.h5", cwd=work)


def _aligned_take(work: Path) -> None:
    _kinectdata("align", SAMPLES / "synth_001.csv", SAMPLES / "synth_001.flac", "-o", "take.h5", cwd=work)


def _recordings_manifest(work: Path) -> None:
    lines = ["recordings:"] + [
        f"  - {{recording: sample_data/{n}.csv, audio: sample_data/{n}.flac, split: {s}}}"
        for n, s in (("synth_001", "train"), ("synth_002", "val"), ("synth_003", "test"))
    ]
    (work / "recordings.yaml").write_text("\n".join(lines) + "\n", encoding="utf-8")


def _tang_manifest(work: Path) -> None:
    """A recordings manifest of a copy made in Dance with Melody's shape (the corpus itself has no licence)."""
    make_tang2018_copy(work)
    _kinectdata("prepare", "tang2018", "Music-to-Dance-Motion-Synthesis", "-o", "tang.yaml", cwd=work)


def _dataset(work: Path) -> None:
    _kinectdata("build-dataset", "sample_data", "-o", "dataset", "--split-ratios", "1,1,1", cwd=work)


def _document_dialect(work: Path) -> None:
    """docs/csv-schemas.md's own example dialect, as my_dialect.json, and a take.csv written in it."""
    from kinectdata.formats import read_motion
    from kinectdata.formats.csv_writer import write_csv

    text = (REPO / "docs" / "csv-schemas.md").read_text(encoding="utf-8")
    (work / "my_dialect.json").write_text(re.search(r"```json\n(.*?)```", text, re.S).group(1), encoding="utf-8")
    motion = read_motion(SAMPLES / "synth_002.csv")
    write_csv(motion, work / "take.csv", work / "my_dialect.json")


STAGE: dict[str, Callable[[Path], None]] = {
    "take.csv": _synth_csv("take.csv", "lsl_kinect"),  # README: --schema lsl_kinect
    "take.wav": _named_wav("take.wav", "synth_001"),
    "music.wav": _named_wav("music.wav", "synth_002"),
    "song.wav": _named_wav("song.wav", "synth_003"),
    "take.skeleton": _ntu_take,
    "take.oni": _oni_take,
    "take.mkv": _k4a_take,
    "take_body.json": _k4a_body,
    "video_openpose/": _openpose_take,
    "dance.jsonl": _openpose_jsonl,
    "videos/": _openpose_videos,
    "aligned/": _aligned_folder,
    "take.h5": _aligned_take,
    "generated.csv": _copy(SAMPLES / "synth_002.csv", "generated.csv"),
    "recordings.yaml": _recordings_manifest,
    "aist_plusplus_final/": lambda work: make_aistpp_copy(work),
    "FineDance/data/finedance/": lambda work: make_finedance_copy(work),
    "bvh_corpus/": lambda work: make_bvh_folder(work),
    "Music-to-Dance-Motion-Synthesis/": lambda work: make_tang2018_copy(work),
    "tang.yaml": _tang_manifest,
    "dataset": _dataset,
}
"""How to make each input an example names but no earlier example of its document makes."""

STAGE_FOR = {"csv-schemas.md": {"take.csv": _document_dialect, "my_dialect.json": _document_dialect}}
"""Inputs a document means differently (its own dialect)."""

OUTPUT_OPTIONS = {"-o", "--out"}


def stage_inputs(example: Example, work: Path) -> None:
    """Make the inputs ``example`` names that are not in ``work`` yet (outputs are left alone)."""
    makers = STAGE | STAGE_FOR.get(example.document.name, {})
    argv = example.argv
    for i, token in enumerate(argv):
        if i and argv[i - 1] in OUTPUT_OPTIONS:
            continue
        key = token if token in makers else token.rstrip("/") + "/" if token.rstrip("/") + "/" in makers else None
        if key and not (work / token).exists():
            makers[key](work)


# -- claims the documents make about an example's result --------------------------------------------


def _same_files(work: Path, example: Example) -> None:
    """README: ``kinectdata synth sample_data ...`` is "how sample_data/ was made": byte for byte."""
    for made in sorted((work / "sample_data").iterdir()):
        bundled = SAMPLES / made.name
        assert bundled.exists(), f"{example}: made {made.name}, which sample_data/ does not hold"
        if made.suffix == ".json":  # the truth file names the command that made it, with its folder
            continue
        assert made.read_bytes() == bundled.read_bytes(), f"{example}: {made.name} differs from sample_data/"


CLAIMS = {"kinectdata synth sample_data --seed 1 --count 3 --duration 22": _same_files}
"""Commands whose document says what they make, and the check of it."""


def quoted_output(example: Example) -> str | None:
    """The output an example's comment quotes, when the comment starts with one of the command's
    arguments and a colon (``kinectdata verify dataset    # dataset: intact, ...``)."""
    comment = example.text.partition(" #")[2].strip()
    first = comment.split(":")[0]
    return comment if ":" in comment and first in example.argv[1:] else None


# -- running --------------------------------------------------------------------------------------


def _program(name: str) -> list[str]:
    # the environment's own script first (the one this Python installed), then PATH: a version
    # manager's shim on PATH (pyenv's) finds the same script, 50 ms later per command
    found = shutil.which(name, path=str(Path(sys.executable).parent)) or shutil.which(name)
    if name == "kinectdata" and found is None:
        return [sys.executable, "-m", "kinectdata"]  # an editable install without scripts on PATH
    assert found, f"{name} is not on PATH"
    return [found]


COMMAND_ENV = {"MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}
"""What every example runs with: no display, one thread (two workers share the two cores)."""


@functools.cache
def _command_server() -> command_server.CommandServer | None:
    server = command_server.start(dict(os.environ, **COMMAND_ENV))
    if server is not None:
        atexit.register(server.close)
    return server


def run_program(argv: list[str], work: Path) -> subprocess.CompletedProcess:
    """``argv`` run in ``work`` as a shell would, kinectdata's commands by the command server
    (command_server.py: a process of their own, the imports already made)."""
    env = dict(os.environ, **COMMAND_ENV)
    server = _command_server() if argv[0] == "kinectdata" else None
    if server is not None:
        return server.run(argv[1:], work, env, timeout=900)
    return subprocess.run(
        [*_program(argv[0]), *argv[1:]], cwd=work, env=env, capture_output=True, text=True, timeout=900
    )


def run(example: Example, work: Path) -> subprocess.CompletedProcess:
    starts = [start for start in SHRINK if example.text.startswith(start)]
    return run_program(example.argv + (SHRINK[max(starts, key=len)] if starts else []), work)


def _examples_by_document() -> list:
    return [pytest.param(d, id=d.name) for d in DOCUMENTS if shell_examples(d)]


@pytest.mark.slow
@pytest.mark.parametrize("document", _examples_by_document())
def test_every_shell_example_runs_as_written(document, tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    shutil.copytree(SAMPLES, work / "sample_data")
    skipped = []
    for example in shell_examples(document):
        why = not_run(example)
        if why:
            skipped.append(f"{example}: {why}")
            continue
        began = time.perf_counter()
        stage_inputs(example, work)
        staged = time.perf_counter()
        done = run(example, work)
        print(f"{staged - began:6.1f} s staging, {time.perf_counter() - staged:6.1f} s running: {example}")
        assert done.returncode == 0, f"{example}\nexit {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
        assert "Traceback" not in done.stderr, f"{example}\n{done.stderr[-3000:]}"
        claim = CLAIMS.get(example.text.split("#")[0].strip())
        if claim:
            claim(work, example)
        printed = quoted_output(example)
        assert printed is None or printed in done.stdout, f"{example}\nprinted: {done.stdout[-2000:]}"
    for line in skipped:
        print("not run:", line)


def test_the_commands_not_run_are_still_in_the_documents():
    """Each entry of NOT_RUN, SHRINK, CLAIMS and STAGE_FOR names something a document still holds."""
    texts = [e.text for d in DOCUMENTS for e in shell_examples(d)]
    for start in [*NOT_RUN, *SHRINK]:
        assert any(t.startswith(start) for t in texts), f"no example starts with {start!r} any more"
    for claim in CLAIMS:
        assert any(t.split("#")[0].strip() == claim for t in texts), f"no example is {claim!r} any more"
    assert set(STAGE_FOR) <= {d.name for d in DOCUMENTS}


def test_examples_are_found():
    """The parser finds continued lines and comments as a shell reads them (known answers)."""
    recipe = next(e for e in shell_examples(REPO / "docs" / "training.md") if "runs/recipe" in e.text)
    examples = shell_examples(REPO / "README.md")
    assert "--clip-norm 1 --epochs 1000 --max-minutes 30" in recipe.text
    assert recipe.argv[-1] == "30" and "\\" not in recipe.text
    verify = next(e for e in examples if e.text.startswith("kinectdata verify"))
    assert verify.argv == ["kinectdata", "verify", "dataset"]
    assert quoted_output(verify) == "dataset: intact, 2 shards (4525 rows, 7 recordings) match manifest.json"
    assert quoted_output(recipe) is None
