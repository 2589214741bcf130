"""Reading ``.oni`` recordings (OpenNI 1.x and OpenNI2) without OpenNI.

>>> with OniFile("take.oni") as oni:
...     depth = oni.stream("depth")
...     frame = oni.read_frame(depth, 0)       # frame.data: uint16 [H, W] depth
...     for frame in oni.frames(depth, start=10, stop=20): ...

Opening reads the records at the start of the file (streams and their properties) and each
stream's seek table, which gives every frame's position, so any frame is one read away. When a
seek table is missing or damaged (a recording cut short by a crash or a full disk has none), the
records are walked instead: every frame before the cut is found, and :attr:`OniFile.problems`
says where and why the walk stopped. Frames are decoded on demand (:mod:`.codecs`).
"""

from __future__ import annotations

import math
import mmap
import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataWarning
from kinectdata.core.jpeg import decode_jpeg
from kinectdata.oni.codecs import CodecError, decode_8z, decode_16z, decode_raw, fourcc
from kinectdata.oni.records import OniError

from . import records as R

# OpenNI2's oniPixelFormat and OpenNI 1.x's xnPixelFormat values
ONI_PIXEL_FORMATS = {
    100: "DEPTH_1_MM",
    101: "DEPTH_100_UM",
    102: "SHIFT_9_2",
    103: "SHIFT_9_3",
    200: "RGB888",
    201: "YUV422",
    202: "GRAY8",
    203: "GRAY16",
    204: "JPEG",
    205: "YUYV",
}
XN_PIXEL_FORMATS = {1: "RGB888", 2: "YUV422", 3: "GRAY8", 4: "GRAY16", 5: "JPEG"}
# per pixel format: (dtype, channels)
_LAYOUTS = {
    "DEPTH_1_MM": (np.uint16, 1),
    "DEPTH_100_UM": (np.uint16, 1),
    "SHIFT_9_2": (np.uint16, 1),
    "SHIFT_9_3": (np.uint16, 1),
    "GRAY16": (np.uint16, 1),
    "GRAY8": (np.uint8, 1),
    "RGB888": (np.uint8, 3),
    "YUV422": (np.uint8, 2),
    "YUYV": (np.uint8, 2),
    "JPEG": (np.uint8, 3),
}


MAX_FRAME_VALUES = 1 << 28  # 268 M values: far beyond any sensor, so a damaged size is refused


class OniWarning(KinectDataWarning):
    """A recording was read only in part (cut short or damaged); the message says where."""


@dataclass
class OniStream:
    """One stream (OpenNI "node") of a recording and the index of its frames.

    Attributes:
        node_id: the node's id in the file.
        name: the node's name (OpenNI2: ``Depth``, ``Image``, ``IR``).
        kind: ``depth``, ``image``, ``ir``, ``audio``, ``device`` or ``type N``.
        codec: the FourCC of its frames (``16zT``, ``NONE``...).
        properties: the node's properties as recorded (int, float, str, or bytes).
        frame_numbers: [N] uint32, 1-based per stream; gaps are dropped frames.
        timestamps_us: [N] uint64 microseconds.
        positions: [N] int64 byte offsets of the frames' records.
    """

    node_id: int
    name: str
    kind: str
    codec: str
    properties: dict[str, Any] = field(default_factory=dict)
    frame_numbers: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint32))
    timestamps_us: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint64))
    positions: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    recorded_frames: int | None = None  # what the NODE_ADDED record says

    @property
    def n_frames(self) -> int:
        return int(self.positions.size)

    @property
    def map_output_mode(self) -> tuple[int, int, int] | None:
        """(x resolution, y resolution, fps) from ``xnMapOutputMode``."""
        raw = self.properties.get("xnMapOutputMode")
        if isinstance(raw, bytes) and len(raw) >= 12:
            return tuple(int(v) for v in np.frombuffer(raw[:12], "<u4"))
        return None

    @property
    def cropping(self) -> tuple[int, int, int, int] | None:
        """(x offset, y offset, width, height) when ``xnCropping`` is enabled."""
        raw = self.properties.get("xnCropping")
        if isinstance(raw, bytes) and len(raw) >= 12:
            enabled = int.from_bytes(raw[:4], "little")
            x, y, w, h = (int(v) for v in np.frombuffer(raw[4:12], "<u2"))
            if enabled and w and h:
                return x, y, w, h
        return None

    @property
    def resolution(self) -> tuple[int, int] | None:
        """(width, height) of the frames in pixels."""
        crop = self.cropping
        if crop is not None:
            return crop[2], crop[3]
        mode = self.map_output_mode
        return None if mode is None else (mode[0], mode[1])

    @property
    def fps(self) -> float | None:
        """Nominal frames per second (``xnMapOutputMode``)."""
        mode = self.map_output_mode
        return None if mode is None or not mode[2] else float(mode[2])

    @property
    def pixel_format(self) -> str:
        if "oniPixelFormat" in self.properties:
            value = int(self.properties["oniPixelFormat"])
            return ONI_PIXEL_FORMATS.get(value, f"oniPixelFormat {value}")
        if "xnPixelFormat" in self.properties and self.kind != "depth":
            value = int(self.properties["xnPixelFormat"])
            return XN_PIXEL_FORMATS.get(value, f"xnPixelFormat {value}")
        return "DEPTH_1_MM" if self.kind == "depth" else "GRAY16" if self.kind == "ir" else "RGB888"

    @property
    def field_of_view(self) -> tuple[float, float] | None:
        """(horizontal, vertical) field of view in radians (``xnFOV``)."""
        raw = self.properties.get("xnFOV")
        if isinstance(raw, bytes) and len(raw) >= 16:
            return tuple(float(v) for v in np.frombuffer(raw[:16], "<f8"))
        return None

    @property
    def frame_layout(self) -> tuple[tuple[int, ...], np.dtype]:
        """Shape and dtype of a decoded frame: depth uint16 [H, W], RGB uint8 [H, W, 3]...

        Raises:
            OniError: the stream's properties give no resolution.
        """
        res = self.resolution
        if res is None:
            raise OniError(f"stream {self.name!r} has no resolution (no xnMapOutputMode property)")
        dtype, channels = _LAYOUTS.get(self.pixel_format, (np.uint16 if self.kind == "depth" else np.uint8, 1))
        if self.kind == "depth":
            dtype, channels = np.uint16, 1
        shape = (res[1], res[0]) if channels == 1 else (res[1], res[0], channels)
        return shape, np.dtype(dtype)

    @property
    def duration_s(self) -> float:
        """Seconds from the first frame's timestamp to the last's."""
        if self.n_frames < 2:
            return 0.0
        return float(self.timestamps_us[-1] - self.timestamps_us[0]) / 1e6

    @property
    def measured_fps(self) -> float | None:
        return (self.n_frames - 1) / self.duration_s if self.duration_s > 0 else None

    @property
    def dropped_frames(self) -> int:
        """Frames missing between the first and the last recorded one: from gaps in the frame
        numbers, or, where the numbers run on (OpenNI's recorders number the frames they receive),
        from timestamp intervals of about k nominal periods (k - 1 frames missing)."""
        if self.n_frames < 2:
            return 0
        by_number = np.clip(np.diff(self.frame_numbers.astype(np.int64)) - 1, 0, None)
        by_time = np.zeros_like(by_number)
        if self.fps:
            periods = np.diff(self.timestamps_us.astype(np.float64)) * self.fps / 1e6
            by_time = np.where(periods > 1.5, np.round(periods) - 1, 0).astype(np.int64)
        return int(np.maximum(by_number, by_time).sum())

    def gaps(self, factor: float = 1.5) -> list[tuple[int, float]]:
        """(frame number after the gap, gap in seconds) where consecutive timestamps are more than
        ``factor`` nominal periods apart."""
        if self.n_frames < 2 or not self.fps:
            return []
        dt = np.diff(self.timestamps_us.astype(np.float64)) / 1e6
        where = np.flatnonzero(dt > factor / self.fps)
        return [(int(self.frame_numbers[i + 1]), float(dt[i])) for i in where]


@dataclass(frozen=True)
class OniFrame:
    """A decoded frame: ``number`` (1-based), ``timestamp_us``, ``data`` (see
    :attr:`OniStream.frame_layout`)."""

    number: int
    timestamp_us: int
    data: np.ndarray


class OniFile:
    """An ``.oni`` recording opened for reading; use as a context manager or call :meth:`close`.

    Attributes:
        path: the file.
        header: version, largest timestamp and node id from the file header.
        streams: the streams, in the order their nodes were added.
        index_source: ``seek table`` or ``scan`` (how the frames were found).
        truncated: the file ends before its END record (frames up to the cut are readable).
        problems: what could not be read, each naming the byte position; also issued as an
            :class:`OniWarning` when the file is opened.
    """

    def __init__(self, path: str | os.PathLike[str]):
        self.path = Path(path)
        self.source = str(self.path)
        try:
            self._file = open(self.path, "rb")
        except FileNotFoundError:
            raise OniError(f"{self.source}: no such file") from None
        except OSError as exc:
            raise OniError(f"{self.source}: cannot open ({exc.strerror or exc})") from exc
        try:
            size = os.fstat(self._file.fileno()).st_size
            self._data = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
            self.size = size
            self.header = R.parse_file_header(bytes(self._data[: R.HEADER_SIZE]), self.source)
            self.layout = R.RecordLayout(self.header.old32)
            self.problems: list[str] = []
            self.truncated = False
            self.index_source = "scan"
            self.streams: list[OniStream] = []
            self._read_structure()
        except BaseException:
            self.close()
            raise
        for problem in self.problems:
            warnings.warn(problem, OniWarning, stacklevel=2)

    # -- structure ------------------------------------------------------------------------------

    def _read_structure(self) -> None:
        by_node: dict[int, OniStream] = {}
        seek_positions: dict[int, int | None] = {}
        position = R.HEADER_SIZE
        first_data = None
        while position < self.size:
            try:
                rec = self.layout.read(self._data, position, self.source)
                if rec.type in (R.NEW_DATA, R.END, R.NODE_REMOVED, R.SEEK_TABLE):
                    first_data = position
                    break
                self._header_record(rec, by_node, seek_positions)
            except OniError as exc:
                self._stop(str(exc))
                break
            position = rec.end
        if first_data is None:
            if not self.problems:
                self._stop(f"{self.source}: byte {position}: the file ends before any frame or END record")
            return
        # a node added after the data began (OpenNI 1.x allows it) has an id above those seen so far
        added_later = self.header.max_node_id > max(by_node, default=0)
        if not added_later and self._index_from_seek_tables(by_node, seek_positions):
            self.index_source = "seek table"
            return
        self._scan(first_data, by_node)

    def _header_record(self, rec: R.Record, by_node: dict[int, OniStream], seek_positions: dict) -> bool:
        """Take in a NODE_ADDED, property or NODE_DATA_BEGIN record; False for any other."""
        if rec.type in R.NODE_ADDED_TYPES:
            added = R.parse_node_added(rec, self.layout, self.source)
            kind = R.NODE_TYPES.get(added.node_type, f"type {added.node_type}")
            stream = OniStream(rec.node, added.name, kind, fourcc(added.codec), recorded_frames=added.frames)
            by_node[rec.node] = stream
            self.streams.append(stream)
            seek_positions[rec.node] = added.seek_table_position
        elif rec.type in R.PROPERTY_TYPES and rec.node in by_node:
            name, value = R.parse_property(rec, self.source)
            by_node[rec.node].properties[name] = value
        elif rec.type == R.NODE_DATA_BEGIN and rec.node in by_node:
            frames, _ = R.parse_data_begin(rec, self.source)
            if by_node[rec.node].recorded_frames is None and frames:  # 1.0.0.4 files count here
                by_node[rec.node].recorded_frames = frames
        else:
            return False
        return True

    def _stop(self, why: str) -> None:
        self.truncated = True
        self.problems.append(why)

    def _index_from_seek_tables(self, by_node: dict[int, OniStream], seek_positions: dict[int, int | None]) -> bool:
        """Fill the frame index from every data stream's seek table; False (nothing changed) if
        any table is missing, damaged or disagrees with the records it points at."""
        index = {}
        try:
            for node, stream in by_node.items():
                seek = seek_positions.get(node)
                if stream.kind == "device" and not stream.recorded_frames:
                    continue
                if not seek or seek >= self.size:
                    return False
                rec = self.layout.read(self._data, seek, self.source)
                if rec.type != R.SEEK_TABLE or rec.node != node:
                    return False
                entries = R.parse_seek_table(self._data, rec, self.layout, self.source)[1:]
                entries = [e for e in entries if e[2]]  # holes (frame numbers never recorded) have no position
                if stream.recorded_frames is not None and len(entries) != stream.recorded_frames:
                    return False
                if len({e[1] for e in entries}) > 1:
                    return False  # properties change mid-stream: walk the records
                numbers = []
                for stamp, _, pos in entries:  # each frame's record must be there and agree
                    rec = self.layout.read(self._data, pos, self.source)
                    if rec.type != R.NEW_DATA or rec.node != node:
                        return False
                    timestamp, number = R.parse_new_data(rec, self.source)
                    if timestamp != stamp:
                        return False
                    numbers.append(number)
                index[node] = (numbers, [e[0] for e in entries], [e[2] for e in entries])
        except OniError:
            return False
        for node, (numbers, stamps, positions) in index.items():
            by_node[node].frame_numbers = np.array(numbers, np.uint32)
            by_node[node].timestamps_us = np.array(stamps, np.uint64)
            by_node[node].positions = np.array(positions, np.int64)
        return True

    def _scan(self, position: int, by_node: dict[int, OniStream]) -> None:
        """Walk the records from ``position`` to END (or to where the file stops making sense)."""
        index: dict[int, list[tuple[int, int, int]]] = {node: [] for node in by_node}
        ended = False
        while position < self.size:
            try:
                rec = self.layout.read(self._data, position, self.source)
                if rec.type == R.NEW_DATA and rec.node in index:
                    timestamp, number = R.parse_new_data(rec, self.source)
                    index[rec.node].append((number, timestamp, position))
                elif rec.type in R.NODE_ADDED_TYPES:  # a stream added while recording
                    self._header_record(rec, by_node, {})
                    index.setdefault(rec.node, [])
                elif rec.type in R.PROPERTY_TYPES and rec.node in by_node:
                    name, value = R.parse_property(rec, self.source)
                    stream = by_node[rec.node]
                    if index[rec.node] and stream.properties.get(name, value) != value and name in _GEOMETRY:
                        self._stop(
                            f"{self.source}: byte {position}: stream {stream.name!r} changes {name} after "
                            f"{len(index[rec.node])} frames; frames from there on are not read"
                        )
                        break
                    stream.properties[name] = value
                elif rec.type == R.END:
                    ended = True
                    break
            except OniError as exc:
                self._stop(f"{exc}; frames before it are read")
                break
            position = rec.end
        else:
            self._stop(f"{self.source}: byte {position}: the file ends without an END record (cut short)")
        if not ended and not self.truncated:
            self._stop(f"{self.source}: byte {position}: no END record")
        for node, frames in index.items():
            stream = by_node[node]
            if frames:
                numbers, stamps, positions = zip(*frames)
                stream.frame_numbers = np.array(numbers, np.uint32)
                stream.timestamps_us = np.array(stamps, np.uint64)
                stream.positions = np.array(positions, np.int64)

    # -- access ---------------------------------------------------------------------------------

    def stream(self, which: str | int) -> OniStream:
        """A stream by kind (``depth``, ``image``, ``ir``), name or node id."""
        for s in self.streams:
            if which in (s.kind, s.name, s.node_id) or (isinstance(which, str) and which.lower() == s.name.lower()):
                return s
        names = ", ".join(f"{s.kind} ({s.name!r}, node {s.node_id})" for s in self.streams) or "none"
        raise OniError(f"{self.source}: no stream {which!r}; streams: {names}")

    def read_frame(self, stream: OniStream, index: int) -> OniFrame:
        """Decode frame ``index`` (0-based position in the stream, not the frame number)."""
        if not 0 <= index < stream.n_frames:
            raise OniError(
                f"{self.source}: stream {stream.name!r} has {stream.n_frames} frames, no frame index {index}"
            )
        position = int(stream.positions[index])
        rec = self.layout.read(self._data, position, self.source)
        number = int(stream.frame_numbers[index])
        what = f"{self.source}: {stream.name} frame {number} (record at byte {position})"
        if rec.type != R.NEW_DATA or rec.node != stream.node_id:
            raise OniError(f"{what}: the record there is {rec.name} of node {rec.node}")
        timestamp, _ = R.parse_new_data(rec, self.source)
        # a view of the mapped file, not a copy (0.13 ms of a 640x480 Im8z frame): every decoder
        # returns a new array, so nothing holds the view once the frame is decoded
        payload = memoryview(self._data)[rec.payload_position : rec.end]
        try:
            data = decode_frame(stream, payload, what)
        except CodecError as exc:
            raise OniError(str(exc)) from exc
        finally:
            del payload
        return OniFrame(number, timestamp, data)

    def frames(self, stream: OniStream, start: int = 0, stop: int | None = None) -> Iterator[OniFrame]:
        """Decoded frames ``start`` .. ``stop - 1`` (0-based positions) of a stream, in order."""
        stop = stream.n_frames if stop is None else min(stop, stream.n_frames)
        for i in range(max(start, 0), stop):
            yield self.read_frame(stream, i)

    def close(self) -> None:
        data = getattr(self, "_data", None)
        if isinstance(data, mmap.mmap):
            try:
                data.close()
            except BufferError:  # a payload view kept by an exception's traceback: unmapped once freed
                pass
        if getattr(self, "_file", None) is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> OniFile:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"OniFile({self.source!r}, streams={[s.name for s in self.streams]})"


_GEOMETRY = ("xnMapOutputMode", "xnCropping", "oniPixelFormat", "xnPixelFormat")


def decode_frame(stream: OniStream, payload, what: str) -> np.ndarray:
    """A frame's payload decoded by the stream's codec into :attr:`OniStream.frame_layout`."""
    try:
        shape, dtype = stream.frame_layout
    except OniError as exc:
        raise CodecError(f"{what}: {exc}") from None
    count = math.prod(int(d) for d in shape)
    if not 0 < count <= MAX_FRAME_VALUES:
        raise CodecError(f"{what}: a {shape[1]}x{shape[0]} frame is not plausible (damaged xnMapOutputMode?)")
    codec = stream.codec
    if codec == "16zT" or codec == "16zP":
        values = decode_16z(payload, count, table=codec == "16zT", what=what)
    elif codec == "Im8z":
        if dtype != np.uint8:
            raise CodecError(f"{what}: Im8z frames must be 8-bit, but the stream's pixels are {dtype}")
        values = decode_8z(payload, count, what=what)
    elif codec == "NONE":
        values = decode_raw(payload, dtype, count, what=what)
    elif codec == "JPEG":
        return decode_jpeg(bytes(payload), (shape[1], shape[0]), what, CodecError, rgb=False)
    else:
        raise CodecError(f"{what}: codec {codec!r} is not one kinectdata decodes (16zT, 16zP, Im8z, JPEG, NONE)")
    return values.reshape(shape)
