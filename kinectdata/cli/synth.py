"""``kinectdata synth``: deterministic synthetic sessions (music + dancing Kinect skeleton, as a Kinect
CSV file or as OpenPose 2-D keypoint files)."""

from __future__ import annotations

import click
from click.core import ParameterSource

from kinectdata.core.errors import ConfigError

DIALECTS = ("dumpkinectskeleton", "kinectreader", "lsl_kinect", "canonical")
MAX_DURATION_S = 600.0  # the generator needs about 5 MB of memory per second of audio


@click.command()
@click.argument("out_dir", type=click.Path(file_okay=False, path_type=str))
@click.option(
    "--seed",
    default=0,
    show_default=True,
    type=click.IntRange(min=0),
    help="Random seed; the same options give identical files.",
)
@click.option(
    "--count",
    default=1,
    show_default=True,
    type=click.IntRange(min=1),
    help="Number of sessions, with seeds SEED, SEED+1, ...",
)
@click.option(
    "--duration",
    default=30.0,
    show_default=True,
    type=click.FloatRange(min=8, max=MAX_DURATION_S),
    help="Audio length in seconds (the skeleton recording is a little shorter).",
)
@click.option(
    "--tempo",
    default=None,
    type=click.FloatRange(min=30, max=300),
    metavar="BPM",
    help="Tempo in beats per minute. Default: drawn from 96..128 by the seed.",
)
@click.option(
    "--offset",
    default=None,
    type=click.FloatRange(min=-5, max=MAX_DURATION_S),
    metavar="SECONDS",
    help="Audio-to-motion offset, audio_time = motion_time + offset. Default: drawn from -1.5..2.5 s.",
)
@click.option("--no-clap", is_flag=True, help="Leave out the sync clap (offset estimation must then refuse).")
@click.option(
    "--sample-rate",
    default=44100,
    show_default=True,
    type=click.IntRange(min=8000),
    help="Audio sample rate in Hz (stereo).",
)
@click.option(
    "--dialect",
    default="dumpkinectskeleton",
    show_default=True,
    type=click.Choice(DIALECTS),
    help="CSV dialect of the skeleton file.",
)
@click.option(
    "--audio-format",
    default="flac",
    show_default=True,
    type=click.Choice(["flac", "wav"]),
    help="Audio file format (16-bit).",
)
@click.option(
    "--format",
    "output_format",
    default="csv",
    show_default=True,
    type=click.Choice(["csv", "openpose"]),
    help="csv: a Kinect v2 skeleton file; openpose: a folder of OpenPose BODY_25 keypoint files of a video.",
)
@click.option(
    "--video-fps",
    default=30.0,
    show_default=True,
    type=click.FloatRange(min=1, max=240),
    help="Video frame rate of --format openpose, frames per second.",
)
@click.option("--name", default=None, help="File name stem. Default: synth_<seed>.")
def synth(
    out_dir,
    seed,
    count,
    duration,
    tempo,
    offset,
    no_clap,
    sample_rate,
    dialect,
    audio_format,
    output_format,
    video_fps,
    name,
) -> None:
    """Write synthetic sessions to OUT_DIR: <name>.csv (Kinect v2 skeleton with sensor jitter,
    noise, tracking losses), <name>.flac (music with a clear beat and a sync clap) and
    <name>.truth.json (tempo, beat times, offset, clap times, the command that remakes it).

    With --format openpose, <name>_openpose/ replaces the CSV file: one OpenPose --write_json file
    per video frame (BODY_25 keypoints in pixels of a 1920x1080 colour camera, with detection noise,
    missed keypoints and a passer-by); the truth file adds an "openpose" section."""
    from kinectdata.synth import synthesize_recording, write_openpose_recording, write_recording  # slow imports

    if name is not None and count > 1:
        raise click.UsageError("--name applies to a single session; with --count the names are synth_<seed>")
    typed = {p for p in ("dialect", "video_fps") if _typed(p)}
    if output_format == "openpose" and "dialect" in typed:
        raise click.UsageError("--dialect applies to --format csv")
    if output_format == "csv" and "video_fps" in typed:
        raise click.UsageError("--video-fps applies to --format openpose")
    for s in range(seed, seed + count):
        try:
            rec = synthesize_recording(
                seed=s, duration_s=duration, tempo_bpm=tempo, offset_s=offset, clap=not no_clap, sample_rate=sample_rate
            )
        except ConfigError as exc:  # the generator's own checks of option combinations: a usage error
            raise click.UsageError(str(exc)) from exc
        stem = name or f"synth_{s:03d}"
        if output_format == "openpose":
            paths = write_openpose_recording(rec, out_dir, stem, video_fps=video_fps, audio_format=audio_format)
        else:
            paths = write_recording(rec, out_dir, stem, dialect=dialect, audio_format=audio_format)
        t = rec.truth
        click.echo(
            f"{stem}: {t['tempo_bpm']:.1f} BPM, offset {t['offset_s']:+.3f} s, "
            f"{t['motion_duration_s']:.1f} s of motion -> " + ", ".join(str(p) for p in paths.values())
        )


def _typed(param: str) -> bool:
    """Whether an option was given on the command line (not its default)."""
    return click.get_current_context().get_parameter_source(param) == ParameterSource.COMMANDLINE


COMMANDS = [synth]
