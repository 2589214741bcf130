"""``kinectdata report``: a dataset on one self-contained HTML page."""

from __future__ import annotations

import click

from kinectdata.cli.progress import progress_bar
from kinectdata.viz.report import write_report


@click.command("report")
@click.argument("dataset", type=click.Path(path_type=str))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(dir_okay=False, path_type=str),
    help="HTML file to write (figures embedded: the one file is the whole report).",
)
@click.option(
    "--no-sources",
    is_flag=True,
    help="Do not re-read the recordings' sources (faster): no interpolation flags or offset correlation curves.",
)
def report(dataset: str, out: str, no_sources: bool) -> None:
    """Write an HTML report on a DATASET folder: splits, warnings (clipping, long gaps, doubtful
    offsets, masked data) and per recording its tracking quality, offset evidence, audio features
    and target distributions."""
    with progress_bar("reporting", "recording") as progress:
        path = write_report(dataset, out, sources=not no_sources, progress=progress)
    click.echo(f"wrote {path}")


COMMANDS = [report]
