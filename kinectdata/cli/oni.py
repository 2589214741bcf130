"""``kinectdata oni``: OpenNI ``.oni`` recordings (info, export)."""

from __future__ import annotations

import json

import click

from kinectdata.cli.progress import progress_bar


@click.group("oni")
def oni() -> None:
    """OpenNI .oni recordings (Kinect v1, PrimeSense, Xtion), read without OpenNI."""


@oni.command("info")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON.")
def info_command(file, as_json) -> None:
    """Show what FILE holds: streams, codecs, resolution, pixel format, frames, duration,
    nominal and measured fps, dropped frames and gaps, and whether the file is cut short."""
    import warnings

    from kinectdata.oni.export import describe, format_description

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the problems are printed below
        summary = describe(file)
    click.echo(json.dumps(summary, indent=2) if as_json else format_description(summary))


@oni.command("export")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--stream", default="depth", show_default=True, help="Stream: depth, image, ir, or a node name.")
@click.option("-o", "--out", required=True, type=click.Path(dir_okay=False), help="HDF5 file to write.")
@click.option("--start", type=float, default=None, help="First frame to keep, in seconds from the stream's first.")
@click.option("--end", type=float, default=None, help="Keep frames before this, in seconds from the stream's first.")
@click.option(
    "--compression", default="gzip", show_default=True, type=click.Choice(["gzip", "lzf", "none"]), help="HDF5 filter."
)
def export_command(file, stream, out, start, end, compression) -> None:
    """Decode one stream of FILE into an HDF5 file: frames [N, H, W] (uint16 depth in mm, or
    [N, H, W, 3] RGB), timestamps_us, time_s and frame_numbers, one frame per chunk."""
    import warnings

    from kinectdata.oni.export import export_stream

    with progress_bar("decoding", "frame") as progress, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        attrs = export_stream(file, out, stream, start_s=start, end_s=end, compression=compression, progress=progress)
    for w in caught:
        click.echo(f"warning: {w.message}", err=True)
    click.echo(
        f"wrote {out}: {attrs['stream']} ({attrs['codec']}, {attrs['width']}x{attrs['height']})"
        + (" from a recording cut short" if attrs["truncated"] else "")
    )


@oni.command("skeleton")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("-o", "--out", required=True, type=click.Path(dir_okay=False), help="Canonical skeleton CSV to write.")
@click.option(
    "--nite",
    "nite_dir",
    default=None,
    type=click.Path(file_okay=False),
    help="Folder with libNiTE2.so and its NiTE2/ data (default: $NITE2_REDIST64, ./NiTE2, /usr/lib...).",
)
@click.option("--user", type=int, default=None, help="NiTE user id. Default: the user tracked longest.")
def skeleton_command(file, out, nite_dir, user) -> None:
    """Track the dancer in FILE with NiTE2's user tracker (not shipped with kinectdata: it must be
    installed) and write the 15-joint skeleton (metres, quaternions x, y, z, w) as canonical CSV,
    its times the recording's own depth timestamps in seconds."""

    from kinectdata.formats.csv_writer import write_csv
    from kinectdata.oni.skeleton import track_skeleton

    with progress_bar("tracking", "frame") as progress:
        motion = track_skeleton(file, nite_dir=nite_dir, user=user, progress=progress)
    origin_s = motion.metadata["time_origin"]["value"] / 1e6
    write_csv(
        motion,
        out,
        "canonical",
        time_origin=origin_s,
        comments={"tracked_by": "NiTE2 user tracker", "source": str(file), "user": str(motion.metadata["user"])},
    )
    click.echo(f"wrote {out}: {motion.n_frames} frames of user {motion.metadata['user']} ({motion.duration:.2f} s)")


COMMANDS = [oni]
