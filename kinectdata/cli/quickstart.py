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
@click.option(
    "--pipeline",
    default="yalta2016",
    show_default=True,
    type=click.Choice(["yalta2016", "listen-to-dance"]),
    help="yalta2016: Kinect sessions, STFT, the DCNN + LSTM. listen-to-dance: synthetic OpenPose sessions, "
    "log-mel, the CDHC model, the rhythm analysis.",
)
@click.option("--epochs", default=3, show_default=True, type=click.IntRange(min=1), help="Training epochs.")
@click.option(
    "--units", default=250, show_default=True, type=click.IntRange(min=1), help="yalta2016: LSTM units per layer."
)
def quickstart(out, samples, pipeline, epochs, units) -> None:
    """Run the toolkit end to end on the bundled sample data in about a minute on 2 CPU cores:
    synthesise a session, align every session (offset from the sync clap, checked against the
    ground truth), build and inspect a dataset, train the reference network briefly, evaluate
    it (SMAPE, forward time, plots, silence test) and generate motion for a test song. With
    --pipeline listen-to-dance: the same for OpenPose poses and the CDHC model."""
    from kinectdata.apps.quickstart import (  # imports the synthesiser, slow to load
        run_listen_quickstart,
        run_quickstart,
    )

    if pipeline == "listen-to-dance":
        if samples is not None:
            raise click.UsageError("--samples applies to the yalta2016 quickstart (its sessions are synthesised)")
        run_listen_quickstart(out, echo=click.echo, epochs=epochs)
    else:
        run_quickstart(out, samples, echo=click.echo, epochs=epochs, units=units)


COMMANDS = [quickstart]
