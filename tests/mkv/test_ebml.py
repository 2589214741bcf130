"""EBML's variable-length integers, unknown sizes and Matroska's lacing, on the specifications'
own examples (RFC 8794, 4; RFC 9559, 10.4)."""

from __future__ import annotations

import pytest

from kinectdata.mkv import ebml
from kinectdata.mkv.ebml import IDS, EbmlError, Element, parse_block


def test_variable_length_integers():
    assert ebml.read_vint(b"\x81", 0, 1, marker=False) == (1, 1)
    assert ebml.read_vint(b"\x40\x01", 0, 2, marker=False) == (1, 2)  # the same value, two bytes long
    assert ebml.read_vint(b"\x1a\x45\xdf\xa3", 0, 4, marker=True) == (0x1A45DFA3, 4)
    assert ebml.read_vint(b"\xff", 0, 1, marker=False) == (-1, 1)  # all value bits set: unknown
    assert ebml.read_vint(b"\x01\xff\xff\xff\xff\xff\xff\xff", 0, 8, marker=False) == (-1, 8)
    with pytest.raises(EbmlError, match="byte 0: 0x00"):
        ebml.read_vint(b"\x00\x01", 0, 2, marker=False)
    with pytest.raises(EbmlError, match="ends inside an element header"):
        ebml.read_vint(b"\x40", 0, 1, marker=False)


def _block(flags: int, body: bytes) -> tuple[bytes, Element]:
    raw = b"\x81\x00\x10" + bytes([flags]) + body  # track 1, time 16
    return raw, Element(IDS["SimpleBlock"], 0, 0, len(raw))


def test_the_three_lacings_split_frames_of_800_500_and_1000_bytes():
    frames = [b"a" * 800, b"b" * 500, b"c" * 1000]
    payload = b"".join(frames)
    xiph = bytes([2]) + b"\xff\xff\xff\x23" + b"\xff\xf5" + payload  # 800 = 3 x 255 + 35, 500 = 255 + 245
    ebml_laced = bytes([2]) + b"\x43\x20" + b"\x5e\xd3" + payload  # 800, then 500 - 800 = -300 (+ 8191)
    for flags, body in ((0x82, xiph), (0x86, ebml_laced)):
        raw, element = _block(flags, body)
        block = parse_block(raw, element)
        assert block.track == 1 and block.timecode == 16 and block.keyframe
        assert [raw[o : o + n] for o, n in block.frames] == frames
    raw, element = _block(0x04, bytes([2]) + b"x" * 1200)  # fixed: three of 400
    assert [n for _, n in parse_block(raw, element).frames] == [400, 400, 400]
    raw, element = _block(0x04, bytes([2]) + b"x" * 1201)
    with pytest.raises(EbmlError, match="do not split into 3 equal"):
        parse_block(raw, element)


def _element(ident: int, body: bytes, unknown: bool = False) -> bytes:
    size = b"\x01\xff\xff\xff\xff\xff\xff\xff" if unknown else bytes([0x80 | len(body)])
    return ident.to_bytes((ident.bit_length() + 7) // 8, "big") + size + body


def test_unknown_sizes_end_where_the_next_element_of_their_level_begins():
    timestamp = _element(IDS["Timestamp"], b"\x00")
    cluster = _element(IDS["Cluster"], timestamp + _element(IDS["SimpleBlock"], b"\x81\x00\x00\x80xy"), unknown=True)
    second = _element(IDS["Cluster"], timestamp, unknown=True)
    segment = _element(IDS["Segment"], _element(IDS["Info"], b"") + cluster + second, unknown=True)
    (top,) = ebml.elements(segment, 0, len(segment))
    assert top.id == IDS["Segment"] and top.end == len(segment)
    kids = list(ebml.elements(segment, top.data, top.end))
    assert [k.name for k in kids] == ["Info", "Cluster", "Cluster"]
    assert kids[1].end == kids[2].start and kids[2].end == len(segment)
    assert [c.name for c in ebml.elements(segment, kids[1].data, kids[1].end)] == ["Timestamp", "SimpleBlock"]


def test_a_laced_block_of_one_frame_has_no_sizes_and_a_frame_of_no_bytes_is_refused():
    raw, element = _block(0x86, bytes([0]) + b"x" * 16)  # EBML lacing, one frame: no sizes follow
    assert [n for _, n in parse_block(raw, element).frames] == [16]
    raw, element = _block(0x04, bytes([255]) + b"x" * 3)  # 256 frames in 3 bytes
    with pytest.raises(EbmlError):
        parse_block(raw, element)


def test_thousands_of_clusters_of_unknown_size_are_walked_without_recursion():
    timestamp = _element(IDS["Timestamp"], b"\x00")
    clusters = _element(IDS["Cluster"], timestamp, unknown=True) * 3000
    segment = _element(IDS["Segment"], clusters, unknown=True)
    (top,) = ebml.elements(segment, 0, len(segment))
    kids = list(ebml.elements(segment, top.data, top.end))
    assert len(kids) == 3000 and all(k.size == len(timestamp) for k in kids)
