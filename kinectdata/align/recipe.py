"""Aligning a skeleton recording with its music: one exact timeline, audio at 16 kHz mono.

:func:`align` is the library recipe; :func:`align_files` reads the inputs, aligns and writes the
HDF5 file (``kinectdata align`` is a thin command over it).

Timeline: with ``audio_time = motion_time + offset``, the output keeps the span both cover. Its
time 0 is the first audio sample inside that span and frame k is at ``k / fps`` on that clock.
The last frame is the last one that has motion at its time and audio for its whole frame period;
the output audio runs one more frame period past it where the source has it (per-frame analysis
windows reach slightly past their frame). The motion is resampled onto the
frame times (:mod:`kinectdata.align.timeline`). The audio must cover at least ``min_coverage`` of the
motion's duration; otherwise the pair is refused (audio shorter than the dance, or a wrong
offset), not silently trimmed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.align.aligned import AlignedRecording, Provenance
from kinectdata.align.audio import DEFAULT_SAMPLE_RATE, Audio, load_audio
from kinectdata.align.envelopes import AudioEnvelopes
from kinectdata.align.offset import DEFAULT_MIN_CONFIDENCE, OffsetChoice, estimate_offset
from kinectdata.align.timeline import Resampled, longer_than, resample_motion
from kinectdata.core.errors import AlignmentError, ConfigError, KinectDataError
from kinectdata.core.hashing import file_sha256
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import UNIT_TOLERANCE
from kinectdata.formats import read_motion

DEFAULT_FPS = 30.0
DEFAULT_MAX_GAP = 0.2
DEFAULT_MIN_COVERAGE = 0.9
MIN_AUTO_OFFSET_S = 2.0
"""A recording shorter than this (seconds) cannot have its offset estimated: give it."""


def resolve_offset(
    motion: Motion,
    audio: Audio | AudioEnvelopes,
    offset: float | str | None,
    *,
    max_offset: float | None = None,
    min_confidence: float = DEFAULT_MIN_CONFIDENCE,
) -> OffsetChoice:
    """The offset to use, with where it came from.

    ``offset`` is a number of seconds (source "given") or "auto"/None (estimated from the audio or
    its envelopes by :func:`kinectdata.align.offset.estimate_offset`, on the motion with its
    implausible values masked: :func:`mask_implausible`).

    Raises:
        AlignmentError: the recording or the audio is too short to estimate an offset (under
            :data:`MIN_AUTO_OFFSET_S`), or no estimate is reliable; the message names both.
    """
    if offset is None or offset == "auto":
        recording = motion.metadata.get("source", "the recording")
        heard = audio.source.get("path", "its audio") if isinstance(audio, Audio) else "its audio"
        if motion.duration < MIN_AUTO_OFFSET_S:
            raise AlignmentError(
                f"{recording}: {motion.n_frames} frame(s), {motion.duration:.2f} s: too short to find its offset to "
                f"{heard} (a clap or the music's rhythm needs at least {MIN_AUTO_OFFSET_S:g} s); give --offset SECONDS"
            )
        if audio.duration < MIN_AUTO_OFFSET_S:
            raise AlignmentError(
                f"{heard}: {audio.duration:.3f} s of audio: too short to find its offset to {recording} (a clap or the "
                f"music's rhythm needs at least {MIN_AUTO_OFFSET_S:g} s); give --offset SECONDS"
            )
        try:
            clean = mask_implausible(motion)[0]  # one overflowing value must not pass for a clap
            est = estimate_offset(clean, audio, max_offset=max_offset, min_confidence=min_confidence)
        except AlignmentError as exc:
            raise AlignmentError(f"{recording} with {heard}: {exc}") from None
        return OffsetChoice.from_estimate(est)
    try:
        seconds = float(offset)
    except (TypeError, ValueError):
        raise ConfigError(f"offset must be a number of seconds or 'auto', not {offset!r}") from None
    if not math.isfinite(seconds):
        raise ConfigError(f"offset must be finite, not {offset!r}")
    return OffsetChoice(seconds)


@dataclass(frozen=True)
class Timeline:
    """Where the output frames sit on the two source clocks.

    Output time 0 is audio sample ``first_sample``; output frame k is at ``k / fps`` seconds, i.e.
    at audio time ``first_sample / sample_rate + k / fps`` and motion time that minus ``offset``.
    """

    offset: float
    fps: float
    sample_rate: int
    first_sample: int
    n_frames: int

    @property
    def start(self) -> float:
        """Audio time (s) of output time 0."""
        return self.first_sample / self.sample_rate

    def motion_times(self) -> np.ndarray:
        """[N] motion-clock times (s) of the output frames."""
        return self.start + np.arange(self.n_frames) / self.fps - self.offset

    def kept_samples(self, available: int) -> int:
        """Audio samples an aligned recording keeps, of ``available`` in the source: its frames'
        periods and one period more where the source has it (per-frame analysis windows, such as
        534 samples at 30 fps, reach slightly past their frame)."""
        return min(available - self.first_sample, int(round((self.n_frames + 1) * self.sample_rate / self.fps)))

    def frame_starts(self) -> np.ndarray:
        """[N] int64 index of the audio sample at each output frame: ``first_sample + round(k * sr / fps)``."""
        return self.first_sample + np.round(np.arange(self.n_frames) * self.sample_rate / self.fps).astype(np.int64)


def plan_timeline(
    motion: Motion,
    audio_samples: int,
    sample_rate: int,
    offset: float,
    *,
    fps: float = DEFAULT_FPS,
    min_coverage: float = DEFAULT_MIN_COVERAGE,
    audio_name: str = "the audio",
) -> Timeline:
    """The common span of a recording and ``audio_samples`` samples of audio at ``offset``.

    Raises:
        AlignmentError: the audio covers less than ``min_coverage`` of the motion's duration, or
            they share fewer than two frames.
    """
    if fps <= 0 or not math.isfinite(fps):
        raise KinectDataError(f"fps must be a positive number, not {fps}")
    if motion.n_frames < 2:
        raise AlignmentError(
            f"{motion.metadata.get('source', 'the recording')}: needs at least 2 frames, has {motion.n_frames}"
        )
    sr, o = sample_rate, offset
    recording = motion.metadata.get("source", "the recording")
    duration = audio_samples / sr
    m0, m1 = float(motion.times[0]), float(motion.times[-1])
    start = max(0.0, m0 + o)
    covered = max(0.0, min(duration, m1 + o) - start)
    coverage = covered / (m1 - m0)
    if coverage < min_coverage:
        raise AlignmentError(
            f"{audio_name}: the audio ({duration:.2f} s) covers only {covered:.2f} s ({100 * coverage:.0f}%) of the "
            f"motion's {m1 - m0:.2f} s ({recording}) at offset {o:+.3f} s (audio_time = motion_time + offset); at "
            f"least {100 * min_coverage:.0f}% is required. The audio is shorter than the motion, or the offset is "
            "wrong (--min-coverage lowers the requirement)."
        )
    first_sample = math.ceil(start * sr - 1e-6)
    t0 = first_sample / sr
    # frame k (at t0 + k / fps on the audio clock) needs motion up to its time and audio for its
    # whole period [t, t + 1 / fps)
    n_motion = math.floor((m1 + o - t0) * fps + 1e-9) + 1
    n_audio = math.floor((audio_samples - first_sample) / sr * fps + 1e-9)
    n = min(n_motion, n_audio)
    if n < 2:
        raise AlignmentError(
            f"{audio_name}: audio ({duration:.2f} s) and motion ({m1 - m0:.2f} s, {recording}) overlap by less than "
            f"two frames at offset {o:+.3f} s"
        )
    return Timeline(offset=o, fps=fps, sample_rate=sr, first_sample=first_sample, n_frames=n)


def resample_onto(motion: Motion, timeline: Timeline, max_gap: float = DEFAULT_MAX_GAP) -> tuple[Resampled, list]:
    """The motion at the timeline's frames (times k / fps), and the gaps longer than ``max_gap``
    on the output clock. Implausible values are masked first (:func:`mask_implausible`): they are
    tracking loss, filled or masked like any other."""
    motion = mask_implausible(motion)[0]
    m0, m1 = float(motion.times[0]), float(motion.times[-1])
    res = resample_motion(motion, np.clip(timeline.motion_times(), m0, m1), max_gap=max_gap)
    res.motion.times = np.arange(timeline.n_frames) / timeline.fps
    res.motion.metadata["time_origin"] = {"value": timeline.start, "unit": "s", "clock": "audio"}
    shift = timeline.offset - timeline.start  # source motion time -> output time
    end = timeline.n_frames / timeline.fps
    long_gaps = [
        {
            "joint": g.joint,
            "quantity": g.quantity,
            "start_s": round(g.start + shift, 4),
            "end_s": round(g.end + shift, 4),
            "length_s": round(g.length, 4),
            "edge": g.edge,
        }
        for g in res.gaps
        if bool(longer_than(g.length, max_gap)) and g.end + shift > 0 and g.start + shift < end
    ]
    return res, long_gaps


def summarize(
    source: Motion, timeline: Timeline, res: Resampled, long_gaps: list, offset: dict, audio_samples: int, kept: int
) -> dict[str, Any]:
    """The figures ``align`` prints and stores (see :func:`format_summary`); ``source`` is the
    recording as read (its implausible values are counted here)."""
    tl, sr = timeline, timeline.sample_rate
    timing = source.timing()
    bad_positions, bad_orientations = implausible_values(source)
    valid_any = res.motion.position_mask | res.position_interpolated
    last_frame_motion_time = tl.start + (tl.n_frames - 1) / tl.fps - tl.offset
    summary = {
        "frames": tl.n_frames,
        "duration_s": tl.n_frames / tl.fps,
        "fps": tl.fps,
        "sample_rate": sr,
        "audio_samples": kept,
        "source_frames": source.n_frames,
        "source_fps": timing["fps"],
        "source_clock": source.metadata.get("time_source", "the timestamps"),
        "source_jitter_ms": timing["jitter_ms"],
        "dropped_frames": timing["dropped_frames"],
        "motion_trimmed_start_s": tl.start - tl.offset - float(source.times[0]),
        "motion_trimmed_end_s": float(source.times[-1]) - last_frame_motion_time,
        "audio_trimmed_start_s": tl.start,
        "audio_trimmed_end_s": (audio_samples - tl.first_sample - kept) / sr,
        "interpolated_share": float(res.position_interpolated.mean()),
        "masked_share": float(1.0 - valid_any.mean()),
        "long_gaps": len(long_gaps),
        "offset_s": tl.offset,
        "offset_source": offset.source,
        "offset_confidence": offset.confidence,
        "implausible_positions": int(bad_positions.sum()),
        "implausible_orientations": int(bad_orientations.sum()) if bad_orientations is not None else 0,
    }
    if res.orientation_interpolated is not None:
        can = source.joint_set.orientation_mask
        summary["orientation_interpolated_share"] = (
            float(res.orientation_interpolated[:, can].mean()) if can.any() else 0.0
        )
    return summary


def align(
    motion: Motion,
    audio: Audio,
    *,
    fps: float = DEFAULT_FPS,
    offset: float | str | None = "auto",
    max_gap: float = DEFAULT_MAX_GAP,
    min_coverage: float = DEFAULT_MIN_COVERAGE,
    max_offset: float | None = None,
    min_confidence: float = DEFAULT_MIN_CONFIDENCE,
) -> AlignedRecording:
    """Put a recording and its audio on one exact timeline.

    Args:
        motion: the skeleton recording, on its own clock.
        audio: mono audio (its rate is kept; :func:`load_audio` gives 16 kHz).
        fps: output frame rate (frames per second).
        offset: seconds with ``audio_time = motion_time + offset``, or "auto" to estimate it
            (:func:`kinectdata.align.offset.estimate_offset`).
        max_gap: longest tracking gap (seconds without data) filled by interpolation; longer
            gaps stay masked and are reported.
        min_coverage: least share (0..1) of the motion's duration the audio must cover.
        max_offset, min_confidence: passed to the offset estimator.

    Raises:
        AlignmentError: no reliable offset, or too little overlap between audio and motion.

    Positions that are not finite or absurdly far (a recorder's overflow: 1e300, inf) and
    orientations that are not unit quaternions are masked as tracking loss and counted in the
    summary (:func:`mask_implausible` says why masked, not refused).
    """
    off = resolve_offset(motion, audio, offset, max_offset=max_offset, min_confidence=min_confidence)
    tl = plan_timeline(
        motion,
        audio.samples.size,
        audio.sample_rate,
        off.seconds,
        fps=fps,
        min_coverage=min_coverage,
        audio_name=audio.source.get("path", "the audio"),
    )
    res, long_gaps = resample_onto(motion, tl, max_gap)
    samples = audio.samples[tl.first_sample : tl.first_sample + tl.kept_samples(audio.samples.size)]
    return AlignedRecording(
        motion=res.motion,
        audio=samples,
        sample_rate=tl.sample_rate,
        fps=fps,
        position_interpolated=res.position_interpolated,
        orientation_interpolated=res.orientation_interpolated,
        offset=off,
        provenance=Provenance(motion=dict(motion.metadata), audio=dict(audio.source)),
        summary=summarize(motion, tl, res, long_gaps, off, audio.samples.size, samples.size),
        gaps=long_gaps,
    )


MAX_ABS_POSITION = {3: 1e3, 2: 1e6}
"""Largest believable coordinate by joint-set dimensions: 1 km in camera space (metres), 10^6
pixels in an image (2-D)."""


def position_limit(dimensions: int) -> float:
    """The largest believable coordinate (:data:`MAX_ABS_POSITION`) of a joint set of ``dimensions``."""
    return MAX_ABS_POSITION.get(dimensions, 1e6)


def describe_position_limit(dimensions: int) -> str:
    """:func:`position_limit` with its unit, for messages: ``1000 m``, ``1e+06 px``."""
    return f"{position_limit(dimensions):g} {'m' if dimensions == 3 else 'px'}"


def implausible_values(motion: Motion) -> tuple[np.ndarray, np.ndarray | None]:
    """Where a recording's valid values cannot be true.

    Returns:
        [T, J] bool: positions marked valid that are not finite or have a coordinate beyond
        :data:`MAX_ABS_POSITION` (metres for 3-D joint sets, pixels for 2-D ones); and [T, J] bool
        (None without orientations): orientations marked valid that are not finite or whose norm is
        more than :data:`~kinectdata.core.quaternions.UNIT_TOLERANCE` from 1.
    """
    limit = position_limit(motion.joint_set.dimensions)
    positions = np.zeros(motion.position_mask.shape, bool)
    orientations = None if motion.orientations is None else np.zeros(positions.shape, bool)
    # a block of frames at a time: the temporaries of a whole hour-long recording would be hundreds of MB
    for a in range(0, motion.n_frames, _CHECK_FRAMES):
        b = a + _CHECK_FRAMES
        with np.errstate(invalid="ignore", over="ignore"):
            positions[a:b] = motion.position_mask[a:b] & ~(np.abs(motion.positions[a:b]) <= limit).all(axis=-1)
            if orientations is not None:
                q = motion.orientations[a:b]
                norm = np.linalg.norm(np.where(np.abs(q) <= 2.0, q, np.inf), axis=-1)
                orientations[a:b] = motion.orientation_mask[a:b] & ~(np.abs(norm - 1.0) <= UNIT_TOLERANCE)
    return positions, orientations


_CHECK_FRAMES = 4096


def mask_implausible(motion: Motion) -> tuple[Motion, int]:
    """The motion with its :func:`implausible_values` masked as tracking loss, and how many joint
    values (positions and orientations) that was.

    Masked, not refused: such values come from a recorder's overflow or a corrupt field in one
    frame (1e300, inf), and the frames around them are sound; refusing would cost the whole take
    for one value, while masking makes it a gap like any untracked joint, filled or left masked
    by the same ``max_gap`` rule, and counted (``implausible_positions`` and
    ``implausible_orientations`` in ``align``'s summary, printed by :func:`format_summary`).
    The input is not changed.
    """
    positions, orientations = implausible_values(motion)
    count = int(positions.sum()) + (int(orientations.sum()) if orientations is not None else 0)
    if not count:
        return motion, 0
    cleaned = replace(
        motion,
        positions=np.where(positions[..., None], np.nan, motion.positions),
        position_mask=motion.position_mask & ~positions,
        confidence=np.where(positions, np.float32(0.0), motion.confidence),
        orientations=None if orientations is None else np.where(orientations[..., None], np.nan, motion.orientations),
        orientation_mask=None if orientations is None else motion.orientation_mask & ~orientations,
        metadata=dict(motion.metadata),
    )
    return cleaned, count


def align_files(
    recording: str | Path,
    audio_path: str | Path,
    out: str | Path | None = None,
    *,
    format: str | None = None,
    schema: str | None = None,
    body: str | None = None,
    person: str | None = None,
    video_fps: float | None = None,
    array_fps: float | None = None,
    unit: str | None = None,
    rest_joints: str | Path | None = None,
    sample_rate: int = DEFAULT_SAMPLE_RATE,
    timeline: str | Path | None = None,
    **options: Any,
) -> AlignedRecording:
    """Read a recording and an audio file, align them (:func:`align`) and write ``out`` (HDF5).

    ``format``, ``schema``, ``body``, ``person``, ``video_fps``, ``array_fps``, ``unit`` and ``rest_joints`` go
    to the reader;
    ``timeline``, an ``.oni`` recorded with the skeleton, gives its frames that recording's depth timestamps
    (:func:`kinectdata.oni.skeleton.retime`); other options go to :func:`align`. Nothing is
    written when anything fails.
    """
    motion = read_motion(
        recording,
        format=format,
        schema=schema,
        body=body,
        person=person,
        video_fps=video_fps,
        array_fps=array_fps,
        unit=unit,
        rest_joints=rest_joints,
    )
    if timeline is not None:
        from kinectdata.oni.skeleton import retime

        motion = retime(motion, timeline)
    audio = load_audio(audio_path, sample_rate=sample_rate)
    result = align(motion, audio, **options)
    result.provenance.motion.update({"path": str(recording), "sha256": file_sha256(recording)})
    result.provenance.audio.update({"path": str(audio_path), "sha256": file_sha256(audio_path)})
    result.provenance.options = {
        "format": format,
        "schema": schema,
        "body": body,
        "person": person,
        "video_fps": video_fps,
        "sample_rate": sample_rate,
        "timeline": None if timeline is None else str(timeline),
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
        f"source          {s['source_frames']} frames, {s['source_fps']:.2f} fps "
        f"(from {s.get('source_clock', 'the timestamps')}), "
        f"jitter {s['source_jitter_ms']:.2f} ms, {s['dropped_frames']} dropped",
        f"trimmed         motion {s['motion_trimmed_start_s']:.3f} s at start, "
        f"{s['motion_trimmed_end_s']:.3f} s at end; "
        f"audio {s['audio_trimmed_start_s']:.3f} s at start, {s['audio_trimmed_end_s']:.3f} s at end",
        f"gaps            {100 * s['interpolated_share']:.2f}% of joint positions interpolated, "
        f"{100 * s['masked_share']:.2f}% masked, {s['long_gaps']} gap(s) longer than max-gap",
    ]
    if s.get("implausible_positions") or s.get("implausible_orientations"):
        lines.append(
            f"implausible     {s.get('implausible_positions', 0)} joint position(s) not finite or beyond "
            f"{describe_position_limit(rec.motion.joint_set.dimensions)}, "
            f"{s.get('implausible_orientations', 0)} orientation(s) not finite or not unit quaternions: "
            "masked as tracking loss"
        )
    if "orientation_interpolated_share" in s:
        lines.append(f"orientations    {100 * s['orientation_interpolated_share']:.2f}% interpolated")
    lines.append(
        f"offset          {off.seconds:+.4f} s ({off.source}, confidence {off.confidence or 0:.2f}); "
        "audio_time = motion_time + offset"
    )
    for g in rec.gaps[:10]:
        span = f"{g['start_s']:.3f}-{g['end_s']:.3f} s ({g['length_s']:.3f} s)"
        where = ", at the recording's edge" if g["edge"] else ""
        lines.append(f"  masked gap    {g['joint']} {g['quantity']}: {span}{where}")
    if len(rec.gaps) > 10:
        lines.append(f"  ... and {len(rec.gaps) - 10} more masked gaps")
    return "\n".join(lines)
