"""``kinectdata synth``: deterministic synthetic sessions (music + dancing Kinect skeleton)."""

from __future__ import annotations

import click

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
@click.option("--name", default=None, help="File name stem. Default: synth_<seed>.")
def synth(out_dir, seed, count, duration, tempo, offset, no_clap, sample_rate, dialect, audio_format, name) -> None:
    """Write synthetic sessions to OUT_DIR: <name>.csv (Kinect v2 skeleton with sensor jitter,
    noise, tracking losses), <name>.flac (music with a clear beat and a sync clap) and
    <name>.truth.json (tempo, beat times, offset, clap times, the command that remakes it)."""
    from ..synth import synthesize_recording, write_recording  # the generator's imports are slow

    if name is not None and count > 1:
        raise click.UsageError("--name applies to a single session; with --count the names are synth_<seed>")
    for s in range(seed, seed + count):
        try:
            rec = synthesize_recording(
                seed=s, duration_s=duration, tempo_bpm=tempo, offset_s=offset, clap=not no_clap, sample_rate=sample_rate
            )
        except ValueError as exc:  # the generator's own checks of option combinations
            raise click.UsageError(str(exc)) from exc
        stem = name or f"synth_{s:03d}"
        paths = write_recording(rec, out_dir, stem, dialect=dialect, audio_format=audio_format)
        t = rec.truth
        click.echo(
            f"{stem}: {t['tempo_bpm']:.1f} BPM, offset {t['offset_s']:+.3f} s, "
            f"{t['motion_duration_s']:.1f} s of motion -> " + ", ".join(str(p) for p in paths.values())
        )


COMMANDS = [synth]
