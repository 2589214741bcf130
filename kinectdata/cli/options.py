"""Options shared by several commands."""

from __future__ import annotations

import dataclasses
import functools

import click

from kinectdata.formats import readers


class OffsetType(click.ParamType):
    """'auto' or a number of seconds."""

    name = "auto|SECONDS"

    def convert(self, value, param, ctx):
        if isinstance(value, float) or value == "auto":
            return value
        try:
            return float(value)
        except ValueError:
            self.fail(f"{value!r} is neither 'auto' nor a number of seconds", param, ctx)


class FloatList(click.ParamType):
    """Comma-separated numbers, e.g. ``0.8,0.1,0.1``, as a tuple of floats (empty text: no numbers);
    ``count`` numbers exactly when given. Bad text is click's usage error naming the option."""

    name = "NUMBERS"

    def __init__(self, count: int | None = None) -> None:
        self.count = count

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        text = str(value).strip()
        try:
            numbers = tuple(float(v) for v in text.split(",")) if text else ()
        except ValueError:
            self.fail(f"{value!r} is not a comma-separated list of numbers", param, ctx)
        if self.count is not None and len(numbers) != self.count:
            self.fail(f"give {self.count} comma-separated numbers, not {len(numbers)}", param, ctx)
        return numbers


def default_of(cls: type, name: str):
    """A dataclass field's default: the library's, so a command's option default cannot drift from it."""
    return {f.name: f.default for f in dataclasses.fields(cls)}[name]


READING_OPTIONS = ("format_", "schema", "body", "person", "video_fps", "array_fps", "unit", "rest_joints")


def reader_options(command=None, *, format_flag: str = "--format"):
    """--format, --schema, --body, --person, --video-fps, --array-fps, --unit and --rest-joints, for commands
    that read a skeleton recording. The command receives them as one ``reading`` dict of :func:`read_motion`'s
    keyword arguments (``format``, ``schema``, ...; None where not given). ``format_flag``: the input
    format's flag, for a command whose ``--format`` is its output's (``@reader_options(format_flag="--from")``)."""
    if command is None:
        return functools.partial(reader_options, format_flag=format_flag)

    @functools.wraps(command)
    def f(*args, **kwargs):
        reading = {k.rstrip("_"): kwargs.pop(k) for k in READING_OPTIONS}
        return command(*args, reading=reading, **kwargs)

    f = click.option(
        "--rest-joints",
        default=None,
        metavar="FILE",
        help="FineDance: the SMPL-X rest joints its rotations are posed on (smplx_neu_J_1.npy in FineDance's code).",
    )(f)
    f = click.option(
        "--unit",
        default=None,
        type=click.Choice(["cm", "m", "mm", "in"]),
        help="BVH: the unit of its offsets and positions, which the file does not state (default cm).",
    )(f)
    f = click.option(
        "--array-fps",
        default=None,
        type=click.FloatRange(min=0, min_open=True),
        help="Joint arrays: this file's frame rate, instead of its array schema's time.",
    )(f)
    f = click.option(
        "--video-fps",
        default=None,
        type=click.FloatRange(min=0, min_open=True),
        help="OpenPose output: the video's frame rate (the JSON files carry no timestamps).",
    )(f)
    f = click.option(
        "--person",
        default=None,
        metavar="ID",
        help="OpenPose output: the person to read, as a track id (0, 1, ... in order of first appearance, "
        "or OpenPose's own person_id). Default: the person seen in the most frames.",
    )(f)
    f = click.option(
        "--body",
        default=None,
        metavar="ID",
        help="Body to read from multi-body files (NTU, Azure JSON, CSV with a body column), as its id "
        "is written in the file. Default: the body tracked in the most frames.",
    )(f)
    f = click.option(
        "--schema",
        default=None,
        metavar="NAME|FILE",
        help="CSV dialect: a shipped schema (kinectreader, lsl_kinect, dumpkinectskeleton, canonical) or "
        "a schema JSON file for another dialect (default: detected from the file); for joint arrays "
        "(.npy, .npz, .pkl, JSON), the array schema (shipped: aistpp_keypoints3d...; or a file) that declares them.",
    )(f)
    f = click.option(
        format_flag,
        "format_",
        default=None,
        type=click.Choice(sorted(readers())),
        help="Recording format. Default: from the file's extension and content.",
    )(f)
    return f
