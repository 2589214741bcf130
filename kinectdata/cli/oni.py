"""``kinectdata oni``: OpenNI ``.oni`` recordings (info, export)."""

from __future__ import annotations

import json

import click


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

    from ..oni.export import describe, format_description

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

    from tqdm import tqdm

    from ..oni.export import export_stream

    with tqdm(unit="frame", desc="decoding", disable=None) as bar, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        attrs = export_stream(file, out, stream, start_s=start, end_s=end, compression=compression, progress=progress)
    for w in caught:
        click.echo(f"warning: {w.message}", err=True)
    click.echo(
        f"wrote {out}: {attrs['stream']} ({attrs['codec']}, {attrs['width']}x{attrs['height']})"
        + (" from a recording cut short" if attrs["truncated"] else "")
    )


COMMANDS = [oni]
