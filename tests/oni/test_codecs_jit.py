"""The compiled .oni frame decoders (numba, kinectdata/oni/codecs_jit.py) against the numpy ones:
the same values for every payload, the same CodecError for every malformed one.

Under CI these tests fail when numba is missing (it is in the ``test`` extra): otherwise the
compiled path, the one users of ``kinectdata[fast]`` get, would go untested.
"""

from __future__ import annotations

import os
import warnings
from contextlib import contextmanager

import numpy as np
import pytest
from conftest import DATA
from helpers import skip_unless_installed
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinectdata.oni import OniFile, OniWarning
from kinectdata.oni import codecs as C
from kinectdata.oni.codecs import CodecError
from reference import oni_python as ref
from reference.oni_python import StreamSpec, write_oni

CODE_BYTES = st.sampled_from(
    [0x0F, 0xFF, 0x7F, 0x80, 0xC0, 0xE3, 0xE0, 0xFE, 0xEF, 0xF0, 0x66, 0x6D, 0x1F, 0xF5, 0xFD, 0x05, 0x00, 0x3F]
)
BODIES = st.one_of(st.binary(max_size=120), st.lists(CODE_BYTES, max_size=120).map(bytes))


@contextmanager
def jit_setting(value: str | None):
    """``KINECTDATA_JIT`` set to ``value`` (None: unset) inside the block, as it was after it."""
    saved = os.environ.pop("KINECTDATA_JIT", None)
    if value is not None:
        os.environ["KINECTDATA_JIT"] = value
    try:
        yield
    finally:
        os.environ.pop("KINECTDATA_JIT", None)
        if saved is not None:
            os.environ["KINECTDATA_JIT"] = saved


def require_jit() -> None:
    """Skip where numba is missing, but fail under CI (which installs it)."""
    with jit_setting(None):
        missing = C.jit_missing()
    skip_unless_installed(missing, "numba (the compiled .oni decoders)")


@contextmanager
def jit_on():
    """The public decoders with their compiled path inside the block."""
    require_jit()
    with jit_setting(None):
        assert C.jit_available()
        yield


def outcome(decode, *args, **kwargs):
    """("ok", values) or ("error", the CodecError's message)."""
    try:
        return "ok", decode(*args, **kwargs)
    except CodecError as exc:
        return "error", str(exc)


def assert_same(jit, numpy):
    assert jit[0] == numpy[0], (jit, numpy)
    if jit[0] == "ok":
        assert jit[1].dtype == numpy[1].dtype and jit[1].shape == numpy[1].shape
        np.testing.assert_array_equal(jit[1], numpy[1])
    else:
        assert jit[1] == numpy[1]


def check_16z(payload: bytes, count: int, table: bool):
    """Both paths agree on a 16z payload, through the public decoder and at the kernel: a kernel
    status OK means the numpy decoder accepts the payload and gives the same values, and every
    payload the numpy decoder refuses gets another status."""
    with jit_on():
        jit = outcome(C.decode_16z, payload, count, table=table)
    numpy = outcome(C._decode_16z_numpy, payload, count, table=table)
    assert_same(jit, numpy)
    buf = np.frombuffer(payload, np.uint8)
    try:
        pos, lut = C._16z_header(buf, count, table, "16z frame")
    except CodecError:
        return numpy
    with jit_on():
        kernels = C._jit_module()
    status, values = kernels.decode_16z(buf, pos, count, lut)
    if status == kernels.OK:
        assert numpy[0] == "ok"
        np.testing.assert_array_equal(values, numpy[1])
    elif numpy[0] == "ok":  # only "an index past the table", past the frame's end
        assert table and status == kernels.PAST_TABLE
    return numpy


def check_8z(payload: bytes, count: int):
    with jit_on():
        jit = outcome(C.decode_8z, payload, count)
    numpy = outcome(C._decode_8z_numpy, payload, count)
    assert_same(jit, numpy)
    buf = np.frombuffer(payload, np.uint8)
    try:
        C._8z_sizes(buf, count, "Im8z frame")
    except CodecError:
        return numpy
    with jit_on():
        kernels = C._jit_module()
    status, values = kernels.decode_8z(buf, count)
    assert (status == kernels.OK) == (numpy[0] == "ok")
    if status == kernels.OK:
        np.testing.assert_array_equal(values, numpy[1])
    return numpy


def full_count(decode, payload, *args):
    """How many values OpenNI's loop (reference/oni_python.py) decodes from the payload (1 where
    the payload is cut inside a code)."""
    try:
        return max(1, decode(payload, 10**9, *args).size)
    except IndexError:
        return 1


# -- any bytes ------------------------------------------------------------------------------------


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(first=st.binary(min_size=2, max_size=2), body=BODIES, fraction=st.floats(0.0, 1.3))
def test_16z_any_bytes_decode_alike(first, body, fraction):
    payload = first + body
    count = max(1, int(fraction * full_count(ref.decode_16z, payload, False)))
    check_16z(payload, count, False)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    table=st.lists(st.integers(0, 65535), max_size=12),
    first=st.integers(0, 14),
    body=BODIES,
    fraction=st.floats(0.0, 1.3),
)
def test_16zt_any_bytes_decode_alike(table, first, body, fraction):
    """Tables of 0..12 entries against indices that often run past them, inside or beyond the frame."""
    payload = len(table).to_bytes(2, "little") + np.array(table, "<u2").tobytes() + bytes([first, 0]) + body
    count = max(1, int(fraction * full_count(ref.decode_16z, payload[2 + 2 * len(table) :], False)))
    check_16z(payload, count, True)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(first=st.binary(min_size=1, max_size=1), body=BODIES, fraction=st.floats(0.0, 1.3))
def test_8z_any_bytes_decode_alike(first, body, fraction):
    payload = first + body
    count = max(1, int(fraction * full_count(ref.decode_8z, payload)))
    check_8z(payload, count)


# -- encoded frames (the existing codec tests' inputs) ----------------------------------------------


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    values=st.lists(st.integers(0, 32767), min_size=1, max_size=300)
    | st.lists(st.integers(1000, 1010), min_size=1, max_size=300)
)
def test_openni_encoded_16z_and_16zt_decode_alike(values):
    depth = np.array(values, np.uint16)
    for payload, table in ((ref.encode_16z(depth), False), (ref.encode_16zt(depth), True)):
        assert check_16z(payload, depth.size, table)[0] == "ok"
        expected = ref.decode_16z(payload, depth.size, table)  # OpenNI's encoder may garble a last value (docs/oni.md)
        with jit_on():
            np.testing.assert_array_equal(C.decode_16z(payload, depth.size, table=table), expected)


@settings(max_examples=150, deadline=None)
@given(values=st.lists(st.integers(0, 255), min_size=1, max_size=300) | st.lists(st.integers(100, 104), min_size=1))
def test_openni_encoded_8z_decode_alike(values):
    data = np.array(values, np.uint8)
    payload = ref.encode_8z(data)
    assert check_8z(payload, data.size)[0] == "ok"
    with jit_on():
        np.testing.assert_array_equal(C.decode_8z(payload, data.size), ref.decode_8z(payload, data.size))


def test_the_existing_fixed_cases_decode_alike():
    """tests/oni/test_oni.py's hand-made payloads."""
    depth = np.arange(100, 200, dtype=np.uint16)
    payload = ref.encode_16zt(depth)
    bad = bytearray(payload)
    bad[0] = 10
    cases = [
        (payload, 101, True),  # too few values
        (payload + b"\x66", 100, True),  # a trailing byte
        (bytes(bad), 100, True),  # a table of 10 entries
        (b"\x00\x01\xff", 2, False),  # ends inside an escape
        (b"\x05", 1, False),  # ends early
        (b"\x00\x10" + b"\x8f" * 500, 251, False),  # the pathological escape chain
        (b"\x00\x00" + b"\xfe" * 10_000_000, 640 * 480, False),  # longer than any encoding
        (b"\x07\x00" + b"\xfe" * 300, 1000, False),  # runs far longer than the frame
    ]
    for case in cases:
        check_16z(*case)
    check_8z(b"\x00" + b"\xef" * 10_000, 100)
    with jit_on():
        np.testing.assert_array_equal(C.decode_16z(b"\x07\x00" + b"\xfe" * 300, 1000, table=False), np.full(1000, 7))
        with pytest.raises(CodecError, match="ends inside an escape"):
            C.decode_16z(b"\x00\x01\xff", 2, table=False)


# -- adversarial payloads -----------------------------------------------------------------------------


def frames(seed=0):
    """A few [2000] frames: noisy depth with holes, long flat stretches, big jumps."""
    rng = np.random.default_rng(seed)
    noisy = (1500 + np.cumsum(rng.integers(-3, 4, 2000))).astype(np.uint16)
    noisy[rng.random(2000) < 0.05] = 0
    flat = np.repeat(rng.integers(0, 4000, 20), 100).astype(np.uint16)
    jumps = rng.integers(0, 32768, 2000).astype(np.uint16)
    return [noisy, flat, jumps]


def test_every_cut_of_encoded_frames_is_refused_alike():
    for depth in frames():
        for payload, table in ((ref.encode_16z(depth[:300]), False), (ref.encode_16zt(depth[:300]), True)):
            for end in range(len(payload) + 1):
                check_16z(payload[:end], 300, table)
        data = depth[:300].astype(np.uint8)
        payload = ref.encode_8z(data)
        for end in range(len(payload) + 1):
            check_8z(payload[:end], 300)


def test_runs_escapes_and_absolute_values_decode_alike():
    rng = np.random.default_rng(1)
    cases16 = [
        b"\x00\x00" + b"\xfe" * 5000,  # the longest runs, 60 values each
        b"\x34\x12" + bytes(range(0xE0, 0xFF)) * 50,  # runs of every length, 0 to 60 values
        b"\x34\x12" + b"\xe1\xfe\xe0\xe2\x66\xe9\x5d" * 300,  # runs between pairs
        b"\x00\x10" + b"\x8f" * 3000,  # escape chains
        b"\x00\x10" + b"\xff\x7f\xff" * 1000,  # absolute values
        b"\x00\x10" + b"\xff\xc5" * 1000 + b"\x6d" * 10,  # one-byte differences, pairs with one value
        b"\xff\xff" + b"\x00\x0f\xff\x12\x34\xf0\x66" * 300,  # wrapping below 0 and above 65535
    ]
    for payload in cases16:
        total = full_count(ref.decode_16z, payload, False)
        for count in (1, 2, total // 3, total - 1, total, total + 1, total + 70):
            if count >= 1:
                check_16z(payload, count, False)
                lut = rng.integers(0, 65536, 4096).astype("<u2")
                check_16z(len(lut).to_bytes(2, "little") + lut.tobytes() + payload, count, True)
    cases8 = [
        b"\x10" + b"\xef" * 2000,
        b"\x10" + bytes(range(0xE0, 0xF0)) * 100,  # runs of every length, 0 to 30 values
        b"\x10" + b"\xe1\xef\xe0\xe7\x66\xe9\x5d\xf1\x2f\x33" * 300,
        b"\x10" + b"\xf1\x2f\x33" * 1000,  # absolute pairs, the common RGB case
        b"\x10" + b"\xf1\x2f\x33\xf4\x56\xf7\x8d\x66\x6f\x99" * 300,  # every kind of absolute code
        b"\xff" + b"\x00\x0f\xff\xfc\x3d\xff\xff\x22" * 300,
    ]
    for payload in cases8:
        total = full_count(ref.decode_8z, payload)
        for count in (1, 2, total // 3, total - 1, total, total + 1, total + 40):
            if count >= 1:
                check_8z(payload, count)


def test_garbage_decodes_or_fails_alike():
    rng = np.random.default_rng(2)
    for size in (0, 1, 2, 3, 4, 7, 50, 1000, 20_000):
        for _ in range(10):
            garbage = rng.integers(0, 256, size, np.uint8).tobytes()
            for count in (1, max(1, size // 2), size + 5):
                check_16z(garbage, count, False)
                check_16z(garbage, count, True)
                check_8z(garbage, count)


def test_tables_of_no_entries_and_indices_past_the_frame():
    check_16z(b"\x00\x00\x00\x00", 1, True)  # no table: even the first value is past it
    lut = b"\x03\x00" + np.array([5, 6, 7], "<u2").tobytes()
    # indices 1, 2, 3: the last is past the 3 entries, but only after a frame of 2 values
    np.testing.assert_array_equal(check_16z(lut + b"\x01\x00\x55", 2, True)[1], [6, 7])
    assert check_16z(lut + b"\x01\x00\x55", 3, True)[0] == "error"
    # 2, then 3 (past the table) repeated by a run, past the frame's end or within it
    assert check_16z(lut + b"\x02\x00\x66\x5d\xe5", 3, True)[0] == "ok"
    assert check_16z(lut + b"\x02\x00\x66\x5d\xe5", 4, True)[0] == "error"
    assert check_16z(lut + b"\x02\x00\x66\x6d\xe5\x5d", 14, True)[0] == "ok"
    # an escape's absolute value past the table, then back inside it: by 0xFF, and after a pair byte
    for escape in (b"\xff", b"\x6f"):
        body = escape + b"\x7f\xff\xff\x00\x01" + b"\x66" * 4
        for count in (2, 3, 4, 8):
            check_16z(lut + b"\x01\x00" + body, count, True)
        assert check_16z(lut + b"\x01\x00" + body, 8, True)[0] == "error"


def test_a_writable_payload_decodes_as_bytes_do():
    payload = ref.encode_16zt(frames()[0])
    with jit_on():
        np.testing.assert_array_equal(
            C.decode_16z(bytearray(payload), 2000, table=True), C.decode_16z(payload, 2000, table=True)
        )
        np.testing.assert_array_equal(C.decode_16z(memoryview(payload), 2000, table=True), frames()[0])


# -- recordings -----------------------------------------------------------------------------------


def read_both(path, kind):
    """Every frame of a stream decoded by both paths: (jit [N, ...], numpy [N, ...])."""
    decoded = []
    for setting in (None, "0"):
        with jit_setting(setting), warnings.catch_warnings(), OniFile(path) as oni:
            warnings.simplefilter("ignore", OniWarning)
            assert C.jit_available() == (setting is None)
            decoded.append(np.stack([f.data for f in oni.frames(oni.stream(kind))]))
    return decoded


@pytest.mark.parametrize("name", ["openni2_dummy_depth", "openni2_dummy_depth_color"])
def test_openni_recordings_decode_alike(name):
    require_jit()
    reference = np.load(DATA / "oni" / f"{name}.reference.npz")
    jit, numpy = read_both(DATA / "oni" / f"{name}.oni", "depth")
    np.testing.assert_array_equal(jit, numpy)
    np.testing.assert_array_equal(jit, reference["depth"])


@pytest.mark.parametrize("codecs", [("16zT", "Im8z"), ("16zP", "Im8z")])
def test_written_recordings_decode_alike(tmp_path, codecs):
    require_jit()
    rng = np.random.default_rng(3)
    depth = (2000 + np.cumsum(rng.integers(-4, 5, (3, 48, 64)), axis=2)).astype(np.uint16)
    depth[:, :, :4] = 0
    y, x = np.mgrid[0:48, 0:64]
    image = np.stack([np.stack([x * 4 + 8 * k, y * 5, (x + y) * 3 + 40 * k], -1) % 256 for k in range(3)])
    image = image.astype(np.uint8)
    path = tmp_path / "take.oni"
    write_oni(path, [StreamSpec("Depth", "depth", codecs[0], depth), StreamSpec("Image", "image", codecs[1], image)])
    for kind, expected in (("depth", depth), ("image", image)):
        jit, numpy = read_both(path, kind)
        np.testing.assert_array_equal(jit, numpy)
        np.testing.assert_array_equal(jit, expected)


# -- the switch -----------------------------------------------------------------------------------


def test_kinectdata_jit_0_switches_to_numpy(monkeypatch):
    require_jit()
    monkeypatch.setenv("KINECTDATA_JIT", "0")
    assert not C.jit_available() and C.jit_missing() == "switched off by KINECTDATA_JIT=0"
    payload = ref.encode_16zt(frames()[0])
    np.testing.assert_array_equal(C.decode_16z(payload, 2000, table=True), frames()[0])
    monkeypatch.delenv("KINECTDATA_JIT")
    assert C.jit_available() and C.jit_missing() is None


def test_without_numba_the_numpy_decoders_run(monkeypatch):
    """What a user without numba gets (simulated: the import is recorded as failed)."""
    monkeypatch.delenv("KINECTDATA_JIT", raising=False)
    monkeypatch.setattr(C, "_JIT", {"missing": "numba is not importable (No module named 'numba')"})
    assert not C.jit_available() and "No module named 'numba'" in C.jit_missing()
    payload = ref.encode_8z(frames()[1].astype(np.uint8))
    np.testing.assert_array_equal(C.decode_8z(payload, 2000), frames()[1].astype(np.uint8))
    with pytest.raises(CodecError, match="ends inside an escape"):
        C.decode_16z(b"\x00\x01\xff", 2, table=False)
