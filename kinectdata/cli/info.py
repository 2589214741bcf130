"""``kinectdata info`` and ``kinectdata formats``."""

from __future__ import annotations

import click
import numpy as np

from kinectdata.cli.options import reader_options
from kinectdata.core.jointsets import load_joint_set, shipped_joint_sets
from kinectdata.formats import read_motion, readers
from kinectdata.formats.csv_schema import load_csv_schema, shipped_csv_schemas


@click.command()
@click.argument("recording", type=click.Path(dir_okay=True, path_type=str))
@reader_options
def info(
    recording: str,
    format_: str | None,
    schema: str | None,
    body: str | None,
    person: str | None,
    video_fps: float | None,
) -> None:
    """Show what a skeleton RECORDING holds: format, joints, frames, timing, tracking."""
    m = read_motion(recording, format=format_, schema=schema, body=body, person=person, video_fps=video_fps)
    t = m.timing()
    md = m.metadata
    click.echo(f"file            {recording}")
    click.echo(f"format          {md.get('format')}" + (f" (schema {md['schema']})" if "schema" in md else ""))
    click.echo(f"joint set       {m.joint_set.name} ({m.n_joints} joints, {m.joint_set.dimensions}-D)")
    if "bodies" in md:
        click.echo(
            f"body            {md['body']} of " + ", ".join(f"{b} ({n} frames)" for b, n in md["bodies"].items())
        )
    if "people" in md:
        click.echo(
            f"person          {md['person']} of "
            + ", ".join(f"{p} ({n} frames)" for p, n in md["people"].items())
            + f"; {md['layout']} keypoints at {md['video_fps']:g} fps"
        )
    click.echo(
        f"frames          {m.n_frames} over {m.duration:.3f} s; {t['fps']:.2f} fps (median interval "
        f"{t['interval_ms']:.2f} ms), jitter {t['jitter_ms']:.2f} ms, {t['dropped_frames']} dropped"
    )
    click.echo(
        f"positions       {100 * m.position_mask.mean():.1f}% valid; mean confidence {np.mean(m.confidence):.3f}"
    )
    if m.has_orientations:
        can = m.joint_set.orientation_mask
        share = m.orientation_mask[:, can].mean() if can.any() else 0.0
        click.echo(f"orientations    {100 * share:.1f}% valid (of joints that carry one)")
    else:
        click.echo("orientations    none in this format")


@click.command()
def formats() -> None:
    """List the readers, shipped CSV dialects and joint sets."""
    click.echo("readers (--format):")
    for name, r in sorted(readers().items()):
        exts = ", ".join(r.extensions) or "by content"
        click.echo(f"  {name:<14} {exts:<12} {r.description}")
    click.echo("CSV dialects (--schema):")
    for name in shipped_csv_schemas():
        click.echo(f"  {name:<20} {_headline(load_csv_schema(name).get('description', ''))}")
    click.echo("joint sets:")
    for name in shipped_joint_sets():
        js = load_joint_set(name)
        click.echo(f"  {name:<14} {len(js)} joints, {js.dimensions}-D")


def _headline(text: str, width: int = 76) -> str:
    """The part of a description before its first colon or full stop, cut at a word."""
    head = text.split(": ")[0].split(". ")[0]
    return head if len(head) <= width else head[: width - 3].rsplit(" ", 1)[0] + "..."


COMMANDS = [info, formats]
