"""What a k4arecorder ``.mkv`` holds (:func:`describe`) and its tracks to HDF5 (:func:`export_tracks`).

The HDF5 file (format ``kinectdata.k4a-frames`` 1) has one group per exported track:

======================  ======================  ==============================================
dataset                 shape, dtype            meaning
======================  ======================  ==============================================
``depth/frames``        [N, H, W] uint16        depth in millimetres (0: none); one frame per
                                                chunk. ``ir/frames`` alike (infrared)
``color/frames``        [N, H, W, 3] uint8      RGB
``<track>/device_time_us``  [N] int64           the device's clock (the body tracker's), us
``<track>/time_s``      [N] float64             seconds from the file's time 0
``depth/points``        [N, H, W, 3] float32    with ``points``: each depth pixel in the depth
                                                camera's frame, mm (x right, y down, z ahead)
``imu/acc``, ``imu/gyro``  [M, 3] float32       m/s^2 and rad/s, the IMU's axes
``imu/acc_time_us``, ``imu/gyro_time_us``  [M] int64  device clock, us
======================  ======================  ==============================================

Attributes: ``format``, ``format_version``, ``source``, ``source_sha256``, ``tags`` (JSON: every
K4A tag), ``start_offset_us``, ``calibration_json`` (the attachment as recorded), ``start_s`` /
``end_s`` (the selection, seconds from the file's time 0), ``truncated``, ``problems`` (JSON);
per track ``fourcc``, ``width``, ``height``, ``mode``, ``fps``, and for depth with points the
intrinsics used (``fx``, ``fy``, ``cx``, ``cy`` in pixels).
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.atomic import atomic_hdf5
from kinectdata.core.errors import KinectDataError
from kinectdata.core.frame_export import check_span, frames_between, hdf5_filter
from kinectdata.core.hashing import file_sha256

from .recording import K4aRecording, MkvTrack

FORMAT = "kinectdata.k4a-frames"
FORMAT_VERSION = 1
TRACK_NAMES = {"color": "COLOR", "depth": "DEPTH", "ir": "IR", "imu": "IMU"}
GAP_PERIODS = 1.5
"""A step between frames longer than this many frame periods is a gap (frames dropped)."""


def _mode(track: MkvTrack) -> str | None:
    return next((v for k, v in track.tags.items() if k.endswith("_MODE")), None)


def _device(take: K4aRecording, file_us) -> float | None:
    return None if take.start_offset_us is None else float(file_us + take.start_offset_us)


def track_summary(take: K4aRecording, track: MkvTrack) -> dict[str, Any]:
    """A track's description, JSON-able: codec, geometry, mode, frames, timing, drops and gaps."""
    times = track.times_us
    period_us = track.frame_period_ns / 1000 if track.frame_period_ns else None
    summary: dict[str, Any] = {
        "name": track.name,
        "kind": track.kind,
        "codec": track.codec,
        "fourcc": track.fourcc,
        "resolution": [track.width, track.height] if track.width else None,
        "mode": _mode(track),
        "fps": 1e6 / period_us if period_us else None,
        "frames": track.frame_count,
        "first_device_time_us": _device(take, times[0]) if len(times) else None,
        "last_device_time_us": _device(take, times[-1]) if len(times) else None,
        "duration_s": float(times[-1] - times[0]) / 1e6 if len(times) > 1 else 0.0,
        "measured_fps": None,
        "dropped_frames": 0,
        "gaps": 0,
        "longest_gap_s": None,
    }
    if track.name == "IMU":
        samples = take.imu()
        summary["samples"] = len(samples.acc_times_us)
        span = (samples.acc_times_us[-1] - samples.acc_times_us[0]) / 1e6 if len(samples.acc_times_us) > 1 else 0
        summary["measured_rate_hz"] = (len(samples.acc_times_us) - 1) / span if span > 0 else None
        return summary
    if len(times) > 1:
        steps = np.diff(times).astype(np.float64)
        summary["measured_fps"] = 1e6 * len(steps) / float(times[-1] - times[0]) if times[-1] > times[0] else None
        if period_us:
            late = steps > GAP_PERIODS * period_us
            summary["dropped_frames"] = int(np.sum(np.round(steps[late] / period_us) - 1))
            summary["gaps"] = int(late.sum())
            summary["longest_gap_s"] = float(steps[late].max()) / 1e6 if late.any() else None
    return summary


def describe(source: str | os.PathLike | K4aRecording) -> dict[str, Any]:
    """Everything ``kinectdata mkv info`` prints, as a dict, of a file or of an open recording
    (which stays open)."""
    if isinstance(source, K4aRecording):
        return _description(source)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the problems are part of the description
        take = K4aRecording(source)
    with take:
        return _description(take)


def _description(take: K4aRecording) -> dict[str, Any]:
    return {
        "file": str(take.path),
        "bytes": os.path.getsize(take.path),
        "title": take.title,
        "writing_app": take.writing_app,
        "timestamp_scale_ns": take.timestamp_scale_ns,
        "start_offset_us": take.start_offset_us,
        "tags": dict(take.tags),
        "attachments": {name: len(data) for name, data in take.attachments.items()},
        "truncated": bool(take.problems),
        "problems": list(take.problems),
        "tracks": [track_summary(take, t) for t in take.tracks.values()],
    }


def format_description(info: dict[str, Any]) -> str:
    """The lines ``kinectdata mkv info`` prints."""
    tags = info["tags"]
    device = tags.get("K4A_DEVICE_SERIAL_NUMBER")
    lines = [
        f"{info['file']}: Matroska, {info['bytes']:,} bytes, written by {info['writing_app'] or 'an unnamed tool'}"
        + (f"; device {device}" if device else "")
    ]
    offset = info["start_offset_us"]
    start = "unknown" if offset is None else f"{offset:.0f} us"
    source = "K4A_START_OFFSET_NS" if "K4A_START_OFFSET_NS" in tags else "no K4A_START_OFFSET_NS tag"
    lines.append(f"  device time of the file's start: {start} ({source}); ticks of {info['timestamp_scale_ns']} ns")
    for key in (
        "K4A_COLOR_FIRMWARE_VERSION",
        "K4A_DEPTH_FIRMWARE_VERSION",
        "K4A_WIRED_SYNC_MODE",
        "K4A_DEPTH_DELAY_NS",
    ):
        if key in tags:
            lines.append(f"  {key}: {tags[key]}")
    if info["attachments"]:
        lines.append("  attached: " + ", ".join(f"{n} ({size:,} bytes)" for n, size in info["attachments"].items()))
    if info["truncated"]:
        lines.append("  TRUNCATED: the recording was cut short or is damaged; the frames before the cut are read")
    for problem in info["problems"]:
        lines.append(f"  problem: {problem}")
    for s in info["tracks"]:
        if s["name"] == "IMU":
            rate = f"{s['measured_rate_hz']:.1f} Hz measured" if s.get("measured_rate_hz") else "no rate"
            lines.append(f"  IMU ({s['codec']}): {s['samples']} samples, {rate}")
            continue
        res = "x".join(map(str, s["resolution"])) if s["resolution"] else "no resolution"
        fps = f"{s['fps']:g} fps nominal" if s["fps"] else "no nominal fps"
        mode = f", mode {s['mode']}" if s["mode"] else ""
        lines.append(f"  {s['name']} ({s['codec']} {s['fourcc']}): {res}{mode}, {fps}")
        if not s["frames"]:
            lines.append("    no frames")
            continue
        measured = f"{s['measured_fps']:.3f} fps measured" if s["measured_fps"] else "one frame"
        span = (
            "device time unknown"
            if s["first_device_time_us"] is None
            else f"device time {s['first_device_time_us']:.0f}..{s['last_device_time_us']:.0f} us"
        )
        lines.append(f"    {s['frames']} frames, {s['duration_s']:.3f} s ({span}), {measured}")
        longest = f", longest {s['longest_gap_s'] * 1000:.1f} ms" if s["gaps"] else ""
        lines.append(f"    dropped frames {s['dropped_frames']}; gaps over 1.5 frame periods {s['gaps']}{longest}")
    return "\n".join(lines)


def export_tracks(
    path: str | os.PathLike,
    out: str | os.PathLike,
    tracks: tuple[str, ...] = ("depth",),
    *,
    start_s: float | None = None,
    end_s: float | None = None,
    points: bool = False,
    compression: str = "gzip",
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Decode the ``tracks`` (``color``, ``depth``, ``ir``, ``imu``) of a recording into one HDF5
    file (written atomically; layout in the module docstring). ``start_s`` / ``end_s`` select by
    seconds from the file's time 0 (start included, end excluded); ``points`` adds the depth
    frames as points through the recording's calibration. Returns the file's attributes."""
    from .calibration import depth_to_points

    options = hdf5_filter(compression)
    check_span(start_s, end_s)
    unknown = [t for t in tracks if t not in TRACK_NAMES]
    if unknown or not tracks:
        raise KinectDataError(f"tracks must be among {', '.join(TRACK_NAMES)}, not {', '.join(unknown) or 'none'}")
    if points and "depth" not in tracks:
        raise KinectDataError("points are made from the depth track: export depth with them")
    with K4aRecording(path) as take:
        chosen = {name: take.track(TRACK_NAMES[name]) for name in tracks}
        picks = {n: frames_between(t.times_us / 1e6, start_s, end_s) for n, t in chosen.items() if n != "imu"}
        empty = [n for n, p in picks.items() if p.size == 0]
        if empty:
            raise KinectDataError(f"{path}: the {', '.join(empty)} track has no frames in the selection")
        intrinsics = take.calibration().depth_intrinsics(take.depth_mode()) if points else None
        total = sum(p.size for p in picks.values())
        done = 0
        attrs = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "source": str(Path(path).resolve()),
            "source_sha256": file_sha256(path),
            "tags": json.dumps(take.tags),
            "start_offset_us": take.start_offset_us if take.start_offset_us is not None else float("nan"),
            "calibration_json": take.calibration_json.rstrip(b"\0").decode("utf-8", "replace"),
            "start_s": start_s if start_s is not None else 0.0,
            "end_s": end_s if end_s is not None else float("inf"),
            "truncated": bool(take.problems),
            "problems": json.dumps(take.problems),
        }
        with atomic_hdf5(out) as f:
            for key, value in attrs.items():
                f.attrs[key] = value
            for name, track in chosen.items():
                group = f.create_group(name)
                group.attrs.update({"track": track.name, "codec": track.codec, "mode": _mode(track) or ""})
                if name == "imu":
                    _write_imu(take, group, start_s, end_s)
                    continue
                picked = picks[name]
                first = take.frame(track, int(picked[0]))
                frames = group.create_dataset(
                    "frames", shape=(picked.size, *first.shape), dtype=first.dtype, chunks=(1, *first.shape), **options
                )
                cloud = None
                if name == "depth" and intrinsics is not None:
                    cloud = group.create_dataset(
                        "points", shape=(picked.size, *first.shape, 3), dtype=np.float32,
                        chunks=(1, *first.shape, 3), **options,
                    )  # fmt: skip
                    group.attrs.update({"fx": intrinsics.fx, "fy": intrinsics.fy, "cx": intrinsics.cx,
                                        "cy": intrinsics.cy, "points_unit": "mm"})  # fmt: skip
                for i, index in enumerate(picked.tolist()):
                    image = first if i == 0 else take.frame(track, index)
                    frames[i] = image
                    if cloud is not None:
                        cloud[i] = depth_to_points(image, intrinsics)
                    done += 1
                    if progress:
                        progress(done, total)
                times = track.times_us[picked]
                if take.start_offset_us is not None:
                    group.create_dataset("device_time_us", data=times + round(take.start_offset_us))
                group.create_dataset("time_s", data=times.astype(np.float64) / 1e6)
                group.attrs.update(
                    {"fourcc": track.fourcc or "", "width": track.width, "height": track.height,
                     "fps": 1e9 / track.frame_period_ns if track.frame_period_ns else 0.0}
                )  # fmt: skip
    return attrs


def _write_imu(take: K4aRecording, group, start_s: float | None, end_s: float | None) -> None:
    samples = take.imu()
    file_time_us = samples.acc_times_us - round(take.start_offset_us)
    keep = frames_between(file_time_us / 1e6, start_s, end_s)
    group.create_dataset("acc", data=samples.acc[keep])
    group.create_dataset("gyro", data=samples.gyro[keep])
    group.create_dataset("acc_time_us", data=samples.acc_times_us[keep])
    group.create_dataset("gyro_time_us", data=samples.gyro_times_us[keep])
    group.create_dataset("time_s", data=file_time_us[keep].astype(np.float64) / 1e6)
