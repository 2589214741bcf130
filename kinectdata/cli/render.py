"""``kinectdata render``: a skeleton animation (MP4 with the music, or GIF)."""

from __future__ import annotations

import click

from kinectdata.cli.options import reader_options
from kinectdata.cli.progress import progress_bar


class SizeType(click.ParamType):
    """WIDTHxHEIGHT in pixels."""

    name = "WIDTHxHEIGHT"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            width, height = (int(v) for v in value.lower().split("x"))
        except ValueError:
            self.fail(f"{value!r} is not WIDTHxHEIGHT in pixels, e.g. 640x480", param, ctx)
        return width, height


@click.command()
@click.argument("motion", type=click.Path(path_type=str))
@click.option(
    "-o",
    "--out",
    default=None,
    type=click.Path(dir_okay=False, path_type=str),
    help="Animation to write: .mp4 (H.264 with the music as AAC; needs imageio-ffmpeg, pip install "
    "'kinectdata[video]') or .gif (no sound). Written atomically: nothing appears if anything fails.",
)
@click.option(
    "--view",
    default=None,
    metavar="[HOST:]PORT",
    help="Instead of writing a file, play MOTION at its own pace in a live view served on this local address "
    "(open it in a browser; port 0: any free one), with the music's beat when it has music.",
)
@click.option(
    "--audio",
    default=None,
    type=click.Path(dir_okay=False, path_type=str),
    help="Music for the MP4 (WAV, FLAC, OGG, MP3...), its first sample at the motion's first frame, cut to "
    "--start..--end. Default: an aligned .h5's own audio (MOTION's, else OTHER's).",
)
@click.option(
    "--compare",
    default=None,
    type=click.Path(path_type=str),
    metavar="OTHER",
    help="A second motion drawn to the right on the same time axis (0 at each one's first frame), e.g. "
    "generated against real. The shorter one stays frozen on its last frame, captioned 'ended', until the "
    "longer one ends. Both must be 2-D or both 3-D.",
)
@click.option(
    "--start", default=0.0, show_default=True, type=click.FloatRange(min=0), help="First time drawn, in seconds."
)
@click.option(
    "--end",
    default=None,
    type=click.FloatRange(min=0, min_open=True),
    help="Draw up to this time, in seconds. Default: the end of the (longer) motion.",
)
@click.option(
    "--fps",
    default=None,
    type=click.FloatRange(min=0, min_open=True),
    help="Output frames per second; each shows the motion's nearest frame. Default: MOTION's rate, at most 30.",
)
@click.option(
    "--size",
    default="640x480",
    show_default=True,
    type=SizeType(),
    help="Pixels of each panel (a comparison is twice as wide); even numbers for MP4.",
)
@click.option(
    "--over",
    default=None,
    type=click.Path(dir_okay=False, path_type=str),
    metavar="TAKE.mkv",
    help="Draw MOTION, the body tracker's JSON of an Azure Kinect take, over that take's depth frames (each body "
    "frame on the depth frame it was made from, joints projected through the take's calibration), at the depth "
    "track's rate and size, no sound.",
)
@click.option(
    "--on",
    "over_track",
    default="depth",
    show_default=True,
    type=click.Choice(["depth", "color"]),
    help="With --over: draw over the take's depth frames or its colour frames.",
)
@reader_options
def render(motion, out, view, audio, compare, start, end, fps, size, over, over_track, reading) -> None:
    """Draw MOTION as a skeleton animation: any readable recording, an aligned .h5 or generated motion
    (CSV, OpenPose JSON Lines). 3-D skeletons (metres) are seen by a fixed raised camera looking the way
    the sensor looks, over a floor grid; 2-D ones (pixels) on image axes, y down. --format applies to
    MOTION, the other reader options to MOTION and OTHER where their format takes them."""

    if (out is None) == (view is None):
        raise click.UsageError("give -o OUT (an animation file) or --view PORT (a live view in the browser)")
    if view is not None:
        for given, name in ((compare, "--compare"), (over, "--over"), (fps, "--fps")):
            if given is not None:
                raise click.UsageError(f"{name} does not go with --view: the view plays one motion at its own pace")
        _render_view(motion, view, audio, start, end, reading)
        return
    if over is not None:
        _render_over(motion, over, over_track, out, audio, compare, start, end, fps, reading)
        return
    from kinectdata.viz.render import load_inputs, render_animation

    paths = [motion] if compare is None else [motion, compare]
    with_audio = out.lower().endswith(".mp4") and audio is None
    inputs = load_inputs(paths, with_audio=with_audio, **reading)
    with progress_bar("rendering", "frame") as progress:
        result = render_animation(inputs, out, start=start, end=end, fps=fps, audio=audio, size=size, progress=progress)
    width, height = result["size"]
    click.echo(
        f"wrote {out}: {result['frames']} frames at {result['fps']:g} fps ({result['start']:.3f} to "
        f"{result['end']:.3f} s), {width}x{height}, "
        + (f"sound from {result['audio']}" if result["audio"] else "no sound")
    )
    for source in result["ended"]:
        click.echo(f"{source} ends before the clip: shown frozen on its last frame after that")


def _render_view(motion, view, audio, start, end, reading) -> None:
    from kinectdata.align.audio import load_audio
    from kinectdata.core.errors import KinectDataError
    from kinectdata.core.motion import frame_clock
    from kinectdata.features.beats import music_beats
    from kinectdata.live.view import ViewSink, play_motion
    from kinectdata.viz.render import load_input, up_axis

    shown = load_input(motion, with_audio=audio is None, **reading)
    if shown.motion.n_frames == 0:
        raise KinectDataError(f"{motion}: no frames to play")
    samples, rate = shown.audio, shown.sample_rate
    if audio is not None:
        heard = load_audio(audio)
        samples, rate = heard.samples, heard.sample_rate
    beats = None if samples is None else music_beats(samples, rate)[0]
    fps = 1.0 / frame_clock(shown.motion.times)[0] if shown.motion.n_frames > 1 else 30.0
    sink = ViewSink(view, shown.motion.joint_set, fps, beats, up_axis(shown.motion))
    click.echo(f"live view: open {sink.url} in a browser; playing {shown.label} (Ctrl-C stops)")
    try:
        played = play_motion(shown.motion, sink, start=start, end=end)
    except KeyboardInterrupt:
        played = "stopped (Ctrl-C)"
    finally:
        sink.close()
    click.echo(f"{played}; {sink.summary()}")


def _render_over(motion, over, over_track, out, audio, compare, start, end, fps, reading) -> None:
    from kinectdata.formats import read_motion
    from kinectdata.viz.overlay import render_overlay

    for given, name in ((compare, "--compare"), (audio, "--audio"), (fps, "--fps")):
        if given is not None:
            raise click.UsageError(f"{name} does not go with --over: the depth frames set the clip's rate and size")
    with progress_bar("rendering", "frame") as progress:
        result = render_overlay(
            read_motion(motion, **reading), over, out, start=start, end=end, on=over_track.upper(), progress=progress
        )
    width, height = result["size"]
    click.echo(
        f"wrote {out}: {result['frames']} {over_track} frames at {result['fps']:g} fps, {width}x{height}, no sound"
    )
    click.echo(result["placement"])


COMMANDS = [render]
