"""What an ``.oni`` holds (:func:`describe`) and one stream's frames to HDF5 (:func:`export_stream`).

The HDF5 file written by :func:`export_stream` (format ``kinectdata.oni-frames`` 1):

=================  ===================  ===============================================
dataset            shape, dtype         meaning
=================  ===================  ===============================================
``frames``         [N, H, W] uint16     depth (see ``depth_unit``) or IR; an image is
                   or [N, H, W, 3] u8   RGB888; chunked one frame per chunk
``timestamps_us``  [N] uint64           the recording's own timestamps, microseconds
``time_s``         [N] float64          seconds from the stream's first frame
``frame_numbers``  [N] uint32           1-based per stream; gaps are dropped frames
=================  ===================  ===============================================

Attributes: ``format``, ``format_version``, ``source`` (path), ``source_sha256``, ``stream``,
``kind``, ``codec``, ``pixel_format``, ``width``, ``height``, ``fps``, ``depth_unit_mm``,
``field_of_view_rad``, ``properties`` (JSON; raw bytes as hex), ``start_s`` / ``end_s`` (the
selection), ``dropped_frames``, ``truncated`` and ``problems`` (JSON list).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.atomic import atomic_hdf5
from kinectdata.core.errors import KinectDataError
from kinectdata.core.frame_export import check_span, frames_between, hdf5_filter
from kinectdata.core.hashing import file_sha256
from kinectdata.oni.reader import OniFile, OniStream

FORMAT = "kinectdata.oni-frames"
FORMAT_VERSION = 1


def _jsonable(value: Any) -> Any:
    return value.hex() if isinstance(value, bytes) else value


def stream_summary(stream: OniStream) -> dict[str, Any]:
    """A stream's description, JSON-able: codec, geometry, frames, timing, gaps."""
    fov = stream.field_of_view
    gaps = stream.gaps()
    return {
        "node_id": stream.node_id,
        "name": stream.name,
        "kind": stream.kind,
        "codec": stream.codec,
        "pixel_format": stream.pixel_format,
        "resolution": list(stream.resolution) if stream.resolution else None,
        "fps": stream.fps,
        "frames": stream.n_frames,
        "recorded_frames": stream.recorded_frames,
        "first_timestamp_us": int(stream.timestamps_us[0]) if stream.n_frames else None,
        "last_timestamp_us": int(stream.timestamps_us[-1]) if stream.n_frames else None,
        "duration_s": stream.duration_s,
        "measured_fps": stream.measured_fps,
        "dropped_frames": stream.dropped_frames,
        "gaps": len(gaps),
        "longest_gap_s": max((g for _, g in gaps), default=None),
        "field_of_view_deg": [float(np.degrees(a)) for a in fov] if fov else None,
    }


def describe(path: str | os.PathLike) -> dict[str, Any]:
    """Everything ``kinectdata oni info`` prints, as a dict."""
    with OniFile(path) as oni:
        return {
            "file": str(oni.path),
            "bytes": oni.size,
            "version": ".".join(map(str, oni.header.version)),
            "layout": "old32 (u32 positions)" if oni.header.old32 else "current (u64 positions)",
            "index": oni.index_source,
            "truncated": oni.truncated,
            "problems": list(oni.problems),
            "streams": [stream_summary(s) for s in oni.streams],
        }


def format_description(info: dict[str, Any]) -> str:
    """The lines ``kinectdata oni info`` prints."""
    lines = [
        f"{info['file']}: .oni version {info['version']}, {info['layout']}, {info['bytes']:,} bytes; "
        f"frames found through the {info['index']}"
    ]
    if info["truncated"]:
        lines.append("  TRUNCATED: the recording was cut short or is damaged; the frames before the cut are read")
    for problem in info["problems"]:
        lines.append(f"  problem: {problem}")
    for s in info["streams"]:
        res = "x".join(map(str, s["resolution"])) if s["resolution"] else "no resolution"
        fps = f"{s['fps']:g} fps nominal" if s["fps"] else "no nominal fps"
        lines.append(
            f"  {s['kind']} {s['name']!r} (node {s['node_id']}): {s['codec']}, {s['pixel_format']}, {res}, {fps}"
        )
        if not s["frames"]:
            lines.append("    no frames")
            continue
        measured = f"{s['measured_fps']:.3f} fps measured" if s["measured_fps"] else "one frame"
        recorded = "" if s["recorded_frames"] in (None, s["frames"]) else f" (header says {s['recorded_frames']})"
        lines.append(
            f"    {s['frames']} frames{recorded}, {s['duration_s']:.3f} s "
            f"(timestamps {s['first_timestamp_us']}..{s['last_timestamp_us']} us), {measured}"
        )
        longest = f", longest {s['longest_gap_s'] * 1000:.1f} ms" if s["gaps"] else ""
        lines.append(f"    dropped frames {s['dropped_frames']}; gaps over 1.5 frame periods {s['gaps']}{longest}")
        if s["field_of_view_deg"]:
            h, v = s["field_of_view_deg"]
            lines.append(f"    field of view {h:.1f} x {v:.1f} degrees")
    return "\n".join(lines)


def _selection(stream: OniStream, start_s: float | None, end_s: float | None) -> np.ndarray:
    if not stream.n_frames:
        return np.zeros(0, np.int64)
    seconds = (stream.timestamps_us.astype(np.float64) - float(stream.timestamps_us[0])) / 1e6
    return frames_between(seconds, start_s, end_s)


def export_stream(
    path: str | os.PathLike,
    out: str | os.PathLike,
    stream: str = "depth",
    *,
    start_s: float | None = None,
    end_s: float | None = None,
    compression: str = "gzip",
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Decode one stream's frames into an HDF5 file (written atomically; layout in the module
    docstring). ``start_s`` / ``end_s`` select frames by seconds from the stream's first frame
    (start included, end excluded). Returns the file's attributes."""
    options = hdf5_filter(compression)
    check_span(start_s, end_s)
    with OniFile(path) as oni:
        s = oni.stream(stream)
        picked = _selection(s, start_s, end_s)
        if picked.size == 0:
            raise KinectDataError(
                f"{path}: stream {s.name!r} has no frames in the selection "
                f"({s.n_frames} frames over {s.duration_s:.3f} s)"
            )
        first = oni.read_frame(s, int(picked[0]))
        shape = first.data.shape
        attrs = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "source": str(Path(path).resolve()),
            "source_sha256": file_sha256(path),
            "stream": s.name,
            "kind": s.kind,
            "codec": s.codec,
            "pixel_format": s.pixel_format,
            "width": shape[1],
            "height": shape[0],
            "fps": s.fps or 0.0,
            "depth_unit_mm": 0.1 if s.pixel_format == "DEPTH_100_UM" else 1.0,
            "field_of_view_rad": list(s.field_of_view or []),
            "properties": json.dumps({k: _jsonable(v) for k, v in s.properties.items()}),
            "start_s": start_s if start_s is not None else 0.0,
            "end_s": end_s if end_s is not None else float("inf"),
            "dropped_frames": s.dropped_frames,
            "truncated": oni.truncated,
            "problems": json.dumps(oni.problems),
        }
        with atomic_hdf5(out) as f:  # no chunk cache: a full disk is an error, not a crash
            frames = f.create_dataset(
                "frames", shape=(picked.size, *shape), dtype=first.data.dtype, chunks=(1, *shape), **options
            )
            for i, index in enumerate(picked.tolist()):
                frame = first if i == 0 else oni.read_frame(s, index)
                if frame.data.shape != shape:
                    raise KinectDataError(
                        f"{path}: {s.name} frame {frame.number}: {frame.data.shape}, not {shape} like the first"
                    )
                frames[i] = frame.data
                if progress:
                    progress(i + 1, picked.size)
            stamps = s.timestamps_us[picked]
            f.create_dataset("timestamps_us", data=stamps)
            f.create_dataset("time_s", data=(stamps.astype(np.float64) - float(s.timestamps_us[0])) / 1e6)
            f.create_dataset("frame_numbers", data=s.frame_numbers[picked])
            for key, value in attrs.items():
                f.attrs[key] = value
    return attrs
