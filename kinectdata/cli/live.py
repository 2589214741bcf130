"""``kinectdata live``: a trained run dances to what it hears, sending each pose as it is made."""

from __future__ import annotations

import json
from pathlib import Path

import click

from kinectdata.cli.train import _torch_or_fail, beats_per_bar_option, style_option, turning_options
from kinectdata.core.errors import KinectDataError


@click.command("live")
@click.option("--run", "run_dir", required=True, type=click.Path(file_okay=False, path_type=str), help="Run folder.")
@click.option(
    "--input",
    "given",
    default=None,
    metavar="DEVICE|FILE",
    help="What to listen to: an audio file, played at real-time pace, or an input device by name or index "
    "(python -m sounddevice lists them). Default: the default input device (the microphone).",
)
@click.option("--play", is_flag=True, help="Play the --input file on the speakers while dancing to it.")
@click.option("--osc", multiple=True, metavar="HOST:PORT", help="Send each pose as an OSC bundle there (repeatable).")
@click.option(
    "--vmc",
    multiple=True,
    metavar="HOST:PORT",
    help="Send each pose to an avatar tool over the VMC protocol (VSeeFace, Unity: usually port 39539; repeatable).",
)
@click.option(
    "--vmc-map",
    default=None,
    type=click.Path(dir_okay=False, path_type=str),
    help="The run's joints as Unity humanoid bones (docs/live.md); default: the one shipped for its joint set, "
    "else one derived from its names.",
)
@click.option(
    "--view",
    default=None,
    metavar="[HOST:]PORT",
    help="Serve a live view of the dance on this local address (open it in a browser; port 0: any free one).",
)
@click.option(
    "--record",
    default=None,
    type=click.Path(dir_okay=False, path_type=str),
    help="Write what was heard and danced to this aligned .h5 at the end (atomically), for info, render, score.",
)
@click.option("--duration", type=click.FloatRange(min=0, min_open=True), default=None, help="Seconds to listen.")
@click.option(
    "--stats", default=None, type=click.Path(dir_okay=False, path_type=str), help="Write the figures as JSON."
)
@click.option(
    "--block-ms",
    type=click.FloatRange(min=1, max=100),
    default=5.0,
    show_default=True,
    help="Audio block length: the latency's floor (a frame waits for the block holding its last sample).",
)
@click.option(
    "--engine",
    default="auto",
    show_default=True,
    type=click.Choice(["auto", "torch", "onnxruntime"]),
    help="auto: ONNX Runtime where installed (about twice torch's speed a frame), else torch (one thread).",
)
@click.option("--precision", default="float32", show_default=True, type=click.Choice(["float32", "float16"]))
@beats_per_bar_option(
    "The song's metre, for a model whose features count bars; default: estimated from a file, else 4."
)
@style_option(
    "The song's dance style, for a run whose features hear it; default: heard in a file before it plays "
    "(a device's song must be given)."
)
@turning_options
def live(
    run_dir,
    given,
    play,
    osc,
    vmc,
    vmc_map,
    view,
    record,
    duration,
    stats,
    block_ms,
    engine,
    precision,
    beats_per_bar,
    style,
    turning,
    travel,
    seed,
) -> None:
    """Listen to a microphone (or a file at real-time pace), step the run's streaming network once per
    motion frame as the audio arrives, and send each pose at once to OSC receivers (--osc), avatar
    tools (--vmc) and into a recording (--record). Runs until the file ends, --duration, or Ctrl-C;
    then prints the latency from a frame's audio to its pose, the processing time, late and dropped
    frames and overruns. --view serves a page that draws the dance as it is made, with the music's
    beat and each frame's latency."""
    _torch_or_fail()
    import torch

    from kinectdata.live.clock import MonotonicClock
    from kinectdata.live.session import LiveDancer, run_live
    from kinectdata.live.sinks import OscSink, RecordSink
    from kinectdata.live.sources import open_source

    torch.set_num_threads(1)  # one frame at batch 1: a second thread brings 15 ms stalls, not speed
    for path in (record, stats):  # before the dance, not after it
        if path is not None and not Path(path).resolve().parent.is_dir():
            raise KinectDataError(f"{path}: its folder {Path(path).resolve().parent} does not exist")
    dancer = LiveDancer(run_dir, engine, precision, turning=turning, seed=seed, travel=travel)
    clock = MonotonicClock()
    block = max(1, round(dancer.sample_rate * block_ms / 1000))
    source = open_source(given, dancer.sample_rate, block, clock, play=play)
    sinks = [OscSink(address, dancer.joint_set) for address in osc]
    if vmc:
        from kinectdata.live.vmc import VmcSink

        sinks += [VmcSink(address, dancer.joint_set, vmc_map) for address in vmc]
    if view is not None:
        from kinectdata.live.view import ViewSink

        viewer = ViewSink(view, dancer.joint_set, dancer.fps)  # its beats: run_live's, from a file
        sinks.append(viewer)
        click.echo(f"live view: open {viewer.url} in a browser")
    recorder = None
    if record is not None:
        recorder = RecordSink(Path(record), dancer.joint_set, dancer.fps, dancer.sample_rate, source.name)
        sinks.append(recorder)
    click.echo(
        f"dancing to {source.name} ({1000 * block / dancer.sample_rate:g} ms blocks, {dancer.engine}); Ctrl-C stops"
    )
    click.echo(f"  {dancer.turning_line}")
    try:
        figures = run_live(
            dancer,
            source,
            sinks,
            clock,
            duration=duration,
            beats_per_bar=beats_per_bar,
            record=recorder,
            style=style,
        )
    finally:
        for sink in sinks:
            if hasattr(sink, "close"):
                sink.close()
    for line in figures.lines():
        click.echo(line)
    if recorder is not None:
        written = recorder.write(str(run_dir))
        click.echo(f"wrote {written}" if written else f"{record}: nothing danced, nothing written")
    if stats is not None:
        from kinectdata.core.atomic import atomic_output

        with atomic_output(stats) as tmp:
            Path(tmp).write_text(json.dumps(figures.to_dict(), indent=1))
        click.echo(f"wrote {stats}")
    if figures.fault is not None:
        raise KinectDataError(figures.fault)


COMMANDS = [live]
