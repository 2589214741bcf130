"""Aligning a skeleton recording with its music: one exact timeline, audio at 16 kHz mono.

:func:`align` is the library recipe; :func:`align_files` reads the inputs, aligns and writes the
HDF5 file (``kinectdata align`` is a thin command over it).

Timeline: with ``audio_time = motion_time + offset``, the output keeps the span both cover. Its
time 0 is the first audio sample inside that span and frame k is at ``k / fps`` on that clock.
The last frame is the last one that has motion at its time and audio for its whole frame period,
so the output audio is exactly ``n_frames / fps`` seconds long. The motion is resampled onto the
frame times (:mod:`kinectdata.timeline`). The audio must cover at least ``min_coverage`` of the
motion's duration; otherwise the pair is refused (audio shorter than the dance, or a wrong
offset), not silently trimmed.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np

from .aligned import AlignedRecording
from .audio import DEFAULT_SAMPLE_RATE, Audio, load_audio
from .errors import AlignmentError, KinectDataError
from .formats import read_motion
from .motion import Motion
from .offset import estimate_offset
from .timeline import resample_motion

DEFAULT_FPS = 30.0
DEFAULT_MAX_GAP = 0.2
DEFAULT_MIN_COVERAGE = 0.9


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _resolve_offset(
    motion: Motion, audio: Audio, offset: float | str | None, max_offset: float | None, min_confidence: float
) -> dict[str, Any]:
    if offset is None or offset == "auto":
        est = estimate_offset(motion, audio, max_offset=max_offset, min_confidence=min_confidence)
        return {
            "seconds": est.offset,
            "source": est.method,
            "confidence": est.confidence,
            "candidates": est.candidates[:5],
            **({"events": est.detail} if est.detail else {}),
        }
    try:
        seconds = float(offset)
    except (TypeError, ValueError):
        raise KinectDataError(f"offset must be a number of seconds or 'auto', not {offset!r}") from None
    if not math.isfinite(seconds):
        raise KinectDataError(f"offset must be finite, not {offset!r}")
    return {"seconds": seconds, "source": "given", "confidence": 1.0}


def align(
    motion: Motion,
    audio: Audio,
    *,
    fps: float = DEFAULT_FPS,
    offset: float | str | None = "auto",
    max_gap: float = DEFAULT_MAX_GAP,
    min_coverage: float = DEFAULT_MIN_COVERAGE,
    max_offset: float | None = None,
    min_confidence: float = 0.5,
) -> AlignedRecording:
    """Put a recording and its audio on one exact timeline.

    Args:
        motion: the skeleton recording, on its own clock.
        audio: mono audio (its rate is kept; :func:`load_audio` gives 16 kHz).
        fps: output frame rate (frames per second).
        offset: seconds with ``audio_time = motion_time + offset``, or "auto" to estimate it
            (:func:`kinectdata.offset.estimate_offset`).
        max_gap: longest tracking gap (seconds without data) filled by interpolation; longer
            gaps stay masked and are reported.
        min_coverage: least share (0..1) of the motion's duration the audio must cover.
        max_offset, min_confidence: passed to the offset estimator.

    Raises:
        AlignmentError: no reliable offset, or too little overlap between audio and motion.
    """
    if fps <= 0 or not math.isfinite(fps):
        raise KinectDataError(f"fps must be a positive number, not {fps}")
    if motion.n_frames < 2:
        raise AlignmentError(
            f"{motion.metadata.get('source', 'the recording')}: needs at least 2 frames, has {motion.n_frames}"
        )
    off = _resolve_offset(motion, audio, offset, max_offset, min_confidence)
    o = off["seconds"]
    sr = audio.sample_rate
    m0, m1 = float(motion.times[0]), float(motion.times[-1])
    start = max(0.0, m0 + o)
    end = min(audio.duration, m1 + o)
    covered = max(0.0, end - start)
    coverage = covered / (m1 - m0)
    if coverage < min_coverage:
        src = audio.source.get("path", "the audio")
        raise AlignmentError(
            f"{src}: the audio ({audio.duration:.2f} s) covers only {covered:.2f} s ({100 * coverage:.0f}%) of the "
            f"motion's {m1 - m0:.2f} s at offset {o:+.3f} s (audio_time = motion_time + offset); at least "
            f"{100 * min_coverage:.0f}% is required. The audio is shorter than the motion, or the offset is wrong "
            f"(--min-coverage lowers the requirement)."
        )
    first_sample = math.ceil(start * sr - 1e-6)
    t0 = first_sample / sr
    # frame k (at t0 + k / fps on the audio clock) needs motion up to its time and audio for its
    # whole period [t, t + 1 / fps)
    n_motion = math.floor((m1 + o - t0) * fps + 1e-9) + 1
    n_audio = math.floor((audio.samples.size - first_sample) / sr * fps + 1e-9)
    n = min(n_motion, n_audio)
    if n < 2:
        raise AlignmentError(
            f"{audio.source.get('path', 'the audio')}: audio ({audio.duration:.2f} s) and motion "
            f"({m1 - m0:.2f} s) overlap by less than two frames at offset {o:+.3f} s"
        )
    grid = np.clip(t0 + np.arange(n) / fps - o, m0, m1)
    res = resample_motion(motion, grid, max_gap=max_gap)
    out = res.motion
    out.times = np.arange(n) / fps
    samples = audio.samples[first_sample : first_sample + int(round(n * sr / fps))]

    long_gaps = [
        {
            "joint": g.joint,
            "quantity": g.quantity,
            "start_s": round(g.start + o - t0, 4),
            "end_s": round(g.end + o - t0, 4),
            "length_s": round(g.length, 4),
            "edge": g.edge,
        }
        for g in res.gaps
        if g.length > max_gap + 1e-9 and g.end + o > t0 and g.start + o < t0 + n / fps
    ]
    timing = motion.timing()
    valid_any = out.position_mask | res.position_interpolated
    summary = {
        "frames": n,
        "duration_s": n / fps,
        "fps": fps,
        "sample_rate": sr,
        "audio_samples": int(samples.size),
        "source_frames": motion.n_frames,
        "source_fps": timing["fps"],
        "source_jitter_ms": timing["jitter_ms"],
        "dropped_frames": timing["dropped_frames"],
        "motion_trimmed_start_s": t0 - o - m0,
        "motion_trimmed_end_s": m1 - (grid[-1] if n else m0),
        "audio_trimmed_start_s": t0,
        "audio_trimmed_end_s": audio.duration - (first_sample + samples.size) / sr,
        "interpolated_share": float(res.position_interpolated.mean()),
        "masked_share": float(1.0 - valid_any.mean()),
        "long_gaps": len(long_gaps),
        "offset_s": o,
        "offset_source": off["source"],
        "offset_confidence": off["confidence"],
    }
    if res.orientation_interpolated is not None:
        can = motion.joint_set.orientation_mask[None, :]
        summary["orientation_interpolated_share"] = (
            float(res.orientation_interpolated[:, can[0]].mean()) if can.any() else 0.0
        )
    out.metadata["time_origin"] = {"value": t0, "unit": "s", "clock": "audio"}
    return AlignedRecording(
        motion=out,
        audio=samples,
        sample_rate=sr,
        fps=fps,
        position_interpolated=res.position_interpolated,
        orientation_interpolated=res.orientation_interpolated,
        offset=off,
        provenance={"motion": dict(motion.metadata), "audio": dict(audio.source)},
        summary=summary,
        gaps=long_gaps,
    )


def align_files(
    recording: str | Path,
    audio_path: str | Path,
    out: str | Path | None = None,
    *,
    format: str | None = None,
    schema: str | None = None,
    body: str | None = None,
    sample_rate: int = DEFAULT_SAMPLE_RATE,
    **options: Any,
) -> AlignedRecording:
    """Read a recording and an audio file, align them (:func:`align`) and write ``out`` (HDF5).

    ``format``, ``schema`` and ``body`` go to the reader; other options to :func:`align`.
    Nothing is written when anything fails.
    """
    motion = read_motion(recording, format=format, schema=schema, body=body)
    audio = load_audio(audio_path, sample_rate=sample_rate)
    result = align(motion, audio, **options)
    result.provenance["motion"].update({"path": str(recording), "sha256": file_sha256(recording)})
    result.provenance["audio"].update({"path": str(audio_path), "sha256": file_sha256(audio_path)})
    result.provenance["options"] = {
        "format": format,
        "schema": schema,
        "body": body,
        "sample_rate": sample_rate,
        **{k: v for k, v in options.items()},
    }
    if out is not None:
        result.save(out)
    return result


def format_summary(rec: AlignedRecording) -> str:
    """The human-readable summary ``kinectdata align`` prints."""
    s = rec.summary
    off = rec.offset
    lines = [
        f"frames          {s['frames']} at {s['fps']:g} fps = {s['duration_s']:.3f} s; "
        f"audio {s['audio_samples']} samples at {s['sample_rate']} Hz",
        f"source          {s['source_frames']} frames, {s['source_fps']:.2f} fps (median), "
        f"jitter {s['source_jitter_ms']:.2f} ms, {s['dropped_frames']} dropped",
        f"trimmed         motion {s['motion_trimmed_start_s']:.3f} s at start, "
        f"{s['motion_trimmed_end_s']:.3f} s at end; "
        f"audio {s['audio_trimmed_start_s']:.3f} s at start, {s['audio_trimmed_end_s']:.3f} s at end",
        f"gaps            {100 * s['interpolated_share']:.2f}% of joint positions interpolated, "
        f"{100 * s['masked_share']:.2f}% masked, {s['long_gaps']} gap(s) longer than max-gap",
    ]
    if "orientation_interpolated_share" in s:
        lines.append(f"orientations    {100 * s['orientation_interpolated_share']:.2f}% interpolated")
    lines.append(
        f"offset          {off['seconds']:+.4f} s ({off['source']}, confidence {off['confidence']:.2f}); "
        "audio_time = motion_time + offset"
    )
    for g in rec.gaps[:10]:
        span = f"{g['start_s']:.3f}-{g['end_s']:.3f} s ({g['length_s']:.3f} s)"
        where = ", at the recording's edge" if g["edge"] else ""
        lines.append(f"  masked gap    {g['joint']} {g['quantity']}: {span}{where}")
    if len(rec.gaps) > 10:
        lines.append(f"  ... and {len(rec.gaps) - 10} more masked gaps")
    return "\n".join(lines)
