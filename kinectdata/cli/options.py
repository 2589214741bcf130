"""Options shared by several commands."""

from __future__ import annotations

import click

from ..formats import readers


def reader_options(f):
    """--format, --schema and --body, for commands that read a skeleton recording."""
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
        "a schema JSON file for another dialect. Default: detected from the file.",
    )(f)
    f = click.option(
        "--format",
        "format_",
        default=None,
        type=click.Choice(sorted(readers())),
        help="Recording format. Default: from the file's extension and content.",
    )(f)
    return f
