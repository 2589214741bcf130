"""``kinectdata capture``: record a take (OpenNI2 sensor, NiTE2 skeleton, audio) on one clock."""

from __future__ import annotations

import click


def _audio_device(value: str | None):
    if value is None:
        return None
    return int(value) if value.isdigit() else value


@click.command("capture")
@click.option("--device", default=None, help="OpenNI2 device URI (Dummy: OpenNI2's test device). Default: the first.")
@click.option(
    "--duration", default=10.0, show_default=True, type=click.FloatRange(min=0, min_open=True), help="Seconds."
)
@click.option("-o", "--out", type=click.Path(file_okay=False), help="Take folder to write.")
@click.option("--audio-device", default=None, help="Audio input (index or name; see --list). Default: no audio.")
@click.option("--sample-rate", default=48000, show_default=True, type=click.IntRange(min=8000), help="Audio Hz.")
@click.option("--color", is_flag=True, help="Record the colour stream too.")
@click.option("--lossy", is_flag=True, help="With --color: let OpenNI2 store colour as JPEG.")
@click.option("--no-skeleton", is_flag=True, help="Do not track the skeleton even when NiTE2 is installed.")
@click.option("--nite", "nite_dir", default=None, type=click.Path(file_okay=False), help="Folder with libNiTE2.so.")
@click.option("--list", "list_devices", is_flag=True, help="List OpenNI2 devices and audio inputs, and exit.")
def capture(
    device, duration, out, audio_device, sample_rate, color, lossy, no_skeleton, nite_dir, list_devices
) -> None:
    """Record a take into OUT: take.oni (depth, and colour, by OpenNI2's recorder), take.csv (the
    NiTE2 skeleton, when NiTE2 is installed), take.wav (from --audio-device) and take.json, which
    stamps them all on the machine's monotonic clock, so that `kinectdata align TAKE/` needs no
    offset estimate."""
    import warnings

    if list_devices:
        _list()
        return
    if out is None:
        raise click.UsageError("give the take folder with -o/--out")
    from kinectdata.capture.take import capture_take

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        doc = capture_take(
            out,
            device=device,
            duration_s=duration,
            audio_device=_audio_device(audio_device),
            sample_rate=sample_rate,
            color=color,
            lossy=lossy,
            skeleton=not no_skeleton,
            nite_dir=nite_dir,
        )
    for w in caught:
        if not issubclass(w.category, DeprecationWarning):
            click.echo(f"warning: {w.message}", err=True)
    oni = doc["oni"]
    streams = ", ".join(oni["streams"])
    click.echo(f"wrote {out}/take.oni: {oni['depth_frames']} depth frames ({streams}) from {doc['device']['uri']}")
    if doc["skeleton"]:
        click.echo(f"wrote {out}/take.csv: {doc['skeleton']['frames']} skeleton frames")
    if doc["audio"]:
        a = doc["audio"]
        click.echo(
            f"wrote {out}/take.wav: {a['frames'] / a['sample_rate']:.2f} s at {a['sample_rate']} Hz; "
            f"offset {doc['offset_s']:+.4f} s (audio_time = oni_time + offset)"
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
        from kinectdata.capture.audio import input_devices

        for d in input_devices():
            click.echo(f"audio input {d['index']}: {d['name']} ({d['channels']} channels, {d['sample_rate']:g} Hz)")
    except KinectDataError as exc:
        click.echo(f"audio inputs: {exc}")


COMMANDS = [capture]
