"""Straightforward Python versions of what OpenNI does to ``.oni`` files, for checking kinectdata.

- ``encode_16z`` / ``encode_16zt`` / ``encode_8z``: OpenNI's compressors (``XnStreamCompressDepth16Z``,
  ``...WithEmbTable``, ``XnStreamCompressImage8Z``), a loop over the values, as OpenNI writes them;
- ``decode_16z`` / ``decode_8z``: OpenNI's decompressors, a loop over the bytes, as OpenNI reads
  them (kinectdata's vectorised decoders are checked against these on any byte string);
- ``write_oni``: a recording writer producing the records OpenNI's recorders write, in the
  current or the old32 layout, optionally cut short, for tests of what OpenNI cannot easily be
  made to write.

Slow by design (a loop per byte or value); for tests and benchmark set-up only.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

# -- codecs -------------------------------------------------------------------------------------


def encode_16z_values(values) -> bytes:
    vals = [int(v) for v in values]
    out = bytearray(vals[0].to_bytes(2, "little"))
    last, stage, ch, zeros = vals[0], 0, 0, 0
    for cur in vals[1:]:
        diff = ((last - cur + 32768) % 65536) - 32768  # XnInt16 of a uint16 difference
        if abs(diff) <= 6:
            d = diff + 6
            if stage == 0:
                ch, stage = (d << 4) & 0xFF, 1
            else:
                ch, stage = (ch + d) & 0xFF, 0
                if ch == 0x66:
                    zeros += 1
                    if zeros == 15:
                        out.append(0xEF)
                        zeros = 0
                else:
                    if zeros:
                        out.append(0xE0 + zeros)
                        zeros = 0
                    out.append(ch)
        else:
            if zeros:
                out.append(0xE0 + zeros)
                zeros = 0
            if stage == 0:
                out.append(0xFF)
            else:
                out.append((ch + 0x0F) & 0xFF)
                stage = 0
            if abs(diff) <= 63:
                out.append((diff + 192) & 0xFF)
            else:
                out += bytes([(cur >> 8) & 0xFF, cur & 0xFF])
        last = cur
    if stage:
        out.append((ch + 0x0D) & 0xFF)
    if zeros:
        out.append(0xE0 + zeros)
    return bytes(out)


def encode_16z(depth: np.ndarray) -> bytes:
    """16zP: the values themselves (valid below 32768, as with OpenNI)."""
    return encode_16z_values(np.asarray(depth).ravel())


def encode_16zt(depth: np.ndarray) -> bytes:
    """16zT: a table of the values present, then the 16z stream of indices into it."""
    flat = np.asarray(depth).ravel()
    table = np.unique(flat)
    head = len(table).to_bytes(2, "little") + table.astype("<u2").tobytes()
    return head + encode_16z_values(np.searchsorted(table, flat))


def encode_8z(data: np.ndarray) -> bytes:
    """Im8z, as XnStreamCompressImage8Z (including its quirk of never starting a run right after
    an absolute value)."""
    vals = [int(v) for v in np.asarray(data, np.uint8).ravel()]
    out = bytearray([vals[0]])
    last, stage, ch, zeros, flag = vals[0], 0, 0, 0, False
    for cur in vals[1:]:
        diff = ((last - cur + 128) % 256) - 128
        if abs(diff) <= 6:
            d = diff + 6
            if stage == 0:
                ch, stage = (d << 4) & 0xFF, 1
            else:
                ch, stage = (ch + d) & 0xFF, 0
                if ch == 0x66 and not flag:
                    zeros += 1
                    if zeros == 15:
                        out.append(0xEF)
                        zeros = 0
                else:
                    if zeros:
                        out.append(0xE0 + zeros)
                        zeros = 0
                    out.append(ch)
                    flag = False
        else:
            if zeros:
                out.append(0xE0 + zeros)
                zeros = 0
            if stage == 0:
                out.append(0xF0 + (cur >> 4))
                ch, stage, flag = (cur & 0x0F) << 4, 1, True
            else:
                out.append((ch + 0x0F) & 0xFF)
                out.append(cur)
                stage = 0
        last = cur
    if stage:
        out.append((ch + 0x0D) & 0xFF)
    if zeros:
        out.append(0xE0 + zeros)
    return bytes(out)


def decode_16z(payload: bytes, count: int, table: bool) -> np.ndarray:
    """XnStreamUncompressDepth16Z(WithEmbTable), byte by byte. IndexError where the payload ends
    inside a code."""
    b, p, lut = payload, 0, None
    if table:
        n = b[0] | b[1] << 8
        lut = [b[2 + 2 * i] | b[3 + 2 * i] << 8 for i in range(n)]
        p = 2 + 2 * n
    v = b[p] | b[p + 1] << 8
    p += 2
    out = [v]

    def escape(p, v):
        e = b[p]
        if e & 0x80:
            return p + 1, (v - (e - 192)) & 0xFFFF
        return p + 2, ((e << 8) + b[p + 1]) & 0xFFFF

    while p != len(b):
        c = b[p]
        if c < 0xE0:
            v = (v - ((c >> 4) - 6)) & 0xFFFF
            out.append(v)
            lo = c & 0x0F
            if lo == 0x0F:
                p, v = escape(p + 1, v)
                out.append(v)
            else:
                if lo != 0x0D:
                    v = (v - (lo - 6)) & 0xFFFF
                    out.append(v)
                p += 1
        elif c == 0xFF:
            p, v = escape(p + 1, v)
            out.append(v)
        else:
            out += [v] * (2 * (c - 0xE0))
            p += 1
    out = out[:count]
    return np.array([lut[i] for i in out] if lut is not None else out, np.uint16)


def decode_8z(payload: bytes, count: int) -> np.ndarray:
    """XnStreamUncompressImage8Z, byte by byte."""
    b = payload
    v, p = b[0], 1
    out = [v]
    while p != len(b):
        c = b[p]
        if c < 0xE0:
            v = (v - ((c >> 4) - 6)) & 0xFF
            out.append(v)
            lo = c & 0x0F
            if lo == 0x0F:
                p += 1
                v = b[p]
                out.append(v)
            elif lo != 0x0D:
                v = (v - (lo - 6)) & 0xFF
                out.append(v)
            p += 1
        elif c >= 0xF0:
            c2 = b[p + 1]
            v = (((c << 4) & 0xFF) + (c2 >> 4)) & 0xFF
            out.append(v)
            lo = c2 & 0x0F
            if lo == 0x0F:
                v = b[p + 2]
                out.append(v)
                p += 3
            else:
                if lo != 0x0D:
                    v = (v - (lo - 6)) & 0xFF
                    out.append(v)
                p += 2
        else:
            out += [v] * (2 * (c - 0xE0))
            p += 1
    return np.array(out[:count], np.uint8)


ENCODERS = {
    "16zT": lambda f: encode_16zt(f),
    "16zP": lambda f: encode_16z(f),
    "Im8z": lambda f: encode_8z(f),
    "NONE": lambda f: np.ascontiguousarray(f).astype(np.asarray(f).dtype.newbyteorder("<")).tobytes(),
}

# -- writer -------------------------------------------------------------------------------------

NODE_TYPES = {"depth": 2, "image": 3, "ir": 5}
PIXEL_FORMATS = {"depth": (100, 4), "image": (200, 1), "ir": (203, 4)}  # (oniPixelFormat, xnPixelFormat)


@dataclass
class StreamSpec:
    """A stream to write: ``frames`` [N, H, W] or [N, H, W, 3], with timestamps (us) and 1-based
    frame numbers (default 0, 33333... and 1..N); ``added_late``: its node is added just before
    its first frame, after other streams' data began."""

    name: str
    kind: str
    codec: str
    frames: np.ndarray
    fps: int = 30
    timestamps_us: list[int] | None = None
    frame_numbers: list[int] | None = None
    extra_properties: dict = field(default_factory=dict)
    added_late: bool = False  # its node is added after the recording's data began (OpenNI 1.x allows it)


def _string(s: str) -> bytes:
    raw = s.encode("latin-1") + b"\0"
    return struct.pack("<I", len(raw)) + raw


class _Writer:
    def __init__(self, old32: bool):
        self.old32 = old32
        self.buf = bytearray()
        self.pos_fmt = "<I" if old32 else "<Q"

    def record(self, rtype: int, node: int, fields: bytes, payload: bytes = b"", undo: int = 0) -> int:
        start = len(self.buf)
        head = 24 if self.old32 else 28
        fmt = "<IIIIII" if self.old32 else "<IIIIIQ"
        self.buf += struct.pack(fmt, 0x0052494E, rtype, node, head + len(fields), len(payload), undo)
        self.buf += fields + payload
        return start


def write_oni(
    path,
    streams: list[StreamSpec],
    *,
    old32: bool = False,
    version: tuple[int, int, int, int] | None = None,
    finish: bool = True,
) -> bytes:
    """Write a recording as OpenNI's recorders lay it out; returns its bytes.

    ``old32``: u32 positions (version 1.0.0.6 unless ``version``). ``version`` 1.0.0.4 or
    1.0.0.5 writes those versions' NODE_ADDED records (no seek table position; 1.0.0.4 also no
    frame count). ``finish=False`` stops after the last frame, as a crashed recorder would: no
    NODE_REMOVED, SEEK_TABLE or END, and the NODE_ADDED records keep frame count 0 and no seek
    table.
    """
    version = version or ((1, 0, 0, 6) if old32 else (1, 0, 1, 0))
    old32 = old32 or version < (1, 0, 1, 0)
    added_type = 0x02 if version <= (1, 0, 0, 4) else 0x0C if version <= (1, 0, 0, 5) else 0x0D
    w = _Writer(old32)
    w.buf += b"NI10" + struct.pack("<BBHIQI", *version, 2**64 - 1, len(streams))
    added, payloads, last, data_begin = {}, {}, {}, {}

    def add_node(node: int, s: StreamSpec) -> None:
        codec = int.from_bytes(s.codec.encode("latin-1"), "little")
        fields = _string(s.name) + struct.pack("<II", NODE_TYPES[s.kind], codec)
        if added_type != 0x02:
            fields += struct.pack("<IQQ", 0, 0, 0)
        if added_type == 0x0D:
            fields += struct.pack(w.pos_fmt, 0)
        added[node] = (w.record(added_type, node, fields), fields)
        h, wd = s.frames.shape[1:3]
        oni_fmt, xn_fmt = PIXEL_FORMATS[s.kind]
        props = {
            "oniRequiredFrameSize": ("int", s.frames[0].nbytes),
            "xnMapOutputMode": ("general", struct.pack("<III", wd, h, s.fps)),
            "xnPixelFormat": ("int", xn_fmt),
            "oniPixelFormat": ("int", oni_fmt),
            **s.extra_properties,
        }
        for name, (kind, value) in props.items():
            if kind == "int":
                w.record(0x03, node, _string(name) + struct.pack("<Iq", 8, value))
            else:
                w.record(0x06, node, _string(name) + struct.pack("<I", len(value)) + value)

    def begin_data(node: int) -> None:
        w.record(0x09, node, b"")
        data_begin[node] = w.record(0x08, node, struct.pack("<IQ", 0, 0))

    for node, s in enumerate(streams, start=1):
        n = len(s.frames)
        s.timestamps_us = s.timestamps_us or [round(i * 1e6 / s.fps) for i in range(n)]
        s.frame_numbers = s.frame_numbers or list(range(1, n + 1))
        payloads[node] = [ENCODERS[s.codec](f) for f in s.frames]
        if not s.added_late:
            add_node(node, s)
    for node in list(added):
        begin_data(node)
    seek = {node: [] for node in range(1, len(streams) + 1)}
    order = sorted(
        ((s.timestamps_us[i], node, i) for node, s in enumerate(streams, start=1) for i in range(len(s.frames))),
        key=lambda t: (t[0], t[1]),
    )
    for ts, node, i in order:
        s = streams[node - 1]
        if node not in added:  # a stream added while recording: its records come just before its data
            add_node(node, s)
            begin_data(node)
        pos = w.record(0x0A, node, struct.pack("<QI", ts, s.frame_numbers[i]), payloads[node][i], last.get(node, 0))
        last[node] = pos
        seek[node].append((ts, pos))
    if finish:
        tables = {}
        for node in added:
            w.record(0x07, node, b"", undo=added[node][0])
            entry = "<QII" if old32 else "<QIQ"
            table = struct.pack(entry, 0, 0, 0) + b"".join(struct.pack(entry, ts, 0, pos) for ts, pos in seek[node])
            tables[node] = w.record(0x0E, node, b"", table)
        w.record(0x0B, 0, b"")
        for node, s in enumerate(streams, start=1):
            start, fields = added[node]
            if added_type == 0x02:  # 1.0.0.4 keeps the frame count in NODE_DATA_BEGIN
                at = data_begin[node] + (24 if old32 else 28)
                w.buf[at : at + 12] = struct.pack("<IQ", len(s.frames), max(s.timestamps_us))
                continue
            name_len = len(_string(s.name)) + 8
            final = fields[:name_len] + struct.pack("<IQQ", len(s.frames), min(s.timestamps_us), max(s.timestamps_us))
            if added_type == 0x0D:
                final += struct.pack(w.pos_fmt, tables[node])
            head = 24 if old32 else 28
            w.buf[start + head : start + head + len(final)] = final
    data = bytes(w.buf)
    if path is not None:
        with open(path, "wb") as f:
            f.write(data)
    return data
