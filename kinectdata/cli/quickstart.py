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
@click.option(
    "--corpus",
    nargs=2,
    default=None,
    metavar="NAME PATH",
    help="Run on a local copy of a real corpus instead of synthetic sessions (e.g. --corpus tang2018 "
    "Music-to-Dance-Motion-Synthesis): prepare it, build the model's dataset with the music's pulse, train with "
    "train-baseline's defaults, evaluate on its validation dances, generate.",
)
@click.option(
    "--minutes",
    default=None,
    type=click.FloatRange(min=0, min_open=True),
    help="Training budget.  [default: 6; 25 with --corpus]",
)
@click.option(
    "--corpus-minutes",
    default=8.0,
    show_default=True,
    type=click.FloatRange(min=0, min_open=True),
    help="Minutes of music synthesised to train on.",
)
@click.option(
    "--epochs", default=None, type=click.IntRange(min=1), help="Stop after this many epochs (default: the budget)."
)
@click.option(
    "--units", default=None, type=click.IntRange(min=1), help="yalta2016: LSTM units per layer.  [default: 128]"
)
def quickstart(out, samples, pipeline, corpus, minutes, corpus_minutes, epochs, units) -> None:
    """Run the toolkit end to end in about 7 minutes on 2 CPU cores: synthesise a session, align
    every sample session (offset from the sync clap, checked against the ground truth), build and
    inspect a dataset; then synthesise a corpus to learn from, train the reference network within
    --minutes, evaluate it on songs at tempi it never heard (SMAPE, forward time, plots, silence
    test, and verdicts: does the motion follow the beat and the tempo, does the model listen) and
    generate motion for a test song. With --pipeline listen-to-dance: the same for OpenPose poses
    and the CDHC model. With --corpus NAME PATH: a real corpus, with the settings that learn on one."""
    overrides = {k: v for k, v in {"epochs": epochs, "units": units}.items() if v is not None}
    if pipeline == "listen-to-dance":
        overrides.pop("units", None)  # the yalta model's setting
    if corpus is not None:
        if samples is not None:
            raise click.UsageError("--samples is for the synthetic quickstart: --corpus reads the corpus given")
        from kinectdata.apps.real_dance import REAL_QUICK_MINUTES, run_real_quickstart

        name, path = corpus
        run_real_quickstart(
            name, path, out, echo=click.echo, pipeline=pipeline, minutes=minutes or REAL_QUICK_MINUTES, **overrides
        )
        return
    from kinectdata.apps.quickstart import (  # imports the synthesiser, slow to load
        QUICK_MINUTES,
        run_listen_quickstart,
        run_quickstart,
    )

    minutes = minutes or QUICK_MINUTES
    if pipeline == "listen-to-dance":
        if samples is not None:
            raise click.UsageError("--samples applies to the yalta2016 quickstart (its sessions are synthesised)")
        run_listen_quickstart(out, echo=click.echo, minutes=minutes, corpus_minutes=corpus_minutes, **overrides)
    else:
        run_quickstart(out, samples, echo=click.echo, minutes=minutes, corpus_minutes=corpus_minutes, **overrides)


COMMANDS = [quickstart]
