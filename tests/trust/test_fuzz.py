"""Fuzzing every reader: damaged or random files give a Motion or a kinectdata error naming the file.

Seeds are real files (``tests/data``, ``sample_data``) and files written here in every format. The
mutations are the damage that disks, transfers and careless tools do: a cut, flipped or zeroed
bytes, inserted bytes, a deleted, repeated or moved line, a number replaced by a huge one, NaN or
text, random bytes, an empty file, the text saved as UTF-16. A reader must return a consistent
Motion or raise :class:`~kinectdata.core.errors.KinectDataError` whose message names the file; any other
exception fails, and so does an answer slower than :data:`HANG_S` seconds or a jump of the peak
memory by more than :data:`MAX_GROWTH_MB`. Dataset shards (:func:`validate_shard`) and aligned
recordings (:meth:`AlignedRecording.load`) get the same treatment, with damage to their HDF5
metadata bytes and edits of their attributes and datasets. The last section pins down each bug
the fuzzing found, with the place the error must name. ``-m slow`` runs the long variants.
"""

from __future__ import annotations

import json
import pickle
import re
import resource
import shutil
import signal
import tempfile
import tracemalloc
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import timedelta
from functools import cache
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from conftest import DATA, REPO
from corpus_copies import finedance_motion, tang2018_dance
from helpers import random_motion
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_azure_json import make_body as azure_body
from test_azure_json import make_doc
from test_bvh import _random_bvh
from test_ntu import make_body as ntu_body
from test_ntu import skeleton_text
from test_openpose import frame_doc, random_person, write_folder

from kinectdata.align.aligned import AlignedRecording
from kinectdata.core.errors import FormatError, KinectDataError
from kinectdata.core.motion import Motion
from kinectdata.dataset import shards
from kinectdata.dataset.shards import json_attribute, read_index, validate_shard
from kinectdata.formats import read_motion
from kinectdata.formats.csv_schema import shipped_csv_schemas
from kinectdata.formats.csv_writer import write_csv
from kinectdata.oni import OniFile, OniWarning

HANG_S = 20.0
"""A reader that has not answered after this many seconds is stuck (files here are below 100 kB)."""
MAX_GROWTH_MB = 256
"""Largest rise of the process's peak memory while one small damaged file is read."""
PER_EXAMPLE = settings(
    deadline=timedelta(seconds=5), suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)


# -- reading under watch ------------------------------------------------------------------------------


class Hung(Exception):
    """A reader ran longer than :data:`HANG_S`."""


@contextmanager
def time_limit(seconds: float = HANG_S) -> Iterator[None]:
    """Raise :class:`Hung` in the block after ``seconds`` (SIGALRM: main thread, Unix)."""

    def hung(signum, frame):
        raise Hung(f"no answer after {seconds} s")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: kilobytes


def answer_or_clear_error(path: Path, read: Callable[[], Any]) -> Any:
    """``read()``'s result, or None when it raised a KinectDataError naming ``path``'s file."""
    peak = peak_rss_mb()
    try:
        with time_limit():
            return read()
    except KinectDataError as exc:
        message = str(exc)
        assert path.name in message, f"the error does not name the file: {message}"
        assert len(message) < 2000, f"an error message of {len(message)} characters: {message[:300]}..."
        return None
    finally:
        assert peak_rss_mb() - peak < MAX_GROWTH_MB, f"peak memory rose by {peak_rss_mb() - peak:.0f} MB"


def check_motion(motion: Motion) -> None:
    """What every Motion a reader returns promises (kinectdata/core/motion.py)."""
    assert isinstance(motion, Motion)
    assert motion.n_frames >= 1
    assert np.isfinite(motion.times).all() and motion.times[0] == 0.0
    assert np.isfinite(motion.positions[motion.position_mask]).all()
    assert ((motion.confidence >= 0) & (motion.confidence <= 1)).all()
    if motion.has_orientations:
        norms = np.linalg.norm(motion.orientations[motion.orientation_mask], axis=-1)
        np.testing.assert_allclose(norms, 1.0, atol=1e-6)


def read_both_ways(path: Path, fmt: str, options: dict[str, Any], damaged: Path | None = None) -> None:
    """Read with the format named, then with the format detected (sniffers see the damage too). An
    error must name ``damaged`` (the file read, unless the damage is in a file read beside it)."""
    for given_format in (fmt, None):
        opts = options if given_format else {k: v for k, v in options.items() if k != "schema"}
        read = lambda: read_motion(path, format=given_format, **opts)  # noqa: B023, E731
        motion = answer_or_clear_error(damaged or path, read)
        if motion is not None:
            check_motion(motion)


@pytest.fixture(scope="module")
def fuzz_folder(tmp_path_factory) -> Path:
    """Where the damaged files are written, one name per seed, overwritten example after example."""
    return tmp_path_factory.mktemp("fuzzed")


# -- seeds ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Seed:
    """A valid file to damage: its format, a file name that format claims, bytes and reader options."""

    format: str
    name: str
    data: bytes
    options: dict[str, Any] = field(default_factory=dict)
    beside: tuple[tuple[str, bytes], ...] = ()
    """Files written unharmed next to it (name, bytes): what its reader reads besides."""
    reads: str | None = None
    """The file the reader is given, when the seed is a file read beside it (a config.json)."""

    def place(self, folder: Path, data: bytes | None = None) -> tuple[Path, Path]:
        """Write the seed (or ``data`` in its place) and the files beside it into ``folder``:
        (the file written, the file to read)."""
        for name, companion in self.beside:
            (folder / name).write_bytes(companion)
        path = folder / self.name
        path.write_bytes(self.data if data is None else data)
        return path, folder / (self.reads or self.name)


def _head_lines(path: Path, n: int) -> bytes:
    return b"".join(path.read_bytes().splitlines(keepends=True)[:n])


def _csv_seed(dialect: str, tmp: Path) -> Seed:
    motion = random_motion(T=3, seed=len(dialect))
    path = tmp / f"{dialect}.csv"
    write_csv(motion, path, dialect)
    return Seed("csv", "take.csv", path.read_bytes(), {"schema": dialect})


def _ntu_seed() -> Seed:
    rng = np.random.default_rng(5)
    states = rng.choice([0, 1, 2], 25)
    frames = [[("72057594037931101", ntu_body(rng, states))], [], [("7", ntu_body(rng)), ("8", ntu_body(rng))]]
    return Seed("ntu", "S001C002P003R004A005.skeleton", skeleton_text(frames).encode())


def _azure_seed() -> Seed:
    rng = np.random.default_rng(6)
    t0 = 1_234_567
    frames = [(t0, [azure_body(rng, 1)[0]]), (t0 + 33_333, []), (t0 + 66_666, [azure_body(rng, 2)[0]])]
    return Seed("azure_json", "body_tracking.json", json.dumps(make_doc(frames), indent=1).encode())


def _openpose_seeds() -> list[Seed]:
    rng = np.random.default_rng(7)
    untracked = [frame_doc([random_person(rng, 18, missing=[3]), random_person(rng, 18)]) for _ in range(3)]
    with_ids = [dict(frame_doc([random_person(rng, 25)], ids=[4]), frame=k * 2) for k in range(3)]
    fps = {"video_fps": 30.0}
    return [
        Seed("openpose", "im1010_openpose.json", (DATA / "openpose" / "im1010_openpose.json").read_bytes(), fps),
        Seed("openpose", "people.json", json.dumps(untracked).encode(), fps),
        Seed("openpose", "frames.jsonl", "\n".join(json.dumps(d) for d in with_ids).encode(), fps),
    ]


@cache
def seeds() -> dict[str, Seed]:
    """Every seed by name (built once)."""
    found = {
        "kinect_v2_real": Seed(
            "csv", "Ges01_wavehand.csv", _head_lines(DATA / "kinect_v2_csv" / "Ges01_wavehand.csv", 6)
        ),
        "sample_data": Seed("csv", "synth_001.csv", _head_lines(REPO / "sample_data" / "synth_001.csv", 1 + 25 * 3)),
        "ntu": _ntu_seed(),
        "azure_json": _azure_seed(),
        "htr_real": Seed("htr", "two_segments.htr", (DATA / "htr" / "two_segments.htr").read_bytes()),
    }
    with tempfile.TemporaryDirectory() as tmp:
        found.update({f"csv_{d}": _csv_seed(d, Path(tmp)) for d in shipped_csv_schemas()})
    found.update({f"openpose_{i}": s for i, s in enumerate(_openpose_seeds())})
    found.update(_corpus_seeds())
    found.update(_tang2018_seeds())
    return found


def _tang2018_seeds() -> dict[str, Seed]:
    """A Dance with Melody skeletons.json (3 frames of a made-up body) with its config.json beside
    it, and the config.json damaged instead."""
    skeletons = json.dumps(tang2018_dance(3, seed=9)).encode()
    config = json.dumps({"start_position": 41, "end_position": 45}).encode()
    return {
        "tang2018": Seed("tang2018", "skeletons.json", skeletons, beside=(("config.json", config),)),
        "tang2018_config": Seed(
            "tang2018", "config.json", config, beside=(("skeletons.json", skeletons),), reads="skeletons.json"
        ),
    }


def _corpus_seeds() -> dict[str, Seed]:
    """A BVH file, AIST++ keypoints as .npz and as a pickle, a FineDance motion."""
    rng = np.random.default_rng(8)
    keypoints = {"keypoints3d": rng.normal(100, 30, (3, 17, 3)), "keypoints3d_optim": rng.normal(100, 30, (3, 17, 3))}
    schema = {"schema": "aistpp_keypoints3d"}
    with tempfile.TemporaryDirectory() as tmp:
        _random_bvh(Path(tmp) / "take.bvh", seed=8, frames=3)
        bvh = (Path(tmp) / "take.bvh").read_bytes()
        np.savez(Path(tmp) / "take.npz", **keypoints)
        npz = (Path(tmp) / "take.npz").read_bytes()
        np.save(Path(tmp) / "001.npy", finedance_motion(0.1, seed=8)[0])
        finedance = (Path(tmp) / "001.npy").read_bytes()
    return {
        "bvh": Seed("bvh", "take.bvh", bvh),
        "arrays_npz": Seed("arrays", "take.npz", npz, schema),
        "arrays_pkl": Seed("arrays", "take.pkl", pickle.dumps(keypoints, protocol=4), schema),
        "finedance": Seed("finedance", "001.npy", finedance, {"rest_joints": REST_JOINTS}),
    }


SEED_NAMES = [
    "kinect_v2_real",
    "sample_data",
    "csv_kinectreader",
    "csv_lsl_kinect",
    "csv_dumpkinectskeleton",
    "csv_canonical",
    "ntu",
    "azure_json",
    "htr_real",
    "openpose_0",
    "openpose_1",
    "openpose_2",
    "bvh",
    "arrays_npz",
    "arrays_pkl",
    "finedance",
    "tang2018",
    "tang2018_config",
]


NAMED_ONLY = {"finedance"}
"""Formats read only when named: a FineDance .npy is told apart from joint arrays by --format alone."""


def test_the_seeds_are_valid_files(tmp_path):
    """Unharmed, every seed reads as a Motion (else the fuzzing would only test error paths)."""
    assert sorted(seeds()) == sorted(SEED_NAMES)
    for seed in seeds().values():
        _, path = seed.place(tmp_path)
        check_motion(read_motion(path, format=seed.format, **seed.options))
        if seed.format == "csv":  # the dialect is detected too
            check_motion(read_motion(path, **{k: v for k, v in seed.options.items() if k != "schema"}))
        elif seed.format not in NAMED_ONLY:
            check_motion(read_motion(path, **seed.options))


# -- mutations --------------------------------------------------------------------------------------

_NUMBER = re.compile(rb"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")
ODD_NUMBERS = [
    b"1e308",
    b"-1e308",
    b"1" + b"0" * 400,  # beyond float64, and beyond Python's default int-to-str digit limit
    b"9223372036854775808",  # 2**63
    b"1000000000",
    b"-1",
    b"0",
    b"-0",
    b"1e-320",
    b"0.5",
    b"NaN",
    b"nan",
    b"-inf",
    b"Infinity",
    b"1.#QNAN",
    b"abc",
    b"",
    b"\xe9",
    b"0x10",
    b"1_000",
]
"""What a damaged or hand-edited number becomes."""


def _cut(draw, data: bytes) -> bytes:
    return data[: draw(st.integers(0, len(data)))]


def _flip(draw, data: bytes) -> bytes:
    out = bytearray(data)
    for at, xor in draw(st.lists(st.tuples(st.integers(0, 2**20), st.integers(1, 255)), min_size=1, max_size=8)):
        if out:
            out[at % len(out)] ^= xor
    return bytes(out)


def _zero(draw, data: bytes) -> bytes:
    start = draw(st.integers(0, len(data)))
    end = min(len(data), start + draw(st.integers(1, 64)))
    return data[:start] + bytes(end - start) + data[end:]


def _insert(draw, data: bytes) -> bytes:
    at = draw(st.integers(0, len(data)))
    return data[:at] + draw(st.binary(min_size=1, max_size=16)) + data[at:]


def _lines_edit(draw, data: bytes) -> bytes:
    lines = data.splitlines(keepends=True)
    if not lines:
        return data
    i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
    how = draw(st.sampled_from(["delete", "repeat", "move"]))
    if how == "delete":
        del lines[i]
    elif how == "repeat":
        lines.insert(j, lines[i])
    else:
        lines.insert(j, lines.pop(i))
    return b"".join(lines)


def _number(draw, data: bytes) -> bytes:
    spans = [m.span() for m in _NUMBER.finditer(data)]
    if not spans:
        return data
    a, b = spans[draw(st.integers(0, len(spans) - 1))]
    return data[:a] + draw(st.sampled_from(ODD_NUMBERS)) + data[b:]


def _utf16(draw, data: bytes) -> bytes:
    return data.decode("utf-8", errors="replace").encode("utf-16")


def _wipe(draw, data: bytes) -> bytes:
    return b""


def _random(draw, data: bytes) -> bytes:
    return draw(st.binary(max_size=2048))


EDITS = [_cut, _flip, _zero, _insert, _lines_edit, _lines_edit, _number, _number, _number, _utf16, _wipe, _random]
"""The mutations, line and number edits weighted up: they reach deepest into the readers."""


@st.composite
def damaged(draw, data: bytes) -> bytes:
    """``data`` after one to three random edits."""
    for edit in draw(st.lists(st.sampled_from(EDITS), min_size=1, max_size=3)):
        data = edit(draw, data)
    return data


# -- the readers ------------------------------------------------------------------------------------


def fuzz_reader(seed: Seed, folder: Path, data: bytes) -> None:
    damaged, path = seed.place(folder, data)
    read_both_ways(path, seed.format, seed.options, damaged)


@pytest.mark.parametrize("name", SEED_NAMES)
@settings(PER_EXAMPLE, max_examples=30)
@given(data=st.data())
def test_damaged_files_give_a_motion_or_a_clear_error(fuzz_folder, name, data):
    seed = seeds()[name]
    fuzz_reader(seed, fuzz_folder, data.draw(damaged(seed.data), label="file"))


@pytest.mark.slow
@pytest.mark.parametrize("name", SEED_NAMES)
@settings(PER_EXAMPLE, max_examples=400)
@given(data=st.data())
def test_damaged_files_give_a_motion_or_a_clear_error_at_length(fuzz_folder, name, data):
    seed = seeds()[name]
    fuzz_reader(seed, fuzz_folder, data.draw(damaged(seed.data), label="file"))


@pytest.fixture(scope="module")
def openpose_folder(tmp_path_factory) -> Path:
    """OpenPose --write_json output: three frames of two people (BODY_25), one file each."""
    rng = np.random.default_rng(8)
    docs = [frame_doc([random_person(rng, 25), random_person(rng, 25)], ids=[0, 1]) for _ in range(3)]
    return write_folder(tmp_path_factory.mktemp("openpose") / "run", docs, [0, 1, 2])


@settings(PER_EXAMPLE, max_examples=20)
@given(frame=st.integers(0, 2), data=st.data())
def test_a_damaged_file_in_an_openpose_folder_gives_a_clear_error(openpose_folder, fuzz_folder, frame, data):
    """The error names one of the folder's files (the damaged one, or the one it disagrees with)."""
    folder = fuzz_folder / "openpose_run"
    shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(openpose_folder, folder)
    target = sorted(folder.iterdir())[frame]
    target.write_bytes(data.draw(damaged(target.read_bytes()), label="file"))
    try:
        with time_limit():
            motion = read_motion(folder, video_fps=30.0)
    except KinectDataError as exc:
        assert any(f.name in str(exc) for f in folder.iterdir()), str(exc)
    else:
        check_motion(motion)


# -- any bytes, in any reader -----------------------------------------------------------------------


def _read_oni(path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OniWarning)
        with OniFile(path) as oni:
            for stream in oni.streams:
                for _ in oni.frames(stream):
                    pass


REST_JOINTS = DATA / "finedance" / "made_up_rest_joints.npy"
EVERY_READER = [
    ("csv", "take.csv", {}),
    ("bvh", "take.bvh", {}),
    ("arrays", "take.npz", {"schema": "aistpp_keypoints3d"}),
    ("arrays", "take.pkl", {"schema": "aistpp_keypoints3d"}),
    ("finedance", "take.npy", {"rest_joints": REST_JOINTS}),
    ("ntu", "take.skeleton", {}),
    ("azure_json", "take.json", {}),
    ("htr", "take.htr", {}),
    ("openpose", "take.jsonl", {"video_fps": 30.0}),
    ("tang2018", "skeletons.json", {}),
    ("oni", "take.oni", {}),
]


@pytest.mark.parametrize(("fmt", "name", "options"), EVERY_READER)
@settings(PER_EXAMPLE, max_examples=25)
@given(data=st.binary(max_size=4096) | st.sampled_from([b"", b"\xef\xbb\xbf", b"\r\n", b"\x00" * 64]))
def test_random_bytes_give_a_clear_error(fuzz_folder, fmt, name, options, data):
    path = fuzz_folder / name
    if fmt == "tang2018":  # its config.json beside it, unharmed
        seeds()["tang2018"].place(fuzz_folder)
    path.write_bytes(data)
    if fmt == "oni":
        answer_or_clear_error(path, lambda: _read_oni(path))
    else:
        read_both_ways(path, fmt, options)


@pytest.mark.parametrize("name", SEED_NAMES)
def test_empty_and_utf16_files(fuzz_folder, name):
    """An empty file is an error naming it; UTF-16 text is read or refused, never a crash."""
    seed = seeds()[name]
    _, path = seed.place(fuzz_folder, b"")
    with pytest.raises(KinectDataError, match=re.escape(seed.name)):
        read_motion(path, format=seed.format, **seed.options)
    try:
        text = seed.data.decode("utf-8")
    except UnicodeDecodeError:
        return  # a binary format (.npy, .npz, a pickle): no text to save as UTF-16
    damaged, path = seed.place(fuzz_folder, text.encode("utf-16"))
    read_both_ways(path, seed.format, seed.options, damaged)


# -- counts that claim a billion of something --------------------------------------------------------

HUGE_COUNTS = [
    ("ntu", lambda d: b"1000000000" + d[d.index(b"\r") :], "the frame count 1000000000 is more than"),
    ("htr_real", lambda d: re.sub(rb"NumFrames\s+\d+", b"NumFrames 1000000000", d), "NumFrames says 1000000000"),
    ("htr_real", lambda d: re.sub(rb"NumSegments\s+\d+", b"NumSegments 1000000000", d), "NumSegments says"),
    ("azure_json", lambda d: d.replace(b'"num_bodies": 1', b'"num_bodies": 1000000000', 1), "num_bodies 1000000000"),
    ("sample_data", lambda d: d.replace(b"\n0.000000,1,", b"\n0.000000,1000000000,", 1), "joint index 1e+09"),
    ("openpose_2", lambda d: d.replace(b'"frame": 4', b'"frame": 1000000000'), None),
    ("tang2018", lambda d: d.replace(b'"length": 3', b'"length": 1000000000'), "length says 1000000000 frames"),
    ("tang2018_config", lambda d: d.replace(b"45", b"1000000045"), None),
]


@pytest.mark.parametrize(("name", "edit", "refusal"), HUGE_COUNTS)
def test_a_count_claiming_a_billion_allocates_nothing_of_that_size(fuzz_folder, name, edit, refusal):
    """The claim is refused (``refusal`` is in the error) or the file read as the few frames it holds."""
    seed = seeds()[name]
    data = edit(seed.data)
    assert data != seed.data
    _, path = seed.place(fuzz_folder, data)
    tracemalloc.start()
    try:
        if refusal is None:
            assert read_motion(path, format=seed.format, **seed.options).n_frames == 3
        else:
            with pytest.raises(FormatError, match=re.escape(refusal)):
                read_motion(path, format=seed.format, **seed.options)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 32 * 2**20, f"{peak / 2**20:.0f} MB at the peak"


# -- HDF5 files: dataset shards and aligned recordings ----------------------------------------------------
#
# libhdf5 2.0 itself crashes (SIGSEGV) or loops forever on some damaged metadata: validate_shard
# contains that by checking in a child process (tested below). AlignedRecording.load reads in
# process, so its byte-level damage here is a cut (which libhdf5 reports cleanly); its attributes
# and datasets are edited through h5py.


def metadata_spans(path: Path) -> list[tuple[int, int]]:
    """Byte ranges [start, end) of an HDF5 file outside its datasets' stored values: superblock,
    object headers, attributes, B-trees and heaps, where damage matters to a reader of the layout."""
    stored: list[tuple[int, int]] = []

    def visit(name: str, obj: Any) -> None:
        if not isinstance(obj, h5py.Dataset):
            return
        d = obj.id
        if obj.chunks is None:
            if d.get_offset() is not None:
                stored.append((d.get_offset(), d.get_offset() + d.get_storage_size()))
        else:
            for i in range(d.get_num_chunks()):
                chunk = d.get_chunk_info(i)
                stored.append((chunk.byte_offset, chunk.byte_offset + chunk.size))

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    spans, at = [], 0
    for start, end in sorted(stored) + [(path.stat().st_size, path.stat().st_size)]:
        if start > at:
            spans.append((at, start))
        at = max(at, end)
    return spans


class Hdf5Seed:
    """A valid HDF5 file to damage: its bytes and its :func:`metadata_spans`."""

    def __init__(self, path: Path) -> None:
        self.data = path.read_bytes()
        self.spans = metadata_spans(path)

    def __repr__(self) -> str:  # hypothesis prints the arguments of a failing example
        return f"Hdf5Seed({len(self.data)} bytes)"


@st.composite
def damaged_hdf5(draw, seed: Hdf5Seed, kinds=("cut", "flip", "zero")) -> bytes:
    """The seed cut anywhere, or with bytes flipped or zeroed in its metadata spans."""
    kind = draw(st.sampled_from(kinds))
    if kind == "cut":
        return seed.data[: draw(st.integers(0, len(seed.data) - 1))]
    offsets = draw(st.lists(st.integers(0, sum(e - s for s, e in seed.spans) - 1), min_size=1, max_size=6))
    out = bytearray(seed.data)
    for offset in offsets:
        for start, end in seed.spans:  # the offset-th metadata byte
            if offset < end - start:
                at = start + offset
                break
            offset -= end - start
        if kind == "flip":
            out[at] ^= draw(st.integers(1, 255))
        else:
            end = min(len(out), at + draw(st.integers(1, 32)))
            out[at:end] = bytes(end - at)
    return bytes(out)


ODD_ATTRIBUTES = [
    "not json",
    "[]",
    "{}",
    "null",
    '{"extractor": "stft"}',
    "",
    b"\xff\xfe",
    np.array([1, 2]),
    np.int64(-1),
    np.float64(np.nan),
    np.bool_(True),
    "kinectdata.shard",
]
"""What an attribute can hold in a damaged or foreign file."""
ODD_DATASETS = [
    None,  # deleted
    np.zeros(0),
    np.zeros((2, 2)),
    np.array([-1]),
    np.array([10**12]),
    np.array([1.5]),
    np.array([b"\xff"]),
    np.array(["not json"], dtype=h5py.string_dtype()),
    np.array(["[1]"], dtype=h5py.string_dtype()),
]
"""What a dataset can be replaced with."""


def hdf5_edits(attributes: list[str], datasets: list[str]) -> st.SearchStrategy:
    """One to three (kind, name, value) edits of an HDF5 file's attributes and datasets."""
    attribute = st.tuples(st.just("attribute"), st.sampled_from(attributes), st.sampled_from(ODD_ATTRIBUTES))
    dataset = st.tuples(st.just("dataset"), st.sampled_from(datasets), st.sampled_from(ODD_DATASETS))
    return st.lists(attribute | dataset, min_size=1, max_size=3)


def apply_hdf5_edits(path: Path, edits: list[tuple[str, str, Any]]) -> None:
    with h5py.File(path, "r+") as f:
        for kind, name, value in edits:
            if kind == "attribute":
                f.attrs[name] = value
                continue
            if name in f:
                del f[name]
            if value is not None:
                f.create_dataset(name, data=value)


# -- shards


@pytest.fixture(scope="module")
def shard(sample_dataset) -> Hdf5Seed:
    return Hdf5Seed(sorted(sample_dataset.glob("*.h5"))[0])


@pytest.fixture(scope="module")
def short_isolation_timeout() -> Iterator[None]:
    """A stuck libhdf5 gives up after 8 s here (metadata of the test shards reads in milliseconds)."""
    saved, shards.ISOLATION_TIMEOUT_S = shards.ISOLATION_TIMEOUT_S, 8.0
    yield
    shards.ISOLATION_TIMEOUT_S = saved


def check_shard(path: Path, *, isolated: bool) -> None:
    """A valid shard or a FormatError naming it; a shard that validates can be read."""
    sizes = answer_or_clear_error(path, lambda: validate_shard(path, isolated=isolated))
    if sizes is not None:
        with h5py.File(path, "r") as f:
            assert sum(r["length"] for r in read_index(f)) == sizes["N"]
            for key, rule in shards.layout()["attributes"].items():
                if rule["type"] == "json":
                    json_attribute(f, key)


ISOLATED = settings(PER_EXAMPLE, deadline=timedelta(seconds=30))  # a child process each, up to 8 s when stuck


@settings(ISOLATED, max_examples=8)
@given(data=st.data())
def test_damaged_shard_bytes_give_a_clear_error(shard, short_isolation_timeout, fuzz_folder, data):
    path = fuzz_folder / "train-00000.h5"
    path.write_bytes(data.draw(damaged_hdf5(shard), label="file"))
    check_shard(path, isolated=True)


@pytest.mark.slow
@settings(ISOLATED, max_examples=64)  # a child interpreter each: 64 of them are a quarter of a minute of CPU
@given(data=st.data())
def test_damaged_shard_bytes_give_a_clear_error_at_length(shard, short_isolation_timeout, fuzz_folder, data):
    path = fuzz_folder / "train-00000.h5"
    path.write_bytes(data.draw(damaged_hdf5(shard), label="file"))
    check_shard(path, isolated=True)


@settings(PER_EXAMPLE, max_examples=40)
@given(edits=hdf5_edits(list(shards.layout()["attributes"]), list(shards.layout()["datasets"])))
def test_edited_shard_attributes_and_datasets_give_a_clear_error(shard, fuzz_folder, edits):
    """Edits through h5py leave a sound HDF5 file: checked in process."""
    path = fuzz_folder / "val-00000.h5"
    path.write_bytes(shard.data)
    apply_hdf5_edits(path, edits)
    check_shard(path, isolated=False)


def _vlen_type_bits_set_to_0xEA(data: bytearray) -> None:
    """A variable-length UTF-8 string datatype message (version 1, class 9, 16 bytes) whose
    type field becomes an undefined value: libhdf5 2.0 dereferences garbage (SIGSEGV)."""
    at = data.index(bytes.fromhex("19 01 01 00 10 00 00 00"))
    data[at + 1] = 0xEA


def _global_heap_object_of_size_0(data: bytearray) -> None:
    """The first object of the global heap collection (the text of string attributes) becomes a
    free-space entry (index 0) of size 0: libhdf5 2.0 never moves past it."""
    at = data.index(b"GCOL") + 16  # after the collection's signature, version and size
    data[at : at + 2] = bytes(2)  # heap object index
    data[at + 8 : at + 16] = bytes(8)  # object size


@pytest.mark.parametrize(
    ("damage", "words"),
    [(_vlen_type_bits_set_to_0xEA, "crashed the HDF5 library"), (_global_heap_object_of_size_0, "did not finish")],
)
def test_a_shard_that_crashes_or_hangs_libhdf5_is_a_format_error(shard, tmp_path, monkeypatch, damage, words):
    monkeypatch.setattr(shards, "ISOLATION_TIMEOUT_S", 3.0)
    data = bytearray(shard.data)
    damage(data)
    path = tmp_path / "test-00000.h5"
    path.write_bytes(bytes(data))
    with pytest.raises(FormatError, match=f"^{re.escape(str(path))}: .*{words}"):
        validate_shard(path)
    path.write_bytes(shard.data)
    assert validate_shard(path) == validate_shard(path, isolated=False)  # the child answers as in process


def test_one_child_checks_shard_after_shard_and_a_crash_costs_only_that_child(shard, tmp_path, monkeypatch):
    """The checking child is started once and reused; one that a file crashed is replaced, and the
    checks after it answer as in process."""
    from kinectdata.dataset.isolation import ShardChecker

    good, bad = tmp_path / "train-00000.h5", tmp_path / "val-00000.h5"
    good.write_bytes(shard.data)
    data = bytearray(shard.data)
    _vlen_type_bits_set_to_0xEA(data)
    bad.write_bytes(bytes(data))
    checker = ShardChecker()
    try:
        expected = validate_shard(good, isolated=False)
        assert checker.check(good, 30.0) == expected
        first = checker._process.pid
        assert checker.check(good, 30.0) == expected and checker._process.pid == first  # the same child
        with pytest.raises(FormatError, match="crashed the HDF5 library"):
            checker.check(bad, 30.0)
        assert checker._process is None  # the crashed one is gone
        assert checker.check(good, 30.0) == expected and checker._process.pid != first
        monkeypatch.chdir(tmp_path)  # a relative path is the caller's, wherever the child started
        assert checker.check(Path(good.name), 30.0) == expected
        child = checker._process
    finally:
        checker.close()
    assert child.poll() is not None  # closing ends it


def test_an_interpreter_that_will_not_start_is_named_with_the_check_it_was_for(shard, tmp_path, monkeypatch):
    """Where the user may not execute the interpreter kinectdata runs in, the shard check's child
    cannot start: the error names the shard, what was being done and the interpreter, for the
    reused child and for a child of its own alike, and a later check with a usable one works."""
    import sys

    from kinectdata.dataset.isolation import ShardChecker, check_once

    good = tmp_path / "train-00000.h5"
    good.write_bytes(shard.data)
    blocked = tmp_path / "python3"
    blocked.write_text("")
    blocked.chmod(0o644)  # not executable
    usable = sys.executable
    monkeypatch.setattr(sys, "executable", str(blocked))
    checker = ShardChecker()
    words = f"{re.escape(str(good))}: checking the shard needs a child Python process, and starting {blocked} failed"
    with pytest.raises(KinectDataError, match=words):
        checker.check(good, 30.0)
    with pytest.raises(KinectDataError, match=words):
        check_once(good, 30.0)
    monkeypatch.setattr(sys, "executable", usable)
    try:
        assert checker.check(good, 30.0) == validate_shard(good, isolated=False)
    finally:
        checker.close()


# -- aligned recordings


@pytest.fixture(scope="module")
def aligned(tmp_path_factory) -> Hdf5Seed:
    """An aligned recording: 12 frames at 30 fps of a Kinect v2 body, 0.4 s of audio."""
    source = random_motion(T=12, seed=3)
    T, J = source.positions.shape[:2]
    motion = Motion(np.arange(T) / 30.0, source.positions, source.joint_set, source.position_mask,
                    source.confidence, source.orientations)  # fmt: skip
    path = tmp_path_factory.mktemp("aligned") / "take.h5"
    AlignedRecording(
        motion,
        np.sin(np.arange(800) / 10.0).astype(np.float32),
        2000,
        30.0,
        np.zeros((T, J), bool),
        np.zeros((T, J), bool),
        offset={"seconds": 0.25, "source": "given", "confidence": None},
    ).save(path)
    return Hdf5Seed(path)


def check_aligned(path: Path) -> None:
    """An aligned recording consistent with its documented layout, or a FormatError naming it."""
    rec = answer_or_clear_error(path, lambda: AlignedRecording.load(path))
    if rec is not None:
        check_motion(rec.motion)
        np.testing.assert_allclose(rec.motion.times, np.arange(rec.n_frames) / rec.fps, rtol=0, atol=1e-9)
        shape = (rec.n_frames, rec.motion.n_joints)
        assert rec.position_interpolated.shape == shape and rec.position_interpolated.dtype == bool
        if rec.motion.has_orientations:
            assert rec.orientation_interpolated.shape == shape and rec.orientation_interpolated.dtype == bool
        assert rec.audio.ndim == 1 and rec.sample_rate > 0 and 0 < rec.fps < np.inf
        assert all(isinstance(x, dict) for x in (rec.summary, rec.motion.metadata))
        assert rec.offset is None or isinstance(rec.offset.seconds, float)
        assert all(isinstance(x, dict) for x in (rec.provenance.motion, rec.provenance.audio, rec.provenance.options))


@settings(PER_EXAMPLE, max_examples=30)
@given(data=st.data())
def test_cut_aligned_recordings_give_a_clear_error(aligned, fuzz_folder, data):
    path = fuzz_folder / "aligned_take.h5"
    path.write_bytes(data.draw(damaged_hdf5(aligned, kinds=("cut",)), label="file"))
    check_aligned(path)


ALIGNED_ATTRIBUTES = ["format", "format_version", "fps", "sample_rate", "joint_set", "offset", "provenance",
                      "summary", "gaps", "metadata"]  # fmt: skip
ALIGNED_DATASETS = [f"motion/{n}" for n in ("times", "positions", "position_mask", "position_interpolated",
                    "confidence", "orientations", "orientation_mask", "orientation_interpolated")] + [
                    "joints/names", "joints/parents", "audio/samples"]  # fmt: skip


@settings(PER_EXAMPLE, max_examples=40)
@given(edits=hdf5_edits(ALIGNED_ATTRIBUTES, ALIGNED_DATASETS))
def test_edited_aligned_recordings_give_a_clear_error(aligned, fuzz_folder, edits):
    path = fuzz_folder / "aligned_edit.h5"
    path.write_bytes(aligned.data)
    apply_hdf5_edits(path, edits)
    check_aligned(path)


# -- regressions: what the fuzzing found ---------------------------------------------------------------


def _line(data: bytes, n: int, edit: Callable[[bytes], bytes]) -> bytes:
    """``data`` with its 1-based line ``n`` edited."""
    lines = data.split(b"\n")
    lines[n - 1] = edit(lines[n - 1])
    return b"\n".join(lines)


def _cell(line: bytes, k: int, value: bytes) -> bytes:
    cells = line.split(b",")
    cells[k] = value
    return b",".join(cells)


SAME_READING = [  # the edit must not change what is read
    ("csv_canonical", lambda d: _line(d, 2, lambda ln: ln + b"\n# note: caf\x8d")),  # a byte cp1252 leaves undefined
    ("csv_lsl_kinect", lambda d: _line(d, 4, lambda ln: _cell(ln, 1, b'"' + ln.split(b",")[1] + b'"'))),
    ("csv_lsl_kinect", lambda d: _line(d, 4, lambda ln: _cell(ln, 1, b'"' + ln.split(b",")[1]))),  # stray quote
    ("csv_kinectreader", lambda d: d.replace(b",\n", b"\n")),  # no trailing delimiter on any row
    ("kinect_v2_real", lambda d: _line(d, 1, lambda ln: ln.rstrip(b","))),  # nor on the first
    ("tang2018", lambda d: json.dumps(json.loads(d), indent=1).encode()),  # saved again, indented
    ("tang2018", lambda d: b"\xef\xbb\xbf" + d),  # with a byte-order mark
    ("tang2018_config", lambda d: d.replace(b"41", b"41.0") + b"\n"),
]


@pytest.mark.parametrize(("name", "edit"), SAME_READING)
def test_edits_that_change_nothing_read(fuzz_folder, name, edit):
    seed = seeds()[name]
    _, path = seed.place(fuzz_folder)
    before = read_motion(path, format=seed.format, **seed.options)
    seed.place(fuzz_folder, edit(seed.data))
    after = read_motion(path, format=seed.format, **seed.options)
    np.testing.assert_array_equal(after.times, before.times)
    np.testing.assert_array_equal(after.positions, before.positions)
    np.testing.assert_array_equal(after.confidence, before.confidence)


_HUGE = b"1" + b"0" * 400
REFUSED = [  # (seed, edit, regex the error must match after the file name)
    ("csv_kinectreader", lambda d: _line(d, 2, lambda ln: _cell(ln, 0, _HUGE)),
     r", line 2, column 'time': '1000+\.\.\.' is beyond the range of 64-bit floating point$"),
    ("csv_lsl_kinect", lambda d: _line(d, 4, lambda ln: _cell(ln, 2, b"0.\"5")),
     r", line 4, column 'SpineBase_Y': non-numeric value '0\.\"5'$"),
    ("kinect_v2_real", lambda d: _line(d, 1, lambda ln: _cell(ln, 0, b"-1e308")),
     r", line 3, column 'time': time 8\.98\d+e\+10 ticks, counted from the first frame's -1e\+308 ticks, overflows"),
    ("csv_canonical", lambda d: _line(d, 2, lambda ln: b"# joint_set: " + b"x" * 300),
     r": the file's '# joint_set: x{37}\.\.\.' line names no known joint set"),
    ("csv_canonical", lambda d: _line(d, 2, lambda ln: b"# joint_set: ../jointsets/kinect_v2"),
     r": the file's '# joint_set: \.\./jointsets/kinect_v2' line names no known joint set"),
    ("openpose_2", lambda d: d.replace(b'"person_id": [4]', b'"person_id": [' + _HUGE + b"]", 1),
     r", line 1, frame 0: people\[0\]\.person_id must be \[integer\] \(64-bit\)"),
    ("openpose_2", lambda d: d.replace(b'"frame": 4', b'"frame": 9007199254740992'),
     r", line 3, frame 2: 'frame' must be a non-negative integer below 2\*\*53, found 9007199254740992$"),
    ("htr_real", lambda d: re.sub(rb"(\[Hips\]\r\n#[^\n]*\n)1\t", rb"\g<1>1.#QNAN\t", d),
     r", line 31: frame number nan is not a whole number$"),
    ("htr_real", lambda d: re.sub(rb"ScaleFactor \S+", b"ScaleFactor 1e308", d).replace(b"Units cm", b"Units m"),
     r", line 31: segment 'Hips' lies beyond 64-bit floating point in frame 1"),
    ("htr_real", lambda d: re.sub(rb"DataFrameRate \S+", b"DataFrameRate 1e-320", d),
     r", line 13: DataFrameRate 9\.99989e-321 makes 2 frames last beyond 64-bit floating point$"),
    ("azure_json", lambda d: re.sub(rb'"timestamp_usec": \d+', b'"timestamp_usec": -4611686018427387904', d, count=1)
     .replace(b"1267900", b"4611686018427387904").replace(b"1301233", b"4611686018427387905"),
     r", frame 2: timestamp_usec 4611686018427387905, counted from the first frame's -4611686018427387904, "),
    ("tang2018", lambda d: re.sub(rb'("center": \[\[)[-0-9.e]+', rb"\g<1>" + _HUGE, d, count=1),
     r", frame 0: 'center' is not \[3\] numbers here$"),  # an OverflowError once
    ("tang2018", lambda d: d.replace(b'"length": 3', b'"length": 1' + b"0" * 5000),
     r": not JSON \(Exceeds the limit \(4300 digits\)"),  # a ValueError once
    ("tang2018_config", lambda d: d.replace(b"45", _HUGE),
     r": end_position must be a song frame \(a number from 0 to 2\*\*53\), not 1000+\.\.\.$"),  # an OverflowError once
    ("tang2018_config", lambda d: d.replace(b"41", b"1" + b"0" * 5000), r": not JSON \(Exceeds the limit"),
]  # fmt: skip


@pytest.mark.parametrize(("name", "edit", "message"), REFUSED)
def test_edits_refused_with_the_place(fuzz_folder, name, edit, message):
    seed = seeds()[name]
    data = edit(seed.data)
    assert data != seed.data
    damaged, path = seed.place(fuzz_folder, data)
    with pytest.raises(FormatError) as err:
        read_motion(path, format=seed.format, **seed.options)
    assert re.match(re.escape(str(damaged)) + message, str(err.value)), str(err.value)


SHARD_REFUSED = [
    (("attribute", "format", np.array([1, 2])), r"attribute 'format' is array\(\[1, 2\]\), expected string$"),
    (("attribute", "fps", np.float64(np.nan)), r"attribute 'fps' is np\.float64\(nan\), expected number$"),
    (("dataset", "recordings/info", np.array(["not json"], dtype=h5py.string_dtype())),
     r"recordings\[0\] cannot be read \(Expecting value: line 1 column 1 \(char 0\)\)$"),
    (("dataset", "recordings/name", np.array([b"\xff"])), r"recordings\[0\] cannot be read \('utf-8' codec"),
    (("dataset", "recordings/info", np.array(["[1]"], dtype=h5py.string_dtype())),
     r"recordings\[0\] info is not a JSON object$"),
]  # fmt: skip


@pytest.mark.parametrize(("edit", "message"), SHARD_REFUSED)
def test_shard_edits_refused_by_name(shard, tmp_path, edit, message):
    path = tmp_path / "train-00000.h5"
    path.write_bytes(shard.data)
    apply_hdf5_edits(path, [edit])
    with pytest.raises(FormatError) as err:
        validate_shard(path, isolated=False)
    assert re.match(re.escape(str(path)) + ": " + message, str(err.value)), str(err.value)
    if edit[1].startswith("recordings/"):  # read without validating first: the same error
        with h5py.File(path, "r") as f, pytest.raises(FormatError, match=message):
            read_index(f)


ALIGNED_REFUSED = [
    (("attribute", "format", np.array([1, 2])), r"not a kinectdata aligned recording \(format attribute array"),
    (("attribute", "fps", np.float64(-30.0)), r"fps -30 and sample_rate 2000 must be positive$"),
    (("attribute", "fps", np.float64(25.0)), r"motion/times are not k / fps for the fps attribute 25$"),
    (("attribute", "offset", "[]"), r"attribute 'offset' must hold a JSON object$"),
    (("dataset", "motion/position_interpolated", np.zeros((2, 2), bool)),
     r"motion/position_interpolated is bool \(2, 2\), expected bool \[N, J\]$"),
    (("dataset", "audio/samples", np.zeros((2, 2), np.float32)),
     r"audio/samples is float32 \(2, 2\), expected float \[S\]$"),
]  # fmt: skip


@pytest.mark.parametrize(("edit", "message"), ALIGNED_REFUSED)
def test_aligned_recording_edits_refused_by_name(aligned, tmp_path, edit, message):
    path = tmp_path / "take.h5"
    path.write_bytes(aligned.data)
    apply_hdf5_edits(path, [edit])
    with pytest.raises(FormatError) as err:
        AlignedRecording.load(path)
    assert re.match(re.escape(str(path)) + ": " + message, str(err.value)), str(err.value)


PICKLES_REFUSED = [
    (b"N)r.\x18\x07A\xa7\xbb\x04GC\x0f\x84\xdc", r"memo index 1090983982 at byte 2"),  # 8 GB of memo, once 12 s
    (b"\x80\x04\x95k\n\x00\x00\x00\x00\x00\x00}\x94.", r"not a readable pickle|cannot read it as a pickle"),
]
"""Pickles the fuzzing found, each refused at once with the reason named (not read for seconds)."""


@pytest.mark.parametrize(("data", "message"), PICKLES_REFUSED)
def test_damaged_pickles_are_refused_at_once(tmp_path, data, message):
    path = tmp_path / "take.pkl"
    path.write_bytes(data)
    with time_limit(2.0), pytest.raises(FormatError, match=message) as err:
        read_motion(path, schema="aistpp_keypoints3d")
    assert str(err.value).startswith(f"{path}: ")
