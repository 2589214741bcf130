"""The ``.oni`` container: file header, records and their fields (see ``docs/oni.md``).

Everything is packed little-endian. A record is ``NIR\\0``, type, node id, fields size, payload
size and an "undo" position; positions are u64, or u32 in the "old32" layout of files older
than version 1.0.1.0 (record header 24 bytes instead of 28). Nothing here decodes frames.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

from kinectdata.core.errors import KinectDataError

MAGIC = b"NI10"
RECORD_MAGIC = 0x0052494E
HEADER_SIZE = 24

NODE_ADDED_1_0_0_4 = 0x02
INT_PROPERTY = 0x03
REAL_PROPERTY = 0x04
STRING_PROPERTY = 0x05
GENERAL_PROPERTY = 0x06
NODE_REMOVED = 0x07
NODE_DATA_BEGIN = 0x08
NODE_STATE_READY = 0x09
NEW_DATA = 0x0A
END = 0x0B
NODE_ADDED_1_0_0_5 = 0x0C
NODE_ADDED = 0x0D
SEEK_TABLE = 0x0E
NODE_ADDED_TYPES = (NODE_ADDED_1_0_0_4, NODE_ADDED_1_0_0_5, NODE_ADDED)
PROPERTY_TYPES = (INT_PROPERTY, REAL_PROPERTY, STRING_PROPERTY, GENERAL_PROPERTY)
RECORD_NAMES = {
    NODE_ADDED_1_0_0_4: "NODE_ADDED (1.0.0.4)",
    INT_PROPERTY: "INT_PROPERTY",
    REAL_PROPERTY: "REAL_PROPERTY",
    STRING_PROPERTY: "STRING_PROPERTY",
    GENERAL_PROPERTY: "GENERAL_PROPERTY",
    NODE_REMOVED: "NODE_REMOVED",
    NODE_DATA_BEGIN: "NODE_DATA_BEGIN",
    NODE_STATE_READY: "NODE_STATE_READY",
    NEW_DATA: "NEW_DATA",
    END: "END",
    NODE_ADDED_1_0_0_5: "NODE_ADDED (1.0.0.5)",
    NODE_ADDED: "NODE_ADDED",
    SEEK_TABLE: "SEEK_TABLE",
}
NODE_TYPES = {1: "device", 2: "depth", 3: "image", 4: "audio", 5: "ir"}


class OniError(KinectDataError):
    """An ``.oni`` file that cannot be read; the message names the file and the byte position."""


@dataclass(frozen=True)
class FileHeader:
    """The 24-byte file header."""

    version: tuple[int, int, int, int]
    max_timestamp: int
    max_node_id: int

    @property
    def old32(self) -> bool:
        """Positions are u32 (files written before version 1.0.1.0)."""
        return self.version < (1, 0, 1, 0)


def parse_file_header(data: bytes, source: str) -> FileHeader:
    if len(data) < HEADER_SIZE:
        raise OniError(f"{source}: {len(data)} bytes, too short for the 24-byte .oni file header")
    if data[:4] != MAGIC:
        raise OniError(f"{source}: not an .oni file (starts with {data[:4]!r}, not {MAGIC!r})")
    major, minor, maintenance, build, max_ts, max_node = struct.unpack_from("<BBHIQI", data, 4)
    version = (major, minor, maintenance, build)
    if not (1, 0, 0, 4) <= version < (1, 1, 0, 0):
        raise OniError(f"{source}: .oni format version {'.'.join(map(str, version))} is not one kinectdata reads")
    return FileHeader(version, max_ts, max_node)


@dataclass(frozen=True)
class Record:
    """One record: where it is and what its header says. ``fields`` are the bytes after the
    record header up to the payload."""

    position: int
    type: int
    node: int
    fields: bytes
    payload_position: int
    payload_size: int
    undo: int

    @property
    def end(self) -> int:
        return self.payload_position + self.payload_size

    @property
    def name(self) -> str:
        return RECORD_NAMES.get(self.type, f"record type 0x{self.type:02X}")


class RecordLayout:
    """Reads records in the current (u64 positions) or old32 layout."""

    def __init__(self, old32: bool):
        self.old32 = old32
        self.header = struct.Struct("<IIIIII" if old32 else "<IIIIIQ")
        self.position = struct.Struct("<I" if old32 else "<Q")
        self.seek_entry = struct.Struct("<QII" if old32 else "<QIQ")

    @property
    def header_size(self) -> int:
        return self.header.size

    def read(self, data, position: int, source: str) -> Record:
        """The record at ``position`` of ``data`` (bytes or mmap).

        Raises:
            OniError: cut off by the end of the file, or not a record (bad magic or sizes).
        """
        size = len(data)
        if position + self.header.size > size:
            raise OniError(f"{source}: byte {position}: the file ends inside a record header")
        magic, rtype, node, fields_size, payload_size, undo = self.header.unpack_from(data, position)
        if magic != RECORD_MAGIC:
            raise OniError(f"{source}: byte {position}: no record here (magic 0x{magic:08X}, not 0x{RECORD_MAGIC:08X})")
        if fields_size < self.header.size:
            raise OniError(f"{source}: byte {position}: record fields size {fields_size} is below the header size")
        payload_position = position + fields_size
        if payload_position + payload_size > size:
            raise OniError(
                f"{source}: byte {position}: the file ends inside a {RECORD_NAMES.get(rtype, hex(rtype))} record "
                f"({payload_position + payload_size - size} bytes missing)"
            )
        fields = bytes(data[position + self.header.size : payload_position])
        return Record(position, rtype, node, fields, payload_position, payload_size, undo)


class FieldReader:
    """Reads a record's fields in order; errors name the record."""

    def __init__(self, record: Record, source: str):
        self.data, self.offset, self.record, self.source = record.fields, 0, record, source

    def _take(self, fmt: str) -> Any:
        size = struct.calcsize(fmt)
        if self.offset + size > len(self.data):
            raise OniError(
                f"{self.source}: byte {self.record.position}: {self.record.name} record of node "
                f"{self.record.node} is shorter than its fields"
            )
        value = struct.unpack_from(fmt, self.data, self.offset)
        self.offset += size
        return value[0] if len(value) == 1 else value

    def u32(self) -> int:
        return self._take("<I")

    def u64(self) -> int:
        return self._take("<Q")

    def i64(self) -> int:
        return self._take("<q")

    def f64(self) -> float:
        return self._take("<d")

    def position(self, layout: RecordLayout) -> int:
        return self._take("<I" if layout.old32 else "<Q")

    def raw(self, size: int) -> bytes:
        if self.offset + size > len(self.data):
            raise OniError(
                f"{self.source}: byte {self.record.position}: {self.record.name} record of node "
                f"{self.record.node} is shorter than its fields"
            )
        out = self.data[self.offset : self.offset + size]
        self.offset += size
        return out

    def string(self) -> str:
        """A u32 length (counting the trailing NUL), then the characters."""
        return self.raw(self.u32()).split(b"\0", 1)[0].decode("latin-1")

    @property
    def remaining(self) -> int:
        return len(self.data) - self.offset


@dataclass(frozen=True)
class NodeAdded:
    name: str
    node_type: int
    codec: int
    frames: int | None
    min_timestamp: int | None
    max_timestamp: int | None
    seek_table_position: int | None


def parse_node_added(record: Record, layout: RecordLayout, source: str) -> NodeAdded:
    f = FieldReader(record, source)
    name, node_type, codec = f.string(), f.u32(), f.u32()
    frames = min_ts = max_ts = seek = None
    if record.type in (NODE_ADDED_1_0_0_5, NODE_ADDED):
        frames, min_ts, max_ts = f.u32(), f.u64(), f.u64()
    if record.type == NODE_ADDED:
        seek = f.position(layout)
    return NodeAdded(name, node_type, codec, frames, min_ts, max_ts, seek)


def parse_property(record: Record, source: str) -> tuple[str, Any]:
    """(name, value): int, float, str, or bytes for a general property."""
    f = FieldReader(record, source)
    name = f.string()
    if record.type == INT_PROPERTY:
        f.u32()
        return name, f.i64()
    if record.type == REAL_PROPERTY:
        f.u32()
        return name, f.f64()
    if record.type == STRING_PROPERTY:
        return name, f.raw(f.u32()).split(b"\0", 1)[0].decode("latin-1")
    return name, f.raw(f.u32())


def parse_new_data(record: Record, source: str) -> tuple[int, int]:
    """(timestamp in microseconds, frame number)."""
    f = FieldReader(record, source)
    return f.u64(), f.u32()


def parse_data_begin(record: Record, source: str) -> tuple[int, int]:
    """(frame count, largest timestamp) of a NODE_DATA_BEGIN record."""
    f = FieldReader(record, source)
    return f.u32(), f.u64()


def parse_seek_table(data, record: Record, layout: RecordLayout, source: str) -> list[tuple[int, int, int]]:
    """Entries (timestamp us, configuration id, record position); entry 0 is a placeholder."""
    size = layout.seek_entry.size
    if record.payload_size % size:
        raise OniError(
            f"{source}: byte {record.position}: seek table of node {record.node} is {record.payload_size} bytes, "
            f"not a multiple of {size}"
        )
    payload = bytes(data[record.payload_position : record.end])
    return [layout.seek_entry.unpack_from(payload, i) for i in range(0, len(payload), size)]
