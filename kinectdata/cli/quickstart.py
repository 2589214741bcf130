"""``kinectdata quickstart``."""

from __future__ import annotations

import click


@click.command()
@click.option(
    "--out", default="quickstart_out", show_default=True, type=click.Path(file_okay=False), help="Output folder."
)
@click.option(
    "--samples",
    default=None,
    type=click.Path(file_okay=False, exists=True),
    help="Folder of sample sessions. Default: ./sample_data, or a freshly synthesised set.",
)
def quickstart(out, samples) -> None:
    """Run the data path end to end on the bundled sample data: synthesise a session, align every
    session (offset found from the sync clap, checked against the ground truth), build a dataset
    from the aligned files and inspect it."""
    from ..quickstart import run_quickstart  # imports the synthesiser, slow to load

    run_quickstart(out, samples, echo=click.echo)


COMMANDS = [quickstart]
