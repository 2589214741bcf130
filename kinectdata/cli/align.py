"""``kinectdata align``: a recording and its music on one exact timeline."""

from __future__ import annotations

import click

from kinectdata.align.audio import DEFAULT_SAMPLE_RATE
from kinectdata.align.offset import DEFAULT_MIN_CONFIDENCE
from kinectdata.align.recipe import DEFAULT_FPS, DEFAULT_MAX_GAP, DEFAULT_MIN_COVERAGE, align_files, format_summary
from kinectdata.cli.options import OffsetType, reader_options


@click.command()
@click.argument("recording", type=click.Path(dir_okay=True, path_type=str))
@click.argument("audio", required=False, type=click.Path(dir_okay=False, path_type=str))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(dir_okay=False, path_type=str),
    help="Output HDF5 file (written atomically: nothing appears if anything fails).",
)
@reader_options
@click.option(
    "--fps",
    default=DEFAULT_FPS,
    show_default=True,
    type=click.FloatRange(min=0, min_open=True),
    help="Output motion frame rate, frames per second; frame k is at exactly k / fps seconds.",
)
@click.option(
    "--sample-rate",
    default=DEFAULT_SAMPLE_RATE,
    show_default=True,
    type=click.IntRange(min=1000),
    help="Output audio sample rate in Hz (mono, band-limited resampling).",
)
@click.option(
    "--offset",
    default="auto",
    show_default=True,
    type=OffsetType(),
    help="Audio-to-motion offset in seconds, audio_time = motion_time + offset (positive: the audio "
    "started first), or 'auto' to estimate it from a sync clap or by cross-correlation; an "
    "ambiguous estimate stops with an error.",
)
@click.option(
    "--max-offset",
    default=None,
    type=click.FloatRange(min=0),
    metavar="SECONDS",
    help="With --offset auto: ignore offsets larger than this many seconds.",
)
@click.option(
    "--min-confidence",
    default=DEFAULT_MIN_CONFIDENCE,
    show_default=True,
    type=click.FloatRange(0, 1),
    help="With --offset auto: least confidence (0..1) accepted.",
)
@click.option(
    "--max-gap",
    default=DEFAULT_MAX_GAP,
    show_default=True,
    type=click.FloatRange(min=0),
    help="Longest tracking gap, in seconds without data, filled by interpolation (and flagged); "
    "longer gaps stay masked and are reported.",
)
@click.option(
    "--timeline",
    default=None,
    type=click.Path(dir_okay=False, path_type=str),
    metavar="FILE.oni",
    help="An .oni recorded with the skeleton: its depth frames' timestamps become the skeleton's "
    "times (one skeleton frame per depth frame).",
)
@click.option(
    "--min-coverage",
    default=DEFAULT_MIN_COVERAGE,
    show_default=True,
    type=click.FloatRange(0, 1),
    help="Least share (0..1) of the motion's duration the audio must cover.",
)
def align(
    recording,
    audio,
    out,
    reading,
    fps,
    sample_rate,
    offset,
    max_offset,
    min_confidence,
    max_gap,
    timeline,
    min_coverage,
) -> None:
    """Align a skeleton RECORDING with its AUDIO and write them to one HDF5 file.

    The motion is resampled onto an exact FPS grid (positions linearly, orientations by slerp
    after making quaternions sign-continuous), short tracking gaps are filled and flagged, the
    audio is read (WAV, FLAC, OGG, MP3...), mixed to mono and resampled, and both are trimmed to
    the span they share. A summary is printed.

    RECORDING may be a take folder written by `kinectdata capture` (no AUDIO then): its skeleton
    and audio are aligned with the offset from the take's clock stamps.
    """
    from kinectdata.align.take import align_take
    from kinectdata.capture.take import is_take

    common = {
        **reading,
        "sample_rate": sample_rate,
        "timeline": timeline,
        "fps": fps,
        "max_gap": max_gap,
        "min_coverage": min_coverage,
    }
    if is_take(recording):
        if audio is not None:
            raise click.UsageError("a take folder brings its own audio; give no AUDIO")
        if offset != "auto":
            raise click.UsageError("a take's offset comes from its clock stamps; give no --offset")
        if timeline is not None:
            raise click.UsageError("a take's skeleton is already on its .oni's timeline; give no --timeline")
        result = align_take(recording, out, **common)
    elif audio is None:
        raise click.UsageError("missing AUDIO (only a take folder brings its own)")
    else:
        result = align_files(
            recording, audio, out, offset=offset, max_offset=max_offset, min_confidence=min_confidence, **common
        )
    click.echo(format_summary(result))
    click.echo(f"wrote {out}")


COMMANDS = [align]
