"""The ``kinectdata`` command line: thin click commands over the library.

Every command turns a :class:`~kinectdata.core.errors.KinectDataError` into a one-line message on
standard error and exit status 1, and prints each
:class:`~kinectdata.core.errors.KinectDataWarning` as one ``warning: ...`` line; click's own usage
errors exit with 2.
"""

from __future__ import annotations

import warnings

import click

from kinectdata.core.errors import KinectDataError, KinectDataWarning
from kinectdata.core.version import __version__


class _Group(click.Group):
    def invoke(self, ctx: click.Context):
        with warnings.catch_warnings():
            python_way = warnings.showwarning

            def one_line(message, category, *args, **kwargs):
                if issubclass(category, KinectDataWarning):
                    click.echo(f"warning: {message}", err=True)
                else:
                    python_way(message, category, *args, **kwargs)

            warnings.showwarning = one_line
            try:
                return super().invoke(ctx)
            except KinectDataError as exc:
                raise click.ClickException(str(exc)) from exc


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="kinectdata")
def main() -> None:
    """kinectdata: skeleton recordings + music -> aligned data for music-driven dance research.

    Units everywhere: seconds, metres, Hz; quaternions (x, y, z, w). Run any command with
    --help for its options.
    """


def _register() -> None:
    from . import align, capture, dataset, info, oni, quickstart, render, report, score, synth, train, verify

    for module in (info, oni, capture, align, dataset, verify, train, score, synth, quickstart, report, render):
        for command in module.COMMANDS:
            main.add_command(command)


_register()
