"""``kinectdata convert``: a recording from one format to another."""

from __future__ import annotations

import click

from kinectdata.cli.options import reader_options


@click.command("convert")
@click.argument("recording", type=click.Path(path_type=str))
@click.option("-o", "--out", required=True, type=click.Path(dir_okay=False), help="the file to write")
@click.option(
    "--format",
    "out_format",
    default=None,
    type=click.Choice(["arrays", "bvh", "csv", "openpose", "smpl24"]),
    help="output format (default: from the output's extension: .csv, .bvh, .npz, .jsonl, .npy)",
)
@click.option("--bvh-unit", default=None, type=click.Choice(["cm", "m", "mm", "in"]), help="BVH: its unit (default cm)")
@click.option("--fps", default=None, type=click.FloatRange(min=0, min_open=True), help="SMPL-24: frame rate (60)")
@click.option("--mapping", default=None, help="SMPL-24: joint-mapping file for a joint set without a shipped one")
@reader_options(format_flag="--from")
def convert(recording, out, out_format, bvh_unit, fps, mapping, reading) -> None:
    """Write RECORDING (any recording kinectdata reads) to OUT in another format: kinectdata's
    canonical CSV (lossless), BVH (a rest pose and rotations, centimetres), joint arrays (.npz with
    their array schema beside them), OpenPose JSON Lines (2-D) or the field's SMPL-24 array (.npy).
    The joint set, frame times and placement are kept where the format can hold them; what it
    cannot is said in one line."""
    from kinectdata.apps.convert import convert as convert_file
    from kinectdata.formats.writers import writer_for

    writer = writer_for(out, out_format).name
    own = (("--bvh-unit", bvh_unit, "bvh"), ("--fps", fps, "smpl24"), ("--mapping", mapping, "smpl24"))
    for flag, value, applies in own:
        if value is not None and writer != applies:
            raise click.UsageError(f"{flag} applies to a {applies} output; {out} is written as {writer}")
    options = {"unit": bvh_unit, "fps": fps, "mapping": mapping}
    written = convert_file(recording, out, out_format, reading=reading, **options)
    click.echo(written.describe())


COMMANDS = [convert]
