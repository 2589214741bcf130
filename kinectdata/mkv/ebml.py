"""EBML, the binary layout of Matroska files: elements, their sizes and values, and Matroska blocks.

An element is an ID (a variable-length integer that keeps its length marker: ``0x1A45DFA3`` is
the EBML header), a size (a variable-length integer without it; all value bits set means
"unknown") and that many bytes of payload: a number, a string, bytes, or more elements. Facts
from RFC 8794 (EBML) and RFC 9559 (Matroska), sections named where used; the element IDs used
by k4arecorder's files are in :data:`IDS`.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass

from kinectdata.core.errors import KinectDataError

IDS = {
    "EBML": 0x1A45DFA3,
    "DocType": 0x4282,
    "DocTypeVersion": 0x4287,
    "Segment": 0x18538067,
    "SeekHead": 0x114D9B74,
    "Info": 0x1549A966,
    "TimestampScale": 0x2AD7B1,
    "Duration": 0x4489,
    "Title": 0x7BA9,
    "MuxingApp": 0x4D80,
    "WritingApp": 0x5741,
    "DateUTC": 0x4461,
    "Tracks": 0x1654AE6B,
    "TrackEntry": 0xAE,
    "TrackNumber": 0xD7,
    "TrackUID": 0x73C5,
    "TrackType": 0x83,
    "Name": 0x536E,
    "CodecID": 0x86,
    "CodecPrivate": 0x63A2,
    "DefaultDuration": 0x23E383,
    "Video": 0xE0,
    "PixelWidth": 0xB0,
    "PixelHeight": 0xBA,
    "Attachments": 0x1941A469,
    "AttachedFile": 0x61A7,
    "FileName": 0x466E,
    "FileMediaType": 0x4660,
    "FileData": 0x465C,
    "FileUID": 0x46AE,
    "Tags": 0x1254C367,
    "Tag": 0x7373,
    "Targets": 0x63C0,
    "TargetType": 0x63CA,
    "TagTrackUID": 0x63C5,
    "TagAttachmentUID": 0x63C6,
    "SimpleTag": 0x67C8,
    "TagName": 0x45A3,
    "TagString": 0x4487,
    "Cluster": 0x1F43B675,
    "Timestamp": 0xE7,
    "SimpleBlock": 0xA3,
    "BlockGroup": 0xA0,
    "Block": 0xA1,
    "BlockDuration": 0x9B,
    "Cues": 0x1C53BB6B,
    "Chapters": 0x1043A770,
    "Void": 0xEC,
    "CRC-32": 0xBF,
}
NAMES = {value: name for name, value in IDS.items()}
TOP_LEVEL = {IDS[n] for n in ("SeekHead", "Info", "Tracks", "Attachments", "Tags", "Cluster", "Cues", "Chapters")}
"""The Segment's children (RFC 9559, 5.1): where a Cluster of unknown size ends, the next of these begins."""


class EbmlError(KinectDataError):
    """An EBML structure that cannot be read; the message names the byte position."""


def read_vint(data, pos: int, end: int, *, marker: bool) -> tuple[int, int]:
    """(value, length in bytes) of the variable-length integer at ``pos`` (RFC 8794, 4): its
    length is one more than the leading zero bits of its first byte (1-8). ``marker`` keeps the
    length marker bit (element IDs); sizes drop it, and a size whose value bits are all set is
    returned as -1 (unknown). Raises :class:`EbmlError` past ``end`` or on a first byte of 0."""
    if pos >= end:
        raise EbmlError(f"byte {pos}: the file ends inside an element header")
    first = data[pos]
    if first == 0:
        raise EbmlError(f"byte {pos}: 0x00 cannot start a variable-length integer")
    length = 9 - first.bit_length()
    if pos + length > end:
        raise EbmlError(f"byte {pos}: the file ends inside an element header")
    value = int.from_bytes(data[pos : pos + length], "big")
    if marker:
        return value, length
    value &= (1 << (7 * length)) - 1
    return (-1 if value == (1 << (7 * length)) - 1 else value), length


@dataclass(frozen=True)
class Element:
    """One element: ``id`` (with its marker), where its header starts, where its payload starts
    and how long the payload is (clipped to the file: ``missing`` bytes of it are not there)."""

    id: int
    start: int
    data: int
    size: int
    missing: int = 0

    @property
    def cut(self) -> bool:
        return self.missing > 0

    @property
    def end(self) -> int:
        return self.data + self.size

    @property
    def name(self) -> str:
        return NAMES.get(self.id, f"0x{self.id:X}")


def elements(data, start: int, end: int) -> Iterator[Element]:
    """The elements one after another from ``start`` to ``end`` (a parent's payload). An element
    of unknown size runs to the next top-level element (:data:`TOP_LEVEL`) or ``end``; one whose
    size runs past ``end`` is clipped there and marked ``cut``, and the walk stops after it."""
    pos = start
    while pos < end:
        ident, n = read_vint(data, pos, end, marker=True)
        size, m = read_vint(data, pos + n, end, marker=False)
        body = pos + n + m
        if size < 0:
            size = _unknown_size_end(data, ident, body, end) - body
        element = Element(ident, pos, body, min(size, end - body), max(0, body + size - end))
        yield element
        if element.cut:
            return
        pos = element.end


def _unknown_size_end(data, ident: int, pos: int, end: int) -> int:
    """Where an element of unknown size ends (RFC 8794, 6.2): a Segment at the next EBML header or
    Segment, a Cluster at the next of the Segment's children (:data:`TOP_LEVEL`), others at ``end``.
    Only the children's headers are read; a child of unknown size that is not where it stops runs
    to ``end`` (nothing recurses)."""
    if ident == IDS["Segment"]:
        stops = {IDS["EBML"], IDS["Segment"]}
    elif ident == IDS["Cluster"]:
        stops = TOP_LEVEL
    else:
        return end
    while pos < end:
        child, n = read_vint(data, pos, end, marker=True)
        if child in stops:
            return pos
        size, m = read_vint(data, pos + n, end, marker=False)
        if size < 0:
            return end
        pos += n + m + size
    return end


def children(data, parent: Element) -> dict[int, list[Element]]:
    """A master element's children by ID, in file order."""
    found: dict[int, list[Element]] = {}
    for child in elements(data, parent.data, parent.end):
        found.setdefault(child.id, []).append(child)
    return found


def first(data, kids: dict[int, list[Element]], name: str, read, default=None):
    """``read`` (:func:`uint`, :func:`text`...) of the first child named ``name`` among ``kids``
    (:func:`children`), or ``default`` when there is none."""
    found = kids.get(IDS[name])
    return read(data, found[0]) if found else default


def uint(data, e: Element) -> int:
    if e.size > 8:
        raise EbmlError(f"byte {e.start}: {e.name} is an unsigned integer of {e.size} bytes (at most 8)")
    return int.from_bytes(data[e.data : e.end], "big")


def sint(data, e: Element) -> int:
    if e.size > 8:
        raise EbmlError(f"byte {e.start}: {e.name} is a signed integer of {e.size} bytes (at most 8)")
    return int.from_bytes(data[e.data : e.end], "big", signed=True)


def floating(data, e: Element) -> float:
    if e.size == 0:
        return 0.0
    if e.size not in (4, 8):
        raise EbmlError(f"byte {e.start}: {e.name} is a float of {e.size} bytes (4 or 8)")
    return struct.unpack(">f" if e.size == 4 else ">d", data[e.data : e.end])[0]


def text(data, e: Element) -> str:
    """A string or UTF-8 element (a NUL byte ends it: what follows is padding, RFC 8794, 7.4)."""
    raw = bytes(data[e.data : e.end]).split(b"\0", 1)[0]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise EbmlError(f"byte {e.data + exc.start}: {e.name} is not UTF-8 text") from None


def payload(data, e: Element) -> bytes:
    return bytes(data[e.data : e.end])


@dataclass(frozen=True)
class Block:
    """A Matroska block's header and its frames (RFC 9559, 10: SimpleBlock and Block).

    Attributes:
        track: the track number. timecode: the time relative to its cluster's, in ticks.
        keyframe: the SimpleBlock's keyframe flag (False for a Block).
        frames: (offset, length) of each frame in the file (more than one when laced).
    """

    track: int
    timecode: int
    keyframe: bool
    frames: tuple[tuple[int, int], ...]


def parse_block(data, e: Element) -> Block:
    """The header and frames of a SimpleBlock or Block element (no lacing, Xiph, EBML or fixed-size
    lacing, RFC 9559, 10.3)."""
    track, n = read_vint(data, e.data, e.end, marker=False)
    pos = e.data + n
    if pos + 3 > e.end:
        raise EbmlError(f"byte {e.start}: a {e.name} of {e.size} bytes is shorter than its header")
    timecode = int.from_bytes(data[pos : pos + 2], "big", signed=True)
    flags = data[pos + 2]
    pos += 3
    lacing = (flags >> 1) & 3
    keyframe = e.id == IDS["SimpleBlock"] and bool(flags & 0x80)
    if lacing == 0:
        return Block(track, timecode, keyframe, ((pos, e.end - pos),))
    if pos >= e.end:
        raise EbmlError(f"byte {e.start}: a laced {e.name} without its frame count")
    count = data[pos] + 1
    pos += 1
    if count == 1:  # one frame: no sizes follow
        return Block(track, timecode, keyframe, ((pos, e.end - pos),))
    sizes: list[int] = []
    if lacing == 1:  # Xiph: each size but the last as a run of 255s and a last byte below 255
        for _ in range(count - 1):
            size = 0
            while True:
                if pos >= e.end:
                    raise EbmlError(f"byte {e.start}: a {e.name}'s Xiph lace sizes run past its end")
                size += data[pos]
                pos += 1
                if data[pos - 1] != 255:
                    break
            sizes.append(size)
    elif lacing == 3:  # EBML: the first size, then signed differences from the one before
        size, n = read_vint(data, pos, e.end, marker=False)
        pos += n
        sizes.append(size)
        for _ in range(count - 2):
            raw, n = read_vint(data, pos, e.end, marker=False)
            size += raw - ((1 << (7 * n - 1)) - 1)
            pos += n
            sizes.append(size)
    if lacing == 2:  # fixed: the rest split evenly
        rest = e.end - pos
        if rest % count:
            raise EbmlError(f"byte {e.start}: {rest} bytes do not split into {count} equal laced frames")
        sizes = [rest // count] * count
    else:
        sizes.append(e.end - pos - sum(sizes))
    if min(sizes) <= 0:
        raise EbmlError(f"byte {e.start}: a {e.name}'s lace sizes leave a frame of {min(sizes)} bytes")
    frames, at = [], pos
    for size in sizes:
        frames.append((at, size))
        at += size
    return Block(track, timecode, keyframe, tuple(frames))
