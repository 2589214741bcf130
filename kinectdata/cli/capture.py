"""``kinectdata capture``: record a take (an OpenNI2 sensor with NiTE2's skeleton, or an Azure
Kinect; audio) on one clock."""

from __future__ import annotations

import click


def _audio_device(value: str | None):
    if value is None:
        return None
    return int(value) if value.isdigit() else value


@click.command("capture")
@click.option(
    "--sensor",
    type=click.Choice(["openni2", "k4a"]),
    default="openni2",
    show_default=True,
    help="openni2: an OpenNI2 device; k4a: an Azure Kinect or Orbbec Femto through pyk4a.",
)
@click.option(
    "--device",
    default=None,
    help="openni2: the device URI (Dummy: OpenNI2's test device); k4a: the device index. Default: the first.",
)
@click.option(
    "--duration", default=10.0, show_default=True, type=click.FloatRange(min=0, min_open=True), help="Seconds."
)
@click.option("-o", "--out", type=click.Path(file_okay=False), help="Take folder to write.")
@click.option("--audio-device", default=None, help="Audio input (index or name; see --list). Default: no audio.")
@click.option("--sample-rate", default=48000, show_default=True, type=click.IntRange(min=8000), help="Audio Hz.")
@click.option("--color", is_flag=True, help="Record the colour stream too.")
@click.option("--lossy", is_flag=True, help="openni2, with --color: let OpenNI2 store colour as JPEG.")
@click.option("--no-skeleton", is_flag=True, help="openni2: do not track the skeleton even when NiTE2 is installed.")
@click.option("--nite", "nite_dir", default=None, type=click.Path(file_okay=False), help="Folder with libNiTE2.so.")
@click.option(
    "--depth-mode",
    default="NFOV_UNBINNED",
    show_default=True,
    help="k4a: NFOV_UNBINNED, NFOV_2X2BINNED, WFOV_UNBINNED, WFOV_2X2BINNED, PASSIVE_IR or OFF.",
)
@click.option(
    "--color-resolution",
    default="720P",
    show_default=True,
    help="k4a, with --color: 720P, 1080P, 1440P, 1536P, 2160P or 3072P (the camera's MJPEG).",
)
@click.option("--fps", default=30, show_default=True, type=click.Choice(["5", "15", "30"]), help="k4a: frame rate.")
@click.option("--list", "list_devices", is_flag=True, help="List the sensors and audio inputs, and exit.")
def capture(
    sensor,
    device,
    duration,
    out,
    audio_device,
    sample_rate,
    color,
    lossy,
    no_skeleton,
    nite_dir,
    depth_mode,
    color_resolution,
    fps,
    list_devices,
) -> None:
    """Record a take into OUT on one clock, so that `kinectdata align TAKE/` needs no offset
    estimate: the sensor's recording (openni2: take.oni by OpenNI2's recorder, and take.csv, the
    NiTE2 skeleton, when NiTE2 is installed; k4a: take.mkv by the Azure Kinect SDK's recorder),
    take.wav (from --audio-device) and take.json, which stamps them all on the machine's
    monotonic clock."""
    import warnings

    if list_devices:
        _list()
        return
    if out is None:
        raise click.UsageError("give the take folder with -o/--out")
    from kinectdata.capture.take import capture_take

    if sensor == "k4a":
        from kinectdata.capture.k4a import K4aSensor

        if device is not None and not device.isdigit():
            raise click.BadParameter(f"{device!r}: a k4a device is its index (0, 1, ...)", param_hint="--device")
        if lossy or no_skeleton or nite_dir:
            raise click.UsageError("--lossy, --no-skeleton and --nite are OpenNI2's; a k4a take has no live skeleton")
        chosen = K4aSensor(
            device_index=int(device or 0),
            depth_mode=depth_mode.upper(),
            color_resolution=color_resolution.upper() if color else "OFF",
            fps=int(fps),
        )
    else:
        from kinectdata.capture.openni import OpenNI2Sensor

        chosen = OpenNI2Sensor(device=device, color=color, lossy=lossy, skeleton=not no_skeleton, nite_dir=nite_dir)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        doc = capture_take(
            out, chosen, duration_s=duration, audio_device=_audio_device(audio_device), sample_rate=sample_rate
        )
    for w in caught:
        if not issubclass(w.category, DeprecationWarning):
            click.echo(f"warning: {w.message}", err=True)
    for line in chosen.describe(doc, out):
        click.echo(line)
    if doc["audio"]:
        a = doc["audio"]
        click.echo(
            f"wrote {out}/take.wav: {a['frames'] / a['sample_rate']:.2f} s at {a['sample_rate']} Hz; "
            f"offset {doc['offset_s']:+.4f} s (audio_time = recording_time + offset)"
        )
    click.echo(f"wrote {out}/take.json")


def _list() -> None:
    from kinectdata.core.errors import KinectDataError

    try:
        from openni import openni2

        from kinectdata.oni.skeleton import openni2_dir

        openni2.initialize(str(openni2_dir()))
        uris = [uri.decode("latin-1") for uri in openni2.Device.enumerate_uris()]
        for uri in uris:
            click.echo(f"OpenNI2 device: {uri}")
        if not uris:
            click.echo("OpenNI2 devices: none connected (OpenNI2's test device opens with --device Dummy)")
    except (ImportError, KinectDataError) as exc:
        click.echo(f"OpenNI2 devices: {exc}")
    try:
        import pyk4a

        count = pyk4a.connected_device_count()
        click.echo(
            f"Azure Kinect devices (--sensor k4a): {count} connected" + (f" (--device 0..{count - 1})" * (count > 0))
        )
    except ImportError:
        click.echo("Azure Kinect devices (--sensor k4a): pyk4a is not installed (pip install 'kinectdata[k4a]')")
    try:
        from kinectdata.capture.audio import input_devices

        for d in input_devices():
            click.echo(f"audio input {d['index']}: {d['name']} ({d['channels']} channels, {d['sample_rate']:g} Hz)")
    except KinectDataError as exc:
        click.echo(f"audio inputs: {exc}")


COMMANDS = [capture]
