"""``kinectdata mkv``: Azure Kinect and Orbbec Femto recordings (k4arecorder ``.mkv``: info, export)."""

from __future__ import annotations

import json

import click

from kinectdata.cli.progress import progress_bar


@click.group("mkv")
def mkv() -> None:
    """Azure Kinect and Orbbec Femto .mkv recordings (k4arecorder), read without the SDK."""


@mkv.command("info")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON.")
@click.option(
    "--body",
    type=click.Path(dir_okay=False),
    default=None,
    help="The take's body-tracking JSON (k4abt's offline processor): say where its frames fall on the depth frames.",
)
def info_command(file, as_json, body) -> None:
    """Show what FILE holds: the device and its tags, each track's pixel format, resolution and
    mode, frames, duration on the device's clock, nominal and measured fps, dropped frames and
    gaps, the IMU's samples, the attached calibration, and whether the file is cut short. With
    --body, how the body tracker's frames line up with the depth frames."""
    import warnings

    from kinectdata.mkv import K4aRecording
    from kinectdata.mkv.export import describe, format_description

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the problems are part of the description
        take = K4aRecording(file)
    with take:
        summary = describe(take)
        if body is not None:
            summary["body_tracking"] = _body_placement(take, body)
    if as_json:
        click.echo(json.dumps(summary, indent=2))
        return
    click.echo(format_description(summary))
    if body is not None:
        click.echo(f"  {summary['body_tracking']['summary']}")


def _body_placement(take, body) -> dict:
    from kinectdata.formats import read_motion
    from kinectdata.mkv.body import place_body_frames, tracker_stamps_us

    placement = place_body_frames(tracker_stamps_us(read_motion(body, format="azure_json")), take)
    return {
        "file": str(body),
        "frames": len(placement.frame),
        "placed": placement.placed,
        "clock": placement.clock,
        "depth_frames": placement.frame.tolist(),
        "summary": placement.describe(),
    }


@mkv.command("export")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option(
    "--track",
    "tracks",
    multiple=True,
    type=click.Choice(["depth", "ir", "color", "imu"]),
    help="A track to export (repeat for more). Default: depth.",
)
@click.option("-o", "--out", required=True, type=click.Path(dir_okay=False), help="HDF5 file to write.")
@click.option("--start", type=float, default=None, help="First frame to keep, in seconds from the file's start.")
@click.option("--end", type=float, default=None, help="Keep frames before this, in seconds from the file's start.")
@click.option("--points", is_flag=True, help="Also write each depth frame as points (mm) through the calibration.")
@click.option(
    "--compression", default="gzip", show_default=True, type=click.Choice(["gzip", "lzf", "none"]), help="HDF5 filter."
)
def export_command(file, tracks, out, start, end, points, compression) -> None:
    """Decode tracks of FILE into one HDF5 file: depth and IR [N, H, W] uint16 (mm), colour
    [N, H, W, 3] RGB, each with device_time_us and time_s; the IMU's accelerations and rotation
    rates with their times; the calibration and every tag as attributes."""
    import warnings

    from kinectdata.mkv.export import export_tracks

    with progress_bar("decoding", "frame") as progress, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        attrs = export_tracks(
            file, out, tuple(tracks) or ("depth",), start_s=start, end_s=end, points=points,
            compression=compression, progress=progress,
        )  # fmt: skip
    for w in caught:
        click.echo(f"warning: {w.message}", err=True)
    click.echo(
        f"wrote {out}: {', '.join(tracks or ('depth',))}" + (" and points" if points else "")
        + (" from a recording cut short" if attrs["truncated"] else "")
    )  # fmt: skip


COMMANDS = [mkv]
