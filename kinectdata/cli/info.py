"""``kinectdata info`` and ``kinectdata formats``."""

from __future__ import annotations

import click
import numpy as np

from kinectdata.cli.options import reader_options
from kinectdata.core.jointsets import load_joint_set, shipped_joint_sets
from kinectdata.core.resources import load_json, shipped_names, shipped_path
from kinectdata.formats import read_motion, readers
from kinectdata.formats.csv_schema import load_csv_schema, shipped_csv_schemas


@click.command()
@click.argument("recording", type=click.Path(dir_okay=True, path_type=str))
@reader_options
def info(
    recording: str,
    reading: dict,
) -> None:
    """Show what a skeleton RECORDING holds: format, joints, frames, timing, tracking. An aligned
    .h5 written by `kinectdata align` shows its motion, audio and offset; an .oni or .mkv sensor
    recording, what `kinectdata oni info` or `kinectdata mkv info` shows; a take folder from
    `kinectdata capture`, its recording, audio, offset and skeleton."""
    from kinectdata.capture.take import describe_take, is_take

    if is_take(recording):
        click.echo("\n".join(describe_take(recording)))
        return
    if recording.lower().endswith((".h5", ".hdf5")):
        from kinectdata.align.aligned import AlignedRecording

        click.echo(aligned_lines(recording, AlignedRecording.load(recording)))
        return
    sensor = None if reading.get("format") else _sensor_recording(recording)
    if sensor is not None:
        click.echo(sensor)
        return
    m = read_motion(recording, **reading)
    t = m.timing()
    md = m.metadata
    click.echo(f"file            {recording}")
    click.echo(f"format          {md.get('format')}" + (f" (schema {md['schema']})" if "schema" in md else ""))
    click.echo(f"joint set       {m.joint_set.name} ({m.n_joints} joints, {m.joint_set.dimensions}-D)")
    if "bodies" in md:
        click.echo(
            f"body            {md['body']} of " + ", ".join(f"{b} ({n} frames)" for b, n in md["bodies"].items())
        )
    if "people" in md:
        click.echo(
            f"person          {md['person']} of "
            + ", ".join(f"{p} ({n} frames)" for p, n in md["people"].items())
            + f"; {md['layout']} keypoints at {md['video_fps']:g} fps"
        )
    if m.n_frames < 2:
        click.echo(f"frames          {m.n_frames}: no frame rate from a single frame")
    else:
        click.echo(
            f"frames          {m.n_frames} over {m.duration:.3f} s; {t['fps']:.2f} fps (mean interval "
            f"{t['interval_ms']:.2f} ms), jitter {t['jitter_ms']:.2f} ms, {t['dropped_frames']} dropped"
        )
    for line in _timing_doubts(md, t) + _frozen_lines(m):
        click.echo(line)
    click.echo(
        f"positions       {100 * m.position_mask.mean():.1f}% valid; mean confidence {np.mean(m.confidence):.3f}"
    )
    for line in _implausible_lines(m):
        click.echo(line)
    if md.get("confidences_clipped"):
        click.echo(f"confidences     {md['confidences_clipped']} above 1 (as OpenPose writes at times), clipped to 1")
    if m.has_orientations:
        can = m.joint_set.orientation_mask
        share = m.orientation_mask[:, can].mean() if can.any() else 0.0
        click.echo(f"orientations    {100 * share:.1f}% valid (of joints that carry one)")
    else:
        click.echo("orientations    none in this format")
    for line in _body_lines(m):
        click.echo(line)


def _sensor_recording(path: str) -> str | None:
    """What ``oni info`` or ``mkv info`` prints, for a depth sensor's own recording (frames, not a
    skeleton: it has its own commands), known by its first bytes; None for anything else."""
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError:
        return None  # the reader says what is wrong with it
    if head == b"\x1a\x45\xdf\xa3":
        from kinectdata.mkv.export import describe, format_description

        return format_description(describe(path)) + "\n(depth, colour and IMU frames, not a skeleton: kinectdata mkv)"
    if head == b"NI10":
        from kinectdata.oni.export import describe, format_description

        return format_description(describe(path)) + "\n(depth and colour frames, not a skeleton: kinectdata oni)"
    return None


def _body_lines(motion) -> list[str]:
    """The bone lengths and the unit, up-axis and speed doubts of a 3-D recording
    (:mod:`kinectdata.core.body_checks`)."""
    from kinectdata.core import body_checks

    if motion.joint_set.dimensions != 3:
        return []
    lines = []
    bones = body_checks.bone_lengths(motion)
    if bones:
        shortest, longest = min(bones, key=bones.get), max(bones, key=bones.get)
        lines.append(
            f"bones           {len(bones)}, median length {np.median(list(bones.values())):.3g} m (shortest "
            f"{shortest} {bones[shortest]:.3g} m, longest {longest} {bones[longest]:.3g} m)"
        )
    for label, doubt in (
        ("unit", body_checks.unit_doubt(motion)),
        ("up axis", body_checks.up_axis_doubt(motion)),
        ("speed", body_checks.speed_doubt(motion)),
    ):
        if doubt is not None:
            lines.append(f"{label:<15} {doubt}")
    return lines


@click.command()
def formats() -> None:
    """List the readers, the writers, the sensor recordings read by their own commands, shipped CSV
    dialects, array schemas and joint sets."""
    click.echo("readers (--format):")
    for name, r in sorted(readers().items()):
        exts = ", ".join(r.extensions) or ("by content" if r.sniff else "--format only")
        click.echo(f"  {name:<14} {exts:<13} {r.description}")
    from kinectdata.apps.convert import writers

    click.echo("writers (kinectdata convert, by the output's extension or --format):")
    for name, w in sorted(writers().items()):
        click.echo(f"  {name:<14} {', '.join(w.extensions):<13} {w.description}")
    click.echo("sensor recordings (depth, colour, IMU frames; their own commands):")
    click.echo(f"  {'oni':<14} {'.oni':<13} OpenNI 1.x and OpenNI2 recordings (Kinect v1, Xtion): kinectdata oni")
    click.echo(f"  {'mkv':<14} {'.mkv':<13} Azure Kinect and Orbbec Femto k4arecorder recordings: kinectdata mkv")
    click.echo("CSV dialects (--schema):")
    for name in shipped_csv_schemas():
        click.echo(f"  {name:<20} {_headline(load_csv_schema(name).get('description', ''))}")
    click.echo("array schemas (--schema, for --format arrays):")
    for name in shipped_names("arrays"):
        click.echo(f"  {name:<26} {_headline(load_json(shipped_path('arrays', name)).get('description', ''))}")
    click.echo("joint sets:")
    for name in shipped_joint_sets():
        js = load_joint_set(name)
        click.echo(f"  {name:<14} {len(js)} joints, {js.dimensions}-D")


def _headline(text: str, width: int = 76) -> str:
    """The part of a description before its first colon or full stop, cut at a word."""
    head = text.split(": ")[0].split(". ")[0]
    return head if len(head) <= width else head[: width - 3].rsplit(" ", 1)[0] + "..."


COMMANDS = [info, formats]


DECLARED_RATE_TOLERANCE = 0.02
"""A declared frame rate more than this share away from the timestamps' is reported."""


def _declared_fps(metadata: dict) -> tuple[str, float] | None:
    """A frame rate the file itself declares (a recorder's preamble ``Stream nominal rate : 30``,
    a ``# fps: 30`` comment): (where, value), or None."""
    for key, value in (metadata.get("file_metadata") or {}).items():
        words = key.lower()
        if "rate" in words or "fps" in words or "frequency" in words:
            try:
                number = float(str(value).split()[0])
            except (ValueError, IndexError):
                continue
            if number > 0:
                return key, number
    return None


def _timing_doubts(metadata: dict, timing: dict) -> list[str]:
    """The line for a frame rate the file declares (:func:`_declared_fps`) and its timestamps
    contradict by more than :data:`DECLARED_RATE_TOLERANCE`, or none."""
    declared = _declared_fps(metadata)
    fps = timing["fps"]
    if declared is None or not np.isfinite(fps) or abs(declared[1] / fps - 1) <= DECLARED_RATE_TOLERANCE:
        return []
    return [
        f"declared rate   {declared[1]:g} fps in the file ({declared[0]}), but the timestamps give {fps:.2f} fps "
        f"({100 * (fps / declared[1] - 1):+.0f}%): the timestamps are used"
    ]


def _frozen_lines(motion) -> list[str]:
    """The line for runs of frozen frames (:meth:`~kinectdata.core.motion.Motion.frozen_runs`: a
    stalled tracker writing its last pose again), with their count, share of the frames, number of
    runs and the longest run (frames, seconds from the first frame), or none."""
    runs = motion.frozen_runs()
    if not runs:
        return []
    frozen = sum(n for _, n in runs)
    start, longest = max(runs, key=lambda r: r[1])
    t0 = float(motion.times[start - 1] - motion.times[0])  # the frame they repeat
    return [
        f"frozen frames   {frozen} repeat the frame before exactly ({100 * frozen / motion.n_frames:.1f}% of the "
        f"frames), in {len(runs)} run(s); the longest holds the pose of {t0:.3f} s for {longest} frame(s) "
        f"({motion.times[start + longest - 1] - motion.times[start - 1]:.3f} s): a stalled tracker; they count as "
        "tracked"
    ]


def _implausible_lines(motion) -> list[str]:
    """The line for valid values that cannot be true (positions not finite or beyond
    :data:`~kinectdata.align.recipe.MAX_ABS_POSITION`, orientations that are not unit
    quaternions), which ``align`` masks as tracking loss, with the first frame holding one; or none."""
    from kinectdata.align.recipe import describe_position_limit, implausible_values

    positions, orientations = implausible_values(motion)
    bad = positions | (orientations if orientations is not None else False)
    if not bad.any():
        return []
    frame = int(np.flatnonzero(bad.any(axis=1))[0])
    return [
        f"implausible     {int(positions.sum())} position(s) not finite or beyond "
        f"{describe_position_limit(motion.joint_set.dimensions)}"
        + (f", {int(orientations.sum())} orientation(s) not unit quaternions" if orientations is not None else "")
        + f", first at frame {frame} ({motion.times[frame] - motion.times[0]:.3f} s): align masks them as tracking loss"
    ]


def aligned_lines(path: str, rec) -> str:
    """What ``info`` (and ``inspect``) show of an aligned recording (an
    :class:`~kinectdata.align.aligned.AlignedRecording` read from ``path``): frames, frame rate
    and duration, the audio's rate and length, the offset, and how valid the joints are."""
    m = rec.motion
    off = rec.offset
    offset = "none recorded"
    if off is not None:
        estimated = off.confidence is not None and off.source != "given"
        sure = f", confidence {off.confidence:.2f}" if estimated else ""
        offset = f"{off.seconds:+.3f} s ({off.source}){sure}"
    lines = [
        f"file            {path}",
        "format          aligned recording (kinectdata align)",
        f"joint set       {m.joint_set.name} ({m.n_joints} joints, {m.joint_set.dimensions}-D)",
        f"frames          {m.n_frames} at {rec.fps:g} fps, {m.n_frames / rec.fps:.3f} s",
        f"audio           {rec.audio.size} samples at {rec.sample_rate} Hz, {rec.audio.size / rec.sample_rate:.3f} s",
        f"offset          {offset}: audio time = motion time + offset",
        f"positions       {100 * m.position_mask.mean():.1f}% valid, {100 * rec.position_interpolated.mean():.1f}% "
        f"filled across gaps; {len(rec.gaps)} gaps longer than the fill limit",
        *_aligned_joint_lines(rec),
    ]
    implausible = rec.summary.get("implausible_positions", 0) + rec.summary.get("implausible_orientations", 0)
    if implausible:
        lines.append(f"implausible     {implausible} value(s) of the source masked as tracking loss when aligned")
    sources = rec.provenance.motion.get("path"), rec.provenance.audio.get("path")
    if any(sources):
        lines.append(f"aligned from    {sources[0]} + {sources[1]}")
    return "\n".join(lines)


SHOWN_JOINTS = 5
"""The least valid joints ``info`` names for an aligned file."""


def _aligned_joint_lines(rec) -> list[str]:
    """How valid each joint's position is in an aligned recording: how many joints are valid in
    every frame, and the least valid ones with their share of valid frames (filled ones included)."""
    m = rec.motion
    share = m.position_mask.mean(axis=0)
    filled = rec.position_interpolated.mean(axis=0)
    whole = int(np.sum(share == 1.0))
    if whole == m.n_joints:
        return [f"joints          all {m.n_joints} valid in every frame"]
    worst = [j for j in np.argsort(share, kind="stable") if share[j] < 1.0][:SHOWN_JOINTS]
    named = ", ".join(
        f"{m.joint_set.names[j]} {100 * share[j]:.1f}%" + (f" ({100 * filled[j]:.1f}% filled)" if filled[j] else "")
        for j in worst
    )
    return [f"joints          {whole} of {m.n_joints} valid in every frame; least valid: {named}"]
