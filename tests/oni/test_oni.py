"""The .oni reader against OpenNI: its own recordings and decodes, plain-loop codecs, damaged files."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest
from conftest import DATA
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinectdata.oni import OniError, OniFile, OniWarning
from kinectdata.oni.codecs import CodecError, decode_8z, decode_16z
from reference import oni_python as ref
from reference.oni_python import StreamSpec, write_oni

FIXTURES = DATA / "oni"


def read_all(path, kind):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OniWarning)
        with OniFile(path) as oni:
            frames = list(oni.frames(oni.stream(kind)))
    return np.stack([f.data for f in frames]), [f.number for f in frames], [f.timestamp_us for f in frames]


# -- OpenNI's own recordings and decodes ---------------------------------------------------------


@pytest.mark.parametrize("name", ["openni2_dummy_depth", "openni2_dummy_depth_color"])
def test_fixtures_decode_exactly_as_openni_does(name):
    reference = np.load(FIXTURES / f"{name}.reference.npz")
    kinds = ["depth"] + (["image"] if "image" in reference.files else [])
    for kind in kinds:
        frames, numbers, stamps = read_all(FIXTURES / f"{name}.oni", kind)
        np.testing.assert_array_equal(frames, reference[kind])
        np.testing.assert_array_equal(numbers, reference[f"{kind}_frame_id"])
        np.testing.assert_array_equal(stamps, reference[f"{kind}_timestamp_us"])


def test_fixture_streams_and_properties():
    with OniFile(FIXTURES / "openni2_dummy_depth_color.oni") as oni:
        assert oni.header.version == (1, 0, 1, 0) and not oni.header.old32
        assert oni.index_source == "seek table" and not oni.truncated and oni.problems == []
        depth, image = oni.stream("depth"), oni.stream("Image")
        assert (depth.name, depth.codec, depth.resolution, depth.fps, depth.pixel_format) == (
            "Depth",
            "16zT",
            (320, 240),
            30.0,
            "DEPTH_1_MM",
        )
        assert (image.codec, image.pixel_format, image.frame_layout) == ("NONE", "RGB888", ((240, 320, 3), np.uint8))
        assert (depth.n_frames, depth.recorded_frames, image.n_frames) == (3, 3, 4)
        assert depth.properties["xnDeviceMaxDepth"] == 65535 and depth.frame_layout == ((240, 320), np.uint16)
        assert depth.duration_s == pytest.approx(0.066) and depth.measured_fps == pytest.approx(30.30303)
        assert depth.dropped_frames == 0 and depth.gaps() == []
        with pytest.raises(OniError, match="no stream 'ir'; streams: depth"):
            oni.stream("ir")
        with pytest.raises(OniError, match="has 3 frames, no frame index 3"):
            oni.read_frame(depth, 3)


# -- codecs against OpenNI's algorithms written as plain loops -----------------------------------

CODE_BYTES = st.sampled_from([0x0F, 0xFF, 0x7F, 0x80, 0xC0, 0xE3, 0xE0, 0x66, 0x6D, 0x1F, 0xF5, 0xFD, 0xEF, 0x05])
BODIES = st.one_of(st.binary(max_size=80), st.lists(CODE_BYTES, max_size=80).map(bytes))


def agree(ours, theirs, payload, *args):
    """Both decode the payload identically, or both find it cut short."""
    try:
        expected = theirs(payload, 10**9, *args)
    except IndexError:
        with pytest.raises(CodecError):
            ours(payload, 1, *args)
        return
    np.testing.assert_array_equal(ours(payload, expected.size, *args), expected)


@settings(max_examples=400, deadline=None)
@given(first=st.binary(min_size=2, max_size=2), body=BODIES)
def test_16z_decoder_matches_openni_on_any_bytes(first, body):
    agree(lambda p, n, t: decode_16z(p, n, table=t), ref.decode_16z, first + body, False)


@settings(max_examples=400, deadline=None)
@given(first=st.binary(min_size=1, max_size=1), body=BODIES)
def test_8z_decoder_matches_openni_on_any_bytes(first, body):
    agree(lambda p, n: decode_8z(p, n), ref.decode_8z, first + body)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    values=st.lists(st.integers(0, 32767), min_size=1, max_size=300)
    | st.lists(st.integers(1000, 1010), min_size=1, max_size=300)
)
def test_16z_and_16zt_of_openni_encoded_values(values):
    depth = np.array(values, np.uint16)
    for payload, table in ((ref.encode_16z(depth), False), (ref.encode_16zt(depth), True)):
        np.testing.assert_array_equal(
            decode_16z(payload, depth.size, table=table), ref.decode_16z(payload, depth.size, table)
        )


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.integers(0, 255), min_size=1, max_size=300) | st.lists(st.integers(100, 104), min_size=1))
def test_8z_of_openni_encoded_values(values):
    data = np.array(values, np.uint8)
    payload = ref.encode_8z(data)
    np.testing.assert_array_equal(decode_8z(payload, data.size), ref.decode_8z(payload, data.size))


def test_decoders_report_short_and_out_of_table_frames():
    depth = np.arange(100, 200, dtype=np.uint16)
    payload = ref.encode_16zt(depth)
    with pytest.raises(CodecError, match="100 values decoded, 101 expected"):
        decode_16z(payload, 101, table=True)
    np.testing.assert_array_equal(decode_16z(payload + b"\x66", 100, table=True), depth)  # a trailing byte is dropped
    bad = bytearray(payload)
    bad[0] = 10  # a table of 10 entries, so the stream's indices run past it
    with pytest.raises(CodecError, match="ends early|past the 10-entry value table"):
        decode_16z(bytes(bad), 100, table=True)
    with pytest.raises(CodecError, match="ends inside an escape"):
        decode_16z(b"\x00\x01\xff", 2, table=False)
    with pytest.raises(CodecError, match="ends early"):
        decode_16z(b"\x05", 1, table=False)


def test_a_pathological_escape_chain_is_settled_exactly():
    """A long run of bytes that could each open an escape: the iterative settling gives up and the
    exact in-order pass decides, as OpenNI's loop would."""
    payload = b"\x00\x10" + b"\x8f" * 500  # 250 codes, each an F nibble and a one-byte escape
    expected = ref.decode_16z(payload, 10**9, False)
    np.testing.assert_array_equal(decode_16z(payload, expected.size, table=False), expected)


@settings(max_examples=300, deadline=None)
@given(
    table=st.lists(st.integers(0, 65535), min_size=1, max_size=20),
    first=st.integers(0, 255),
    body=BODIES,
    fraction=st.floats(0.0, 1.0),
)
def test_16zt_decoder_matches_openni_up_to_any_frame_size(table, first, body, fraction):
    """A frame ends at its size: what the stream holds beyond it (a writer's trailing byte, an
    index past the table) does not matter."""
    payload = (
        len(table).to_bytes(2, "little") + np.array(table, "<u2").tobytes() + bytes([first % len(table), 0]) + body
    )
    try:  # the stream of indices, by OpenNI's loop (16zT is 16z on indices, looked up after)
        indices = ref.decode_16z(payload[2 + 2 * len(table) :], 10**9, False)
    except IndexError:
        return  # cut inside a code: covered by the 16z test
    count = max(1, int(fraction * indices.size))
    if len(body) + 2 > 3 * count + 16:  # longer than any encoding of `count` values: a damaged size
        with pytest.raises(CodecError, match="more than any encoding"):
            decode_16z(payload, count, table=True)
        return
    if int(indices[:count].max()) >= len(table):
        with pytest.raises(CodecError, match="past the"):
            decode_16z(payload, count, table=True)
        return
    np.testing.assert_array_equal(decode_16z(payload, count, table=True), np.array(table, np.uint16)[indices[:count]])


def test_damaged_sizes_cannot_make_the_decoders_allocate_without_bound():
    with pytest.raises(CodecError, match="more than any encoding of the frame"):
        decode_16z(b"\x00\x00" + b"\xfe" * 10_000_000, 640 * 480, table=False)
    with pytest.raises(CodecError, match="more than any encoding of the frame"):
        decode_8z(b"\x00" + b"\xef" * 10_000, 100)
    # within the limit, runs far longer than the frame stop at the frame
    out = decode_16z(b"\x07\x00" + b"\xfe" * 300, 1000, table=False)
    np.testing.assert_array_equal(out, np.full(1000, 7, np.uint16))


# -- the container: layouts, versions, dropped frames ------------------------------------------


def scene(n=5, h=24, w=32, seed=0):
    rng = np.random.default_rng(seed)
    depth = rng.integers(500, 4000, (n, h, w)).astype(np.uint16)
    depth[:, :, :4] = 0
    image = rng.integers(0, 256, (n - 1, h, w, 3)).astype(np.uint8)
    return depth, image


@pytest.mark.parametrize("version", [(1, 0, 0, 4), (1, 0, 0, 5), (1, 0, 0, 6), (1, 0, 1, 0)])
@pytest.mark.parametrize("codecs", [("16zT", "Im8z"), ("16zP", "NONE"), ("NONE", "Im8z")])
def test_every_layout_version_and_codec(tmp_path, version, codecs):
    depth, image = scene()
    path = tmp_path / "take.oni"
    write_oni(
        path,
        [StreamSpec("Depth", "depth", codecs[0], depth), StreamSpec("Image", "image", codecs[1], image)],
        version=version,
    )
    with OniFile(path) as oni:
        assert oni.header.old32 == (version < (1, 0, 1, 0)) and oni.problems == []
        assert oni.index_source == ("seek table" if version >= (1, 0, 0, 6) else "scan")
        assert [s.recorded_frames for s in oni.streams] == [5, 4]
    np.testing.assert_array_equal(read_all(path, "depth")[0], depth)
    np.testing.assert_array_equal(read_all(path, "image")[0], image)


def test_dropped_frames_and_gaps(tmp_path):
    depth, _ = scene(6)
    numbers = [1, 2, 3, 5, 6, 9]
    stamps = [round((k - 1) * 1e6 / 30) for k in numbers]
    write_oni(
        tmp_path / "d.oni", [StreamSpec("Depth", "depth", "16zT", depth, timestamps_us=stamps, frame_numbers=numbers)]
    )
    with OniFile(tmp_path / "d.oni") as oni:
        s = oni.stream("depth")
        assert s.dropped_frames == 3
        assert [n for n, _ in s.gaps()] == [5, 9] and s.gaps()[1][1] == pytest.approx(0.1, abs=1e-3)
        assert [f.number for f in oni.frames(s)] == numbers


def test_a_damaged_seek_table_falls_back_to_walking_the_records(tmp_path):
    depth, image = scene()
    data = bytearray(
        write_oni(None, [StreamSpec("Depth", "depth", "16zT", depth), StreamSpec("Image", "image", "NONE", image)])
    )
    table = data.rfind(b"NIR\0\x0e\x00\x00\x00")  # the last SEEK_TABLE record
    data[table + 28 + 20 + 12 + 3] ^= 0xFF  # frame 1's position (after the placeholder) now points past the end
    (tmp_path / "s.oni").write_bytes(bytes(data))
    with OniFile(tmp_path / "s.oni") as oni:
        assert oni.index_source == "scan" and oni.problems == []
    np.testing.assert_array_equal(read_all(tmp_path / "s.oni", "depth")[0], depth)
    np.testing.assert_array_equal(read_all(tmp_path / "s.oni", "image")[0], image)


def test_dropped_frames_from_timestamps_when_numbers_run_on(tmp_path):
    """OpenNI's recorders number the frames they receive: a drop shows only in the timestamps."""
    depth, _ = scene(5)
    stamps = [0, 33_333, 133_333, 166_667, 200_000]  # two frames missing after the second
    write_oni(tmp_path / "d.oni", [StreamSpec("Depth", "depth", "16zT", depth, timestamps_us=stamps)])
    with OniFile(tmp_path / "d.oni") as oni:
        assert oni.stream("depth").dropped_frames == 2


def test_a_stream_added_while_recording_is_found(tmp_path):
    depth, image = scene(6)
    write_oni(
        tmp_path / "late.oni",
        [
            StreamSpec("Depth", "depth", "16zT", depth),
            StreamSpec(
                "Image", "image", "NONE", image, timestamps_us=[100_000 + 33_333 * k for k in range(5)], added_late=True
            ),
        ],
    )
    with OniFile(tmp_path / "late.oni") as oni:
        assert oni.index_source == "scan" and not oni.problems
        assert [s.kind for s in oni.streams] == ["depth", "image"]
    np.testing.assert_array_equal(read_all(tmp_path / "late.oni", "image")[0], image)


def seek_table_of(data: bytes, node: int) -> int:
    return data.find(b"NIR\0\x0e\x00\x00\x00" + node.to_bytes(4, "little"))


def test_damaged_seek_tables_and_records_never_escape_as_other_errors(tmp_path):
    depth, image = scene(4)
    data = write_oni(None, [StreamSpec("Depth", "depth", "16zT", depth), StreamSpec("Image", "image", "NONE", image)])
    # the depth table points at the image stream's records
    bad = bytearray(data)
    depth_table, image_table = seek_table_of(data, 1), seek_table_of(data, 2)
    bad[depth_table + 28 + 20 + 12 : depth_table + 28 + 20 + 20] = data[
        image_table + 28 + 20 + 12 : image_table + 28 + 20 + 20
    ]
    (tmp_path / "a.oni").write_bytes(bytes(bad))
    with OniFile(tmp_path / "a.oni") as oni:
        assert oni.index_source == "scan"
    np.testing.assert_array_equal(read_all(tmp_path / "a.oni", "depth")[0], depth)
    # a seek table whose size is not a whole number of entries
    bad = bytearray(data)
    bad[image_table + 16 : image_table + 20] = (4 * 20 + 7).to_bytes(4, "little")
    (tmp_path / "b.oni").write_bytes(bytes(bad))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OniWarning)
        with OniFile(tmp_path / "b.oni") as oni:
            assert oni.index_source == "scan"
            assert oni.stream("depth").n_frames == 4
    # an absurd resolution
    bad = bytearray(data)
    mode = bad.find(b"xnMapOutputMode\0") + 16 + 4
    bad[mode : mode + 8] = b"\xff" * 8
    (tmp_path / "c.oni").write_bytes(bytes(bad))
    with OniFile(tmp_path / "c.oni") as oni:
        with pytest.raises(OniError, match=r"c\.oni: Depth frame 1 .* not plausible"):
            oni.read_frame(oni.stream("depth"), 0)


def test_a_frame_record_with_short_fields_stops_the_walk_there(tmp_path):
    depth, _ = scene(5)
    data = bytearray(write_oni(None, [StreamSpec("Depth", "depth", "16zT", depth)], finish=False))
    third = [i for i in range(len(data)) if data.startswith(b"NIR\0\x0a\x00\x00\x00", i)][2]
    data[third + 12 : third + 16] = (28 + 4).to_bytes(4, "little")  # fields size: too short for ts + number
    (tmp_path / "s.oni").write_bytes(bytes(data))
    with pytest.warns(OniWarning, match="shorter than its fields"):
        oni = OniFile(tmp_path / "s.oni")
    with oni:
        assert oni.stream("depth").n_frames == 2


# -- files cut short or damaged ----------------------------------------------------------------


def test_a_recording_cut_short_reads_up_to_the_cut(tmp_path):
    depth, image = scene(8)
    data = write_oni(
        None, [StreamSpec("Depth", "depth", "16zT", depth), StreamSpec("Image", "image", "NONE", image)], finish=False
    )
    step = max(1, len(data) // 60)
    for cut in list(range(24, len(data), step)) + [len(data)]:
        path = tmp_path / "cut.oni"
        path.write_bytes(data[:cut])
        with pytest.warns(OniWarning, match=r"cut\.oni: byte \d+"):
            oni = OniFile(path)
        with oni:
            assert oni.truncated and oni.index_source == "scan"
            originals = {"depth": depth, "image": image}
            for stream in oni.streams:  # a cut in the header may leave a stream out entirely
                got = [f.data for f in oni.frames(stream)]
                for k, frame in enumerate(got):  # every frame before the cut, exactly
                    np.testing.assert_array_equal(frame, originals[stream.kind][k])
    assert len(got) == len(image)  # uncut, all frames


def read_everything_or_fail_naming(path) -> None:
    """Open and decode every frame; the only failure allowed is an OniError naming the file."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OniWarning)
            with OniFile(path) as oni:
                for s in oni.streams:
                    for _ in oni.frames(s):
                        pass
    except OniError as exc:
        assert path.name in str(exc)


def test_a_finished_file_cut_anywhere_never_crashes_or_hangs(tmp_path):
    depth, image = scene(4)
    data = write_oni(None, [StreamSpec("Depth", "depth", "16zT", depth), StreamSpec("Image", "image", "Im8z", image)])
    for cut in range(0, len(data), 37):
        path = tmp_path / "c.oni"
        path.write_bytes(data[:cut])
        read_everything_or_fail_naming(path)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(flips=st.lists(st.tuples(st.integers(0, 10**6), st.integers(1, 255)), min_size=1, max_size=6))
def test_corrupted_bytes_give_frames_or_a_clear_error(tmp_path, flips):
    depth, image = scene(3)
    data = bytearray(
        write_oni(None, [StreamSpec("Depth", "depth", "16zT", depth), StreamSpec("Image", "image", "Im8z", image)])
    )
    for at, xor in flips:
        data[at % len(data)] ^= xor
    path = tmp_path / "x.oni"
    path.write_bytes(bytes(data))
    started = time.monotonic()
    read_everything_or_fail_naming(path)
    assert time.monotonic() - started < 5


def test_not_an_oni_file(tmp_path):
    (tmp_path / "a.oni").write_bytes(b"RIFF" + bytes(40))
    with pytest.raises(OniError, match=r"a\.oni: not an \.oni file"):
        OniFile(tmp_path / "a.oni")
    (tmp_path / "b.oni").write_bytes(b"NI10")
    with pytest.raises(OniError, match="too short for the 24-byte"):
        OniFile(tmp_path / "b.oni")
    with pytest.raises(OniError, match="missing.oni: no such file"):
        OniFile(tmp_path / "missing.oni")


# -- the command line --------------------------------------------------------------------------


def cli(*args):
    from click.testing import CliRunner

    from kinectdata.cli import main

    return CliRunner().invoke(main, [str(a) for a in args])


def test_oni_info_describes_streams_and_timing():
    result = cli("oni", "info", FIXTURES / "openni2_dummy_depth_color.oni")
    assert result.exit_code == 0, result.output
    for phrase in (
        ".oni version 1.0.1.0, current (u64 positions)",
        "depth 'Depth' (node 1): 16zT, DEPTH_1_MM, 320x240, 30 fps nominal",
        "image 'Image' (node 2): NONE, RGB888, 320x240",
        "3 frames, 0.066 s (timestamps 0..66000 us), 30.303 fps measured",
        "dropped frames 0; gaps over 1.5 frame periods 0",
    ):
        assert phrase in result.output, phrase
    as_json = cli("oni", "info", "--json", FIXTURES / "openni2_dummy_depth.oni")
    import json

    doc = json.loads(as_json.output)
    assert doc["streams"][0]["frames"] == 29 and doc["truncated"] is False


def test_oni_info_reports_a_truncated_file(tmp_path):
    depth, _ = scene(6)
    data = write_oni(None, [StreamSpec("Depth", "depth", "16zT", depth)], finish=False)
    (tmp_path / "t.oni").write_bytes(data[: len(data) - 50])
    result = cli("oni", "info", tmp_path / "t.oni")
    assert result.exit_code == 0, result.output
    assert "TRUNCATED" in result.output and "the file ends inside a NEW_DATA record" in result.output
    assert "5 frames" in result.output


def test_oni_export_writes_frames_and_timestamps(tmp_path):
    import h5py

    reference = np.load(FIXTURES / "openni2_dummy_depth.reference.npz")
    out = tmp_path / "depth.h5"
    result = cli("oni", "export", FIXTURES / "openni2_dummy_depth.oni", "-o", out, "--start", 0.1, "--end", 0.5)
    assert result.exit_code == 0, result.output
    t = reference["depth_timestamp_us"] / 1e6
    keep = (t >= 0.1) & (t < 0.5)
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f["frames"][()], reference["depth"][keep])
        np.testing.assert_array_equal(f["timestamps_us"][()], reference["depth_timestamp_us"][keep])
        np.testing.assert_array_equal(f["frame_numbers"][()], reference["depth_frame_id"][keep])
        np.testing.assert_allclose(f["time_s"][()], t[keep])
        assert f["frames"].chunks == (1, 240, 320)
        assert (f.attrs["format"], f.attrs["stream"], f.attrs["codec"], f.attrs["depth_unit_mm"]) == (
            "kinectdata.oni-frames",
            "Depth",
            "16zT",
            1.0,
        )
    image = tmp_path / "image.h5"
    assert (
        cli("oni", "export", FIXTURES / "openni2_dummy_depth_color.oni", "--stream", "image", "-o", image).exit_code
        == 0
    )
    with h5py.File(image, "r") as f:
        expected = np.load(FIXTURES / "openni2_dummy_depth_color.reference.npz")["image"]
        np.testing.assert_array_equal(f["frames"][()], expected)


def test_oni_export_errors_name_the_file_and_leave_nothing(tmp_path):
    out = tmp_path / "x.h5"
    result = cli("oni", "export", FIXTURES / "openni2_dummy_depth.oni", "--stream", "ir", "-o", out)
    assert result.exit_code == 1 and "openni2_dummy_depth.oni: no stream 'ir'" in result.output
    result = cli("oni", "export", FIXTURES / "openni2_dummy_depth.oni", "-o", out, "--start", 5)
    assert result.exit_code == 1 and "no frames in the selection" in result.output
    (tmp_path / "bad.oni").write_bytes(b"not an oni file at all, really")
    result = cli("oni", "info", tmp_path / "bad.oni")
    assert result.exit_code == 1 and "bad.oni: not an .oni file" in result.output
    assert not out.exists() and not list(tmp_path.glob(".*partial"))
