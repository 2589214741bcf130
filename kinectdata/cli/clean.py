"""``kinectdata clean``: a recording's sides, gaps, jitter and bone lengths repaired, with a report."""

from __future__ import annotations

import json
from pathlib import Path

import click

from kinectdata.cli.options import reader_options


@click.command("clean")
@click.argument("recording", type=click.Path(path_type=str))
@click.option("-o", "--out", required=True, type=click.Path(dir_okay=False), help="the cleaned recording (any format)")
@click.option("--sides/--no-sides", default=True, show_default=True,
              help="find and swap back the stretches where a frontal tracker mirrored left and right")  # fmt: skip
@click.option("--up", type=click.Choice(["+y", "-y", "+z", "-z", "+x", "-x"]), default="+y", show_default=True,
              help="the recording's up axis (Kinect v1/v2, BVH: +y; Azure Kinect camera: -y), for --sides")  # fmt: skip
@click.option("--gaps/--no-gaps", default=True, show_default=True, help="take out inferred jumps, fill short gaps")
@click.option("--max-gap", type=click.FloatRange(min=0), default=None, help="the longest gap filled, s (0.2)")
@click.option("--jump", type=click.FloatRange(min=0, min_open=True), default=None,
              help="how far an inferred joint may lie from its tracked neighbours' line, m (0.1)")  # fmt: skip
@click.option(
    "--jitter",
    type=click.Choice(["wiener", "butterworth", "savgol", "one-euro", "none"]),
    default="wiener",
    show_default=True,
    help="the jitter filter: the short-time Wiener smoother, a zero-phase Butterworth or Savitzky-Golay (offline), "
    "the 1-euro filter (causal)",
)
@click.option("--min-cutoff", type=click.FloatRange(min=0, min_open=True), default=None, help="1-euro: Hz (1)")
@click.option("--beta", type=click.FloatRange(min=0), default=None, help="1-euro: Hz per m/s of speed (50)")
@click.option("--d-cutoff", type=click.FloatRange(min=0, min_open=True), default=None, help="1-euro: Hz (1)")
@click.option("--cutoff", type=click.FloatRange(min=0, min_open=True), default=None, help="Butterworth: Hz (6)")
@click.option("--order", type=click.IntRange(min=1), default=None, help="Butterworth: its order (2)")
@click.option("--window", type=click.FloatRange(min=0, min_open=True), default=None, help="Savitzky-Golay: s (0.3)")
@click.option("--wiener-window", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Wiener: its windows, s (1.2)")  # fmt: skip
@click.option("--over-subtraction", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Wiener: how many times the noise's power is taken away (2)")  # fmt: skip
@click.option("--bones/--no-bones", default=True, show_default=True, help="hold each bone to one length")
@click.option("--spread/--no-spread", default=True, show_default=True,
              help="share each bone's error by its ends first (--no-spread: each keeps its direction)")  # fmt: skip
@click.option("--bone-lengths", type=click.Path(dir_okay=False), default=None,
              help='JSON {"child joint": metres} of a measured body (other bones: the median)')  # fmt: skip
@click.option("--report", "report_path", type=click.Path(dir_okay=False), default=None, help="write the report as JSON")
@reader_options(format_flag="--from")
def clean(recording, out, sides, up, gaps, max_gap, jump, jitter, min_cutoff, beta, d_cutoff, cutoff, order, window,
          wiener_window, over_subtraction, bones, spread, bone_lengths, report_path, reading) -> None:  # fmt: skip
    """Clean RECORDING (any 3-D recording kinectdata reads) and write it to OUT in the format its
    extension names: left and right swapped back where a frontal tracker mirrored a dancer seen from
    behind, inferred joints that jump away taken out and short gaps filled, the jitter
    filtered per joint (each sample weighted by its confidence), each bone held to the recording's
    median length along its own direction. Prints what each stage
    changed, and the bone-length CV and jerk before and after. The joint set, frame times,
    confidences, orientations and placement are kept."""
    from kinectdata.apps.convert import write_motion
    from kinectdata.cleaning import CleanConfig, clean_motion
    from kinectdata.core.atomic import atomic_output
    from kinectdata.core.errors import InputError
    from kinectdata.formats import read_motion

    chosen = {"min_cutoff_hz": min_cutoff, "beta": beta, "d_cutoff_hz": d_cutoff}
    chosen |= {"cutoff_hz": cutoff, "order": order, "window_s": window, "max_gap_s": max_gap, "jump_m": jump}
    chosen |= {"wiener_window_s": wiener_window, "over_subtraction": over_subtraction}
    given = {}
    if bone_lengths is not None:
        try:
            given = json.loads(Path(bone_lengths).read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(bone_lengths, f"cannot read it as JSON ({exc})") from None
        if not isinstance(given, dict):
            raise InputError(bone_lengths, 'expected a JSON object {"child joint": metres, ...}')
    axis = "xyz".index(up[1])
    config = CleanConfig(
        sides=sides,
        up=tuple(float(up[0] + "1") if a == axis else 0.0 for a in range(3)),
        gaps=gaps,
        jitter=jitter.replace("-", "_"),
        bones=bones,
        spread=spread,
        bone_lengths=given,
        **{k: v for k, v in chosen.items() if v is not None},
    )
    cleaned = clean_motion(read_motion(recording, **reading), config)
    for line in cleaned.report.lines():
        click.echo(line)
    if report_path is not None:
        with atomic_output(report_path) as tmp:
            tmp.write_text(cleaned.report.to_json() + "\n", encoding="utf-8")
    click.echo(write_motion(cleaned.motion, out).describe())


COMMANDS = [clean]
