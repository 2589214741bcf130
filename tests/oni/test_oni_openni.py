"""Fresh recordings written by the real OpenNI (1.x and 2) and decoded by OpenNI's own player
must decode identically in kinectdata. Skipped, with the reason, where OpenNI is not installed
(``.ci/run`` installs it)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import DATA
from helpers import skip_unless_installed

from kinectdata.oni import OniFile, OniWarning
from reference import openni as openni_ref
from reference.oni_python import StreamSpec, write_oni

BASE = DATA / "oni" / "openni2_dummy_depth_color.oni"  # OpenNI 1.x's mock nodes are based on its nodes


@pytest.fixture(scope="module")
def openni1():
    skip_unless_installed(openni_ref.openni1_missing(), "OpenNI 1.x")
    return openni_ref.tool()


@pytest.fixture(scope="module")
def openni2():
    skip_unless_installed(openni_ref.openni2_missing(), "OpenNI2")


def depth_scene(n: int, h: int = 480, w: int = 640, seed: int = 3) -> np.ndarray:
    """Kinect-like depth in mm: a tilted wall, a moving blob, holes, a blind band."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    frames = []
    for k in range(n):
        d = 2500 + (x * 1.3).astype(np.int64) + rng.integers(-12, 13, (h, w))
        blob = (x - 200 - 20 * k) ** 2 + (y - 240) ** 2 < 90**2
        d[blob] = 1400 + rng.integers(-5, 6, blob.sum())
        d[rng.random((h, w)) < 0.01] = 0
        d[:, :8] = 0
        frames.append(d)
    return np.stack(frames).astype(np.uint16)


def rgb_scene(n: int, h: int = 480, w: int = 640) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    return np.stack([np.stack([(x + 3 * k) % 256, (y * 2) % 256, (x + y + k) % 256], -1) for k in range(n)]).astype(
        np.uint8
    )


def ours(path, name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OniWarning)
        with OniFile(path) as oni:
            stream = oni.stream(name)
            frames = list(oni.frames(stream))
    return {
        "frames": np.stack([f.data for f in frames]),
        "frame_id": np.array([f.number for f in frames]),
        "timestamp_us": np.array([f.timestamp_us for f in frames], np.uint64),
    }


def assert_same_as_openni(path) -> dict:
    theirs = openni_ref.dump(path)
    assert theirs, "OpenNI decoded nothing"
    for name, expected in theirs.items():
        got = ours(path, name)
        for key in ("frames", "frame_id", "timestamp_us"):
            np.testing.assert_array_equal(got[key], expected[key], err_msg=f"{path.name} {name} {key}")
    return theirs


@pytest.mark.parametrize(
    "feeds",
    [
        [("depth", "16zT")],
        [("depth", "16zP"), ("image", "Im8z")],
        [("depth", "NONE"), ("image", "NONE")],
        [("image", "JPEG")],
    ],
    ids=lambda f: "+".join(c for _, c in f),
)
def test_openni1_recordings_at_640x480(openni1, tmp_path, feeds):
    data = {"depth": depth_scene(6), "image": rgb_scene(5)}
    path = tmp_path / "rec.oni"
    openni_ref.record(BASE, path, [(kind, data[kind], codec) for kind, codec in feeds])
    theirs = assert_same_as_openni(path)
    with OniFile(path) as oni:
        assert [s.codec for s in oni.streams] == [codec for _, codec in feeds]
        assert all(s.resolution == (640, 480) for s in oni.streams)
    for (kind, codec), decoded in zip(feeds, theirs.values()):
        if codec != "JPEG":  # lossless codecs give back what was recorded (but see docs/oni.md on 16z's tail)
            assert np.mean(decoded["frames"] == data[kind][: len(decoded["frames"])]) > 0.999


@pytest.mark.parametrize("version", [(1, 0, 0, 4), (1, 0, 0, 5), (1, 0, 0, 6), (1, 0, 1, 0)])
def test_openni1_plays_the_reference_writers_files_as_kinectdata_reads_them(openni1, tmp_path, version):
    """The files the other tests fabricate (old32 layouts, every record version) are real .oni
    files: OpenNI decodes them to the frames kinectdata does."""
    depth, image = depth_scene(4, 60, 80), rgb_scene(3, 60, 80)
    path = tmp_path / "w.oni"
    write_oni(
        path,
        [StreamSpec("Depth", "depth", "16zT", depth), StreamSpec("Image", "image", "Im8z", image)],
        version=version,
    )
    theirs = assert_same_as_openni(path)
    np.testing.assert_array_equal(theirs["Depth"]["frames"], depth)


def test_openni2_dummy_recordings(openni2, tmp_path):
    for color, lossy in ((False, False), (True, False), (True, True)):
        path = tmp_path / f"dummy-{color}-{lossy}.oni"
        openni_ref.record_dummy(path, 0.5, color=color, lossy=lossy)
        with OniFile(path) as oni:
            assert oni.index_source == "seek table" and not oni.problems
            depth = oni.stream("depth")
            assert (depth.codec, depth.resolution, depth.pixel_format) == ("16zT", (320, 240), "DEPTH_1_MM")
            assert depth.n_frames >= 5 and depth.timestamps_us[0] == 0 and depth.dropped_frames == 0
            if color:
                assert oni.stream("image").codec == ("JPEG" if lossy else "NONE")
        if openni_ref.openni1_missing() is None:
            assert_same_as_openni(path)


def test_an_openni2_recording_cut_short_reads_what_was_written(openni2, tmp_path):
    path = tmp_path / "full.oni"
    openni_ref.record_dummy(path, 0.5)
    full = ours(path, "depth")
    data = path.read_bytes()
    end = data.rfind(b"NIR\0\x0b\x00\x00\x00")  # the END record; the rest is OpenNI2's zero padding
    cut = tmp_path / "cut.oni"
    cut.write_bytes(data[: int(end * 0.6)])
    with pytest.warns(OniWarning, match=r"cut\.oni: byte \d+: the file ends inside"):
        with OniFile(cut) as oni:
            assert oni.truncated and oni.index_source == "scan"
    part = ours(cut, "depth")
    assert 0 < len(part["frames"]) < len(full["frames"])
    np.testing.assert_array_equal(part["frames"], full["frames"][: len(part["frames"])])
