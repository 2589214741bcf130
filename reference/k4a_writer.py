"""A writer of k4arecorder's Matroska layout, written from the Azure Kinect Sensor SDK's
recorder (src/record/sdk/record.cpp, src/record/internal/matroska_write.cpp) and not sharing code
with kinectdata's reader: EBML header (DocType matroska, version 2), Segment with Info
(TimestampScale 1 000 ns, title "Azure Kinect"), Tracks (COLOR, DEPTH, IR as V_MS/VFW/FOURCC with a
40-byte BITMAPINFOHEADER; IMU as S_K4A/IMU subtitles), the calibration.json attachment, one Tag
per K4A_* fact, then clusters of at most 32 ms: each video frame a keyframe SimpleBlock, each run
of IMU samples one BlockGroup of fixed-laced 40-byte samples with a BlockDuration; a SeekHead first,
a 1 024-byte Void before the clusters, Cues after them, CRC-32s in the Clusters and Tags, as the
recorder lays them out. Block times are device times less K4A_START_OFFSET_NS; depth and IR pixels
big-endian.
"""

from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

FOURCC_CODES = {"b16g": (16, 0x67363162), "MJPG": (24, 0x47504A4D), "NV12": (12, 0x3231564E),
                "YUY2": (16, 0x32595559), "BGRA": (32, 0x41524742)}  # fmt: skip


def _size(n: int) -> bytes:
    for length in range(1, 9):
        if n < (1 << (7 * length)) - 1:
            return ((1 << (7 * length)) | n).to_bytes(length, "big")
    raise ValueError(n)


def element(ident: int, body: bytes) -> bytes:
    return ident.to_bytes((ident.bit_length() + 7) // 8, "big") + _size(len(body)) + body


def unsigned(ident: int, value: int) -> bytes:
    return element(ident, value.to_bytes(max(1, (value.bit_length() + 7) // 8), "big"))


def string(ident: int, value: str) -> bytes:
    return element(ident, value.encode())


@dataclass
class VideoTrack:
    name: str  # COLOR, DEPTH, IR
    fourcc: str
    width: int
    height: int
    frames: list[bytes]  # payloads as written (depth/IR: big-endian uint16)
    times_ns: list[int]  # device times
    tags: dict[str, str] = field(default_factory=dict)


def depth_track(name: str, images: np.ndarray, times_ns, mode: str) -> VideoTrack:
    """A DEPTH or IR track from uint16 [N, H, W] images (written big-endian)."""
    n, h, w = images.shape
    tag = {"DEPTH": "K4A_DEPTH_MODE", "IR": "K4A_IR_MODE"}[name]
    return VideoTrack(name, "b16g", w, h, [im.astype(">u2").tobytes() for im in images], list(times_ns), {tag: mode})


def imu_samples(times_ns, acc, gyro) -> list[tuple[int, bytes]]:
    """(device time in ns, 40-byte sample) per IMU sample (the gyroscope's time 0.1 ms later)."""
    return [
        (int(t), struct.pack("<Q3fQ3f", int(t), *map(float, a), int(t) + 100_000, *map(float, g)))
        for t, a, g in zip(times_ns, acc, gyro)
    ]


def with_crc(ident: int, body: bytes) -> bytes:
    """A master element whose first child is a CRC-32 of the rest of its payload (RFC 8794, 11.3.1:
    the IEEE CRC, stored little-endian), as libmatroska writes the recorder's Clusters and Tags."""
    return element(ident, element(0xBF, struct.pack("<I", zlib.crc32(body))) + body)


def _closed_segment(info: bytes, entries: bytes, attachments: bytes, tags: bytes, clusters: list) -> bytes:
    """The payload of a Segment the recorder closed: SeekHead (to Info, Tracks, Attachments, Tags,
    Cues), Info, Tracks, Attachments, Tags, a Void of 1 024 bytes, the Clusters, then Cues for track
    1 (a point per cluster at least 1 s after the last), as record.cpp lays them out."""
    tracks, tags_element = element(0x1654AE6B, entries), with_crc(0x1254C367, tags)
    cluster_bytes = [c for _, c in clusters]

    def seek_head(positions: list[int]) -> bytes:  # 8-byte positions: its size does not depend on them
        ids = (0x1549A966, 0x1654AE6B, 0x1941A469, 0x1254C367, 0x1C53BB6B)
        return element(0x114D9B74, b"".join(
            element(0x4DBB, element(0x53AB, i.to_bytes(4, "big")) + element(0x53AC, p.to_bytes(8, "big")))
            for i, p in zip(ids, positions)))  # fmt: skip

    head_size = len(seek_head([0] * 5))
    front = [info, tracks, attachments, tags_element, element(0xEC, bytes(1021))]
    offsets, at = [], head_size
    for part in front:
        offsets.append(at)
        at += len(part)
    cues_at = at + sum(len(c) for c in cluster_bytes)
    points, last, position = b"", None, at
    for (time_us, _), cluster in zip(clusters, cluster_bytes):
        if last is None or time_us - last >= 1_000_000:
            points += element(
                0xBB, unsigned(0xB3, time_us) + element(0xB7, unsigned(0xF7, 1) + unsigned(0xF1, position))
            )
            last = time_us
        position += len(cluster)
    cues = element(0x1C53BB6B, points)
    head = seek_head([offsets[0], offsets[1], offsets[2], offsets[3], cues_at])
    return head + b"".join(front) + b"".join(cluster_bytes) + cues


def write_k4a(
    path,
    videos: list[VideoTrack],
    imu: list[tuple[int, bytes]] | None = None,
    *,
    fps: int = 30,
    calibration: dict | None = None,
    global_tags: dict[str, str] | None = None,
    seed: int = 1,
    cut_at: int | None = None,
    killed: bool = False,
) -> dict[str, int]:
    """Write the file; return the track UIDs by name. ``cut_at`` truncates the written bytes there.
    ``killed``: as the recorder leaves a file it never closed (record.cpp writes the Info element,
    the Segment's size and K4A_START_OFFSET_NS in k4a_record_flush, at close): a Segment of unknown
    size, a 256-byte Void where Info would be, the tags without the start offset."""
    rng = np.random.default_rng(seed)
    uid = {v.name: int(rng.integers(1, 1 << 60)) for v in videos}
    if imu is not None:
        uid["IMU"] = int(rng.integers(1, 1 << 60))
    attachment_uid = int(rng.integers(1, 1 << 60))
    items = [(int(t), i + 1, payload) for i, v in enumerate(videos) for t, payload in zip(v.times_ns, v.frames)]
    imu_number = len(videos) + 1
    items += [(t, imu_number, payload) for t, payload in (imu or [])]
    items.sort(key=lambda x: x[0])
    all_items = list(items)
    start_ns = items[0][0]

    entries = b""
    for number, v in enumerate(videos, 1):
        bits, code = FOURCC_CODES[v.fourcc]
        image_size = {"b16g": 2, "NV12": 1.5, "YUY2": 2, "BGRA": 4}.get(v.fourcc, 0) * v.width * v.height
        header = struct.pack("<IiiHHIIiiII", 40, v.width, v.height, 1, bits, code, int(image_size), 0, 0, 0, 0)
        entries += element(0xAE, unsigned(0xD7, number) + unsigned(0x73C5, uid[v.name]) + unsigned(0x83, 1)
                           + string(0x536E, v.name) + string(0x86, "V_MS/VFW/FOURCC") + unsigned(0x9C, 1)
                           + element(0x63A2, header) + unsigned(0x23E383, 1_000_000_000 // fps)
                           + element(0xE0, unsigned(0xB0, v.width) + unsigned(0xBA, v.height)))  # fmt: skip
    if imu is not None:
        entries += element(0xAE, unsigned(0xD7, imu_number) + unsigned(0x73C5, uid["IMU"]) + unsigned(0x83, 0x11)
                           + string(0x536E, "IMU") + string(0x86, "S_K4A/IMU") + unsigned(0x9C, 1))  # fmt: skip
    calibration_json = json.dumps(calibration or {"CalibrationInformation": {"Cameras": []}}).encode()
    attachments = element(0x1941A469, element(0x61A7, string(0x466E, "calibration.json")
                          + string(0x4660, "application/octet-stream") + element(0x465C, calibration_json)
                          + unsigned(0x46AE, attachment_uid)))  # fmt: skip

    def tag(name: str, value: str, target: str | None = None, target_uid: int = 0) -> bytes:
        if target == "TRACK":
            targets = string(0x63CA, "TRACK") + unsigned(0x63C5, target_uid)
        elif target == "ATTACHMENT":
            targets = string(0x63CA, "ATTACHMENT") + unsigned(0x63C6, target_uid)
        else:
            targets = unsigned(0x63C5, 0)
        return element(0x7373, element(0x63C0, targets) + element(0x67C8, string(0x45A3, name) + string(0x4487, value)))

    tags = b""
    for v in videos:
        tags += tag(f"K4A_{v.name}_TRACK", str(uid[v.name]), "TRACK", uid[v.name])
        for name, value in v.tags.items():
            tags += tag(name, value, "TRACK", uid[v.name])
    if imu is not None:
        tags += tag("K4A_IMU_TRACK", str(uid["IMU"]), "TRACK", uid["IMU"]) + tag(
            "K4A_IMU_MODE", "ON", "TRACK", uid["IMU"]
        )
    for name, value in (global_tags or {}).items():
        tags += tag(name, value)
    tags += tag("K4A_CALIBRATION_FILE", "calibration.json", "ATTACHMENT", attachment_uid)
    if not killed:
        tags += tag("K4A_START_OFFSET_NS", str(start_ns))

    clusters: list[tuple[int, bytes]] = []  # (cluster time in us, element)
    while items:
        first = items[0][0]
        batch = [x for x in items if x[0] < first + 32_000_000]
        items = items[len(batch) :]
        body = unsigned(0xE7, (first - start_ns) // 1000)
        i = 0
        while i < len(batch):
            t, number, payload = batch[i]
            relative = struct.pack(">h", (t - first) // 1000)
            if number == imu_number:
                j = i
                while j < len(batch) and batch[j][1] == imu_number:
                    j += 1
                run = batch[i:j]
                block = (
                    bytes([0x80 | number]) + relative + b"\x04" + bytes([len(run) - 1]) + b"".join(r[2] for r in run)
                )
                body += element(0xA0, element(0xA1, block) + unsigned(0x9B, (run[-1][0] - t) // 1000 + 1))
                i = j
            else:
                body += element(0xA3, bytes([0x80 | number]) + relative + b"\x80" + payload)
                i += 1
        clusters.append(((first - start_ns) // 1000, with_crc(0x1F43B675, body)))
    duration_us = max(t for t, _, _ in all_items) - start_ns
    info = element(0x1549A966, unsigned(0x2AD7B1, 1000) + string(0x4D80, "libmatroska-1.4.9")
                   + string(0x5741, "k4arecord-test") + string(0x7BA9, "Azure Kinect")
                   + element(0x4489, struct.pack(">d", duration_us / 1000))
                   + element(0x4461, struct.pack(">q", 912_345_678_000_000_000)))  # fmt: skip
    if killed:  # a Void of 1 024 where the SeekHead goes and one of 256 where Info goes
        head_part = element(0xEC, bytes(1024 - 3)) + element(0xEC, bytes(256 - 3))
        front = element(0x1654AE6B, entries) + attachments + with_crc(0x1254C367, tags) + element(0xEC, bytes(1021))
        body = head_part + front + b"".join(c for _, c in clusters)
        segment = b"\x18\x53\x80\x67\x01" + b"\xff" * 7 + body
    else:
        segment = element(0x18538067, _closed_segment(info, entries, attachments, tags, clusters))
    head = element(0x1A45DFA3, string(0x4282, "matroska") + unsigned(0x4287, 2) + unsigned(0x4285, 2))
    data = head + segment
    with open(path, "wb") as f:
        f.write(data if cut_at is None else data[:cut_at])
    return uid
