"""Azure Kinect and Orbbec Femto recordings (``k4arecorder``'s Matroska ``.mkv``), read without the SDK.

>>> with K4aRecording("take.mkv") as take:
...     depth = take.track("DEPTH")          # MkvTrack: frames, device times (us), mode tags
...     image = take.frame(depth, 0)         # uint16 [576, 640], millimetres
...     imu = take.imu()                     # ImuSamples: times (us), accelerations, rotation rates

The layout is the Azure Kinect Sensor SDK's recorder (src/record/sdk/record.cpp and
src/record/internal/matroska_write.cpp, microsoft/Azure-Kinect-Sensor-SDK; the file format page of
the SDK's documentation): a Segment whose timestamps tick in microseconds (TimestampScale 1 000
ns); video tracks named ``COLOR``, ``DEPTH``, ``IR`` with codec ``V_MS/VFW/FOURCC`` and a 40-byte
BITMAPINFOHEADER naming the pixels (``b16g``: 16-bit big-endian depth or infrared; ``MJPG``,
``NV12``, ``YUY2``, ``BGRA`` colour); a subtitle track ``IMU`` (``S_K4A/IMU``) of 40-byte samples
laced in blocks; one Tag per ``K4A_*`` fact (modes, serial number, firmware, ``K4A_START_OFFSET_NS``),
targeted at a track, the calibration attachment or nothing; and ``calibration.json`` attached.
A block's time is the device time less ``K4A_START_OFFSET_NS``: device time (us) = block time (us)
+ offset (ns) / 1000, as the SDK's playback gives it. The IMU samples carry their own device times
in nanoseconds (the documentation says microseconds; the recorder writes ``usec * 1000``).

Opening walks the clusters once and keeps each frame's position; a file cut short (a recorder
killed, a full disk) keeps every frame before the cut and says where in :attr:`problems`. A
recorder killed before it closed the file never wrote the Info element (its TimestampScale) nor
``K4A_START_OFFSET_NS`` (both are written when the recording is closed: record.cpp's
``k4a_record_flush``): the recorder's microsecond ticks are then assumed, the offset is recovered
from the first IMU sample (its own device time less its block's time) when there is an IMU track,
and :attr:`problems` says so.
"""

from __future__ import annotations

import mmap
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinectdata.core.errors import KinectDataError, KinectDataWarning

from . import ebml
from .ebml import IDS, EbmlError, Element

K4A_TRACKS = ("COLOR", "DEPTH", "IR", "IMU")
IMU_SAMPLE = np.dtype([("acc_time_ns", "<u8"), ("acc", "<f4", 3), ("gyro_time_ns", "<u8"), ("gyro", "<f4", 3)])
"""One IMU sample as the recorder packs it (40 bytes, little-endian; include/k4ainternal/matroska_common.h)."""
MAX_TICKS = 1 << 52
"""Cluster times beyond this many ticks (142 years in the recorder's microseconds) are damage."""
TRACK_TYPES = {1: "video", 2: "audio", 0x11: "subtitle", 0x12: "buttons", 0x20: "control", 0x21: "metadata"}


class MkvError(KinectDataError):
    """A ``.mkv`` file that cannot be read; the message names the file and the byte position."""


class MkvWarning(KinectDataWarning):
    """A recording was read only in part (cut short or damaged); the message says where."""


@dataclass
class MkvTrack:
    """One track of a recording and the index of its frames.

    Attributes:
        number: the track's number in the file's blocks. uid: its TrackUID.
        name: ``COLOR``, ``DEPTH``, ``IR``, ``IMU`` (or what the file names it).
        kind: ``video``, ``subtitle``...; codec: the CodecID (``V_MS/VFW/FOURCC``, ``S_K4A/IMU``).
        fourcc: the video's pixel format from its BITMAPINFOHEADER (``b16g``, ``MJPG``...; None otherwise).
        width, height: pixels (0 for other tracks). bits: bits per pixel the header gives.
        frame_period_ns: the track's DefaultDuration (None when not given).
        tags: the ``K4A_*`` tags aimed at this track (``K4A_DEPTH_MODE``: ``NFOV_UNBINNED``...).
        times_us: [N] int64 block times of its frames in microseconds from the file's start; the
            device's clock is ``times_us + start_offset_us`` (:attr:`K4aRecording.device_times_us`).
        positions, sizes: [N] int64 where each frame's bytes are in the file. A track other than
            video (the IMU) has a row per block instead: its laced samples, back to back.
    """

    number: int
    uid: int
    name: str
    kind: str
    codec: str
    fourcc: str | None = None
    width: int = 0
    height: int = 0
    bits: int = 0
    frame_period_ns: int | None = None
    tags: dict[str, str] = field(default_factory=dict)
    times_us: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    positions: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    sizes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def frame_count(self) -> int:
        return len(self.times_us)


@dataclass(frozen=True)
class ImuSamples:
    """The IMU's samples: [N] device times in microseconds (accelerometer's and gyroscope's),
    accelerations [N, 3] in m/s^2 and rotation rates [N, 3] in rad/s, the sensor's own axes."""

    acc_times_us: np.ndarray
    acc: np.ndarray
    gyro_times_us: np.ndarray
    gyro: np.ndarray


class K4aRecording:
    """A k4arecorder ``.mkv`` file, opened for reading (a context manager; :meth:`close` frees it).

    Attributes:
        path: the file. tags: the ``K4A_*`` tags aimed at no track (serial number, firmware,
            sync mode, ``K4A_START_OFFSET_NS``...). tracks: by name, in file order.
        attachments: name -> bytes (``calibration.json``).
        timestamp_scale_ns: nanoseconds per tick (1 000 in the recorder's files).
        title, writing_app: the Info element's.
        start_offset_us: the device time of the file's time 0, microseconds (``K4A_START_OFFSET_NS``
            / 1000, or recovered from the IMU; None when neither gives it).
        problems: what was wrong with the file (cut short, damaged, never closed) and what was
            read despite it, one line each.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        try:
            handle = open(self.path, "rb")
        except OSError as exc:
            raise MkvError(f"{self.path}: cannot open: {exc.strerror or exc}") from None
        with handle:
            size = os.fstat(handle.fileno()).st_size
            if size == 0:
                raise MkvError(f"{self.path}: empty file, not a Matroska recording")
            self._map = mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
        self.tags: dict[str, str] = {}
        self.tracks: dict[str, MkvTrack] = {}
        self.attachments: dict[str, bytes] = {}
        self.timestamp_scale_ns = 1_000_000  # Matroska's default (RFC 9559, 5.1.2.1)
        self.title = self.writing_app = ""
        self.problems: list[str] = []
        self.start_offset_us: float | None = None
        try:
            self._read()
        except EbmlError as exc:
            self.close()
            raise MkvError(f"{self.path}: {exc}") from None
        except BaseException:
            self.close()
            raise
        for problem in self.problems:
            warnings.warn(f"{self.path}: {problem}", MkvWarning, stacklevel=2)

    def __enter__(self) -> K4aRecording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if getattr(self, "_map", None) is not None:
            self._map.close()
            self._map = None

    # -- what the file says --------------------------------------------------------------------

    def track(self, name: str) -> MkvTrack:
        """The track named ``name`` (``COLOR``, ``DEPTH``, ``IR``, ``IMU``)."""
        try:
            return self.tracks[name]
        except KeyError:
            have = ", ".join(self.tracks) or "none"
            raise MkvError(f"{self.path}: no {name} track (the file has: {have})") from None

    def device_times_us(self, track: MkvTrack) -> np.ndarray:
        """[N] float64 device times of ``track``'s frames in microseconds (the body tracker's clock)."""
        if self.start_offset_us is None:
            raise MkvError(
                f"{self.path}: no K4A_START_OFFSET_NS and no IMU to recover it: the device's times are unknown"
            )
        return track.times_us + self.start_offset_us

    def depth_mode(self) -> str:
        """The depth mode (``NFOV_UNBINNED``...): the DEPTH track's ``K4A_DEPTH_MODE`` tag, the file's
        (PASSIVE_IR has no depth track to aim it at), or the one mode of the track's resolution."""
        from .calibration import DEPTH_MODES

        depth = self.track("DEPTH")
        mode = depth.tags.get("K4A_DEPTH_MODE") or self.tags.get("K4A_DEPTH_MODE")
        if mode:
            return mode
        by_size = [m for m, (_, _, size) in DEPTH_MODES.items() if size == (depth.width, depth.height)]
        if not by_size:
            raise MkvError(f"{self.path}: no K4A_DEPTH_MODE tag, and no depth mode is {depth.width} x {depth.height}")
        return by_size[0]

    def calibration(self):
        """The device calibration attached to the recording
        (:class:`~kinectdata.mkv.calibration.DeviceCalibration`)."""
        from .calibration import read_calibration

        if not self.calibration_json:
            raise MkvError(f"{self.path}: no calibration.json attached")
        return read_calibration(self.calibration_json, source=f"{self.path}: calibration.json")

    @property
    def calibration_json(self) -> bytes:
        """The attached calibration as recorded (the attachment ``K4A_CALIBRATION_FILE`` names,
        else ``calibration.json``; empty when there is none)."""
        return self.attachments.get(self.tags.get("K4A_CALIBRATION_FILE", "calibration.json"), b"")

    def frame_bytes(self, track: MkvTrack, index: int) -> bytes:
        """The bytes of frame ``index`` (of the IMU track: one block's samples)."""
        if self._map is None:
            raise MkvError(f"{self.path}: the recording is closed")
        if not 0 <= index < track.frame_count:
            raise MkvError(f"{self.path}: {track.name} frame {index} out of range (0..{track.frame_count - 1})")
        start = int(track.positions[index])
        return self._map[start : start + int(track.sizes[index])]

    def frame(self, track: MkvTrack, index: int) -> np.ndarray:
        """Frame ``index`` of a video track decoded: uint16 [H, W] for ``b16g`` (depth in mm, or
        infrared), uint8 [H, W, 3] RGB for colour (:mod:`.pixels`)."""
        from .pixels import decode_frame

        return decode_frame(self.frame_bytes(track, index), track, what=f"{self.path}: {track.name} frame {index}")

    def imu(self) -> ImuSamples:
        """Every IMU sample in file order (the ``IMU`` track's laced 40-byte records)."""
        track = self.track("IMU")
        bad = np.flatnonzero(track.sizes % IMU_SAMPLE.itemsize)
        if bad.size:
            raise MkvError(
                f"{self.path}: byte {int(track.positions[bad[0]])}: an IMU block of {int(track.sizes[bad[0]])} bytes, "
                f"not whole {IMU_SAMPLE.itemsize}-byte samples"
            )
        samples = self._samples(track)
        return ImuSamples(
            acc_times_us=samples["acc_time_ns"].astype(np.int64) // 1000,
            acc=samples["acc"].astype(np.float32),
            gyro_times_us=samples["gyro_time_ns"].astype(np.int64) // 1000,
            gyro=samples["gyro"].astype(np.float32),
        )

    def _samples(self, track: MkvTrack) -> np.ndarray:
        if self._map is None:
            raise MkvError(f"{self.path}: the recording is closed")
        if not track.frame_count:
            return np.zeros(0, IMU_SAMPLE)
        ends = track.positions + track.sizes
        if np.all(track.positions[1:] == ends[:-1]):  # the blocks' samples back to back: one read
            return np.frombuffer(self._map[int(track.positions[0]) : int(ends[-1])], IMU_SAMPLE).copy()
        return np.concatenate([np.frombuffer(self.frame_bytes(track, i), IMU_SAMPLE) for i in range(track.frame_count)])

    # -- reading the structure -----------------------------------------------------------------

    def _read(self) -> None:
        data, end = self._map, len(self._map)
        if bytes(data[:4]) != IDS["EBML"].to_bytes(4, "big"):
            raise MkvError(f"{self.path}: not a Matroska file (no EBML header at byte 0)")
        top = ebml.elements(data, 0, end)  # what follows the first Segment (padding, junk) is not read
        first = next(top)
        header = ebml.children(data, first)
        doc_type = ebml.text(data, header[IDS["DocType"]][0]) if IDS["DocType"] in header else "matroska"
        if doc_type not in ("matroska", "webm"):
            raise MkvError(f"{self.path}: an EBML file of type {doc_type!r}, not Matroska")
        segment = next((e for e in top if e.id == IDS["Segment"]), None)
        if segment is None:
            raise MkvError(f"{self.path}: no Segment after the EBML header")
        if segment.cut:
            self.problems.append(
                f"cut short at byte {segment.end}: the last {segment.missing:,} bytes of the Segment are missing"
            )
        uids_by_number: dict[int, MkvTrack] = {}
        clusters: list[Element] = []
        raw_tags: list[tuple[str, int, str]] = []
        info = False
        walk = ebml.elements(data, segment.data, segment.end)
        while True:
            try:
                e = next(walk, None)
            except EbmlError as exc:
                if not uids_by_number:
                    raise
                self.problems.append(f"the Segment cannot be followed past here ({exc}): what comes after is lost")
                break
            if e is None:
                break
            if e.id == IDS["Info"]:
                self._read_info(e)
                info = True
            elif e.id == IDS["Tracks"]:
                for entry in ebml.children(data, e).get(IDS["TrackEntry"], []):
                    track = self._read_track(entry)
                    uids_by_number[track.number] = track
            elif e.id == IDS["Attachments"]:
                self._read_attachments(e)
            elif e.id == IDS["Tags"]:
                raw_tags.extend(self._read_tags(e))
            elif e.id == IDS["Cluster"]:
                clusters.append(e)
        by_uid = {t.uid: t for t in uids_by_number.values()}
        for name, track_uid, value in raw_tags:
            target = by_uid.get(track_uid) if track_uid else None
            (target.tags if target is not None else self.tags)[name] = value
        self.tracks = {t.name: t for t in uids_by_number.values()}
        recorder = any(t.codec == "S_K4A/IMU" or t.name in K4A_TRACKS for t in self.tracks.values())
        if not info and recorder:
            self.timestamp_scale_ns = 1000
            self.problems.append(
                "no Info element (a recorder stopped before it closed the file): its microsecond ticks are assumed"
            )
        self._index(clusters, uids_by_number)
        self._start_offset()

    def _start_offset(self) -> None:
        """:attr:`start_offset_us` from the tag, or from the first IMU sample: its device time less
        its block's time (the recorder makes a sample's block time exactly that difference)."""
        raw = self.tags.get("K4A_START_OFFSET_NS")
        if raw is not None:
            try:
                self.start_offset_us = int(raw) / 1000
                return
            except ValueError:
                raise MkvError(f"{self.path}: K4A_START_OFFSET_NS is {raw!r}, not a number of nanoseconds") from None
        imu = self.tracks.get("IMU")
        if imu is not None and imu.frame_count and imu.sizes[0] >= IMU_SAMPLE.itemsize:
            first = np.frombuffer(self.frame_bytes(imu, 0)[: IMU_SAMPLE.itemsize], IMU_SAMPLE)[0]
            self.start_offset_us = int(first["acc_time_ns"]) / 1000 - float(imu.times_us[0])
            self.problems.append(
                f"no K4A_START_OFFSET_NS tag: the device time of the file's start, {self.start_offset_us:.0f} us, "
                "is taken from the first IMU sample"
            )
        elif self.tracks:
            self.problems.append("no K4A_START_OFFSET_NS tag and no IMU track: the device's times are unknown")

    def _read_info(self, info: Element) -> None:
        data, kids = self._map, ebml.children(self._map, info)
        self.timestamp_scale_ns = ebml.first(data, kids, "TimestampScale", ebml.uint, self.timestamp_scale_ns)
        if self.timestamp_scale_ns == 0:
            raise MkvError(f"{self.path}: byte {kids[IDS['TimestampScale']][0].start}: a TimestampScale of 0")
        self.title = ebml.first(data, kids, "Title", ebml.text, self.title)
        self.writing_app = ebml.first(data, kids, "WritingApp", ebml.text, self.writing_app)

    def _read_track(self, entry: Element) -> MkvTrack:
        data, kids = self._map, ebml.children(self._map, entry)

        def one(name, read, default=None):
            return ebml.first(data, kids, name, read, default)

        number = one("TrackNumber", ebml.uint)
        if not number:
            raise MkvError(f"{self.path}: byte {entry.start}: a TrackEntry without its TrackNumber")
        kind = one("TrackType", ebml.uint, 0)
        track = MkvTrack(
            number=number,
            uid=one("TrackUID", ebml.uint, 0),
            name=one("Name", ebml.text, f"track {number}"),
            kind=TRACK_TYPES.get(kind, f"type {kind}"),
            codec=one("CodecID", ebml.text, ""),
            frame_period_ns=one("DefaultDuration", ebml.uint),
        )
        if IDS["Video"] in kids:
            video = ebml.children(data, kids[IDS["Video"]][0])
            track.width = ebml.first(data, video, "PixelWidth", ebml.uint, 0)
            track.height = ebml.first(data, video, "PixelHeight", ebml.uint, 0)
        private = one("CodecPrivate", ebml.payload)
        if track.codec == "V_MS/VFW/FOURCC":
            if private is None or len(private) < 40:
                raise MkvError(
                    f"{self.path}: byte {entry.start}: track {track.name}'s V_MS/VFW/FOURCC codec needs a "
                    f"40-byte BITMAPINFOHEADER, it has {0 if private is None else len(private)} bytes"
                )
            width, height = (int(v) for v in np.frombuffer(private, "<i4", 2, 4))
            track.bits = int(np.frombuffer(private, "<u2", 1, 14)[0])
            track.fourcc = private[16:20].decode("latin-1")
            track.width, track.height = track.width or abs(width), track.height or abs(height)
        return track

    def _read_attachments(self, element: Element) -> None:
        data = self._map
        for attached in ebml.children(data, element).get(IDS["AttachedFile"], []):
            kids = ebml.children(data, attached)
            if IDS["FileName"] in kids and IDS["FileData"] in kids:
                self.attachments[ebml.text(data, kids[IDS["FileName"]][0])] = ebml.payload(
                    data, kids[IDS["FileData"]][0]
                )

    def _read_tags(self, element: Element) -> list[tuple[str, int, str]]:
        """(name, the UID of the track it targets or 0, value) of every SimpleTag (a tag aimed at an
        attachment, as K4A_CALIBRATION_FILE is, counts as aimed at no track)."""
        data, found = self._map, []
        for tag in ebml.children(data, element).get(IDS["Tag"], []):
            kids = ebml.children(data, tag)
            track_uid = 0
            if IDS["Targets"] in kids:
                targets = ebml.children(data, kids[IDS["Targets"]][0])
                track_uid = ebml.first(data, targets, "TagTrackUID", ebml.uint, 0)
            for simple in kids.get(IDS["SimpleTag"], []):
                fields = ebml.children(data, simple)
                if IDS["TagName"] in fields:
                    value = ebml.first(data, fields, "TagString", ebml.text, "")
                    found.append((ebml.text(data, fields[IDS["TagName"]][0]), track_uid, value))
        return found

    def _index(self, clusters: list[Element], tracks: dict[int, MkvTrack]) -> None:
        """Every frame's time and place, cluster by cluster: a row per frame of a video track, a row
        per block of any other (the IMU's laced samples lie back to back: one span each)."""
        data = self._map
        tick_us = self.timestamp_scale_ns / 1000
        rows: dict[int, list[tuple[int, int, int]]] = {n: [] for n in tracks}
        video = {n for n, t in tracks.items() if t.kind == "video"}
        for cluster in clusters:
            base = None
            try:
                for e in ebml.elements(data, cluster.data, cluster.end):
                    if e.id == IDS["Timestamp"]:
                        base = ebml.uint(data, e)
                        if base > MAX_TICKS:
                            raise EbmlError(f"byte {e.start}: a Cluster Timestamp of {base} ticks")
                        continue
                    block_element = e
                    if e.id == IDS["BlockGroup"]:
                        inner = ebml.children(data, e).get(IDS["Block"])
                        if not inner:
                            continue
                        block_element = inner[0]
                    elif e.id != IDS["SimpleBlock"]:
                        continue
                    if block_element.cut:
                        self.problems.append(
                            f"cut short at byte {len(data)}: the block from byte {block_element.start} is incomplete, "
                            "the frames from there on are lost"
                        )
                        break
                    if base is None:
                        raise EbmlError(f"byte {e.start}: a block before its Cluster's Timestamp")
                    block = ebml.parse_block(data, block_element)
                    if block.track not in rows:
                        continue
                    time = base + block.timecode
                    if block.track in video:
                        rows[block.track].extend((time, offset, size) for offset, size in block.frames)
                    else:
                        first = block.frames[0][0]
                        rows[block.track].append((time, first, block.frames[-1][0] + block.frames[-1][1] - first))
            except EbmlError as exc:  # a damaged cluster: its size still says where the next one starts
                what = "incomplete" if cluster.cut else "damaged"
                self.problems.append(
                    f"the Cluster from byte {cluster.start} is {what} ({exc}): its frames from there on are lost"
                )
        for number, track in tracks.items():
            table = np.asarray(rows[number], dtype=np.int64).reshape(-1, 3)
            track.times_us = np.round(table[:, 0] * tick_us).astype(np.int64)
            track.positions, track.sizes = table[:, 1].copy(), table[:, 2].copy()
