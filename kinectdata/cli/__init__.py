"""The ``kinectdata`` command line: thin click commands over the library.

Every command turns a :class:`~kinectdata.core.errors.KinectDataError` into a one-line message on
standard error and exit status 1, and prints each
:class:`~kinectdata.core.errors.KinectDataWarning` as one ``warning: ...`` line; click's own usage
errors exit with 2. An environment fault (:class:`OSError`: a path that cannot be written or read,
a full disk) is one line naming the path, exit status 1. Anything else is a bug: one line saying so
and naming the file its traceback was saved to, exit status 70 (``EX_SOFTWARE``). A reader that
stops reading (``kinectdata info FILE | head``) ends the command quietly, as it ends a shell tool:
exit status 141 (128 + SIGPIPE), nothing on standard error.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

import click

from kinectdata.core.errors import KinectDataError, KinectDataWarning
from kinectdata.core.version import __version__

COMMAND_MODULES = {
    "info": "info",
    "formats": "info",
    "oni": "oni",
    "mkv": "mkv",
    "capture": "capture",
    "align": "align",
    "prepare": "prepare",
    "folds": "prepare",
    "build-dataset": "dataset",
    "inspect": "dataset",
    "verify": "verify",
    "train-baseline": "train",
    "evaluate": "train",
    "generate": "train",
    "export": "train",
    "sweep": "train",
    "score": "score",
    "smpl24": "score",
    "convert": "convert",
    "clean": "clean",
    "synth": "synth",
    "quickstart": "quickstart",
    "report": "report",
    "render": "render",
    "live": "live",
}
"""Each command and the module of ``kinectdata.cli`` that defines it (in its ``COMMANDS``): a
command's module is imported when the command runs, so that ``kinectdata info`` does not import
what ``kinectdata train-baseline`` needs (``tests/cli`` checks the table against the modules)."""


class _Group(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMAND_MODULES)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in self.commands and name in COMMAND_MODULES:
            import importlib

            module = importlib.import_module(f"{__name__}.{COMMAND_MODULES[name]}")
            for command in module.COMMANDS:
                self.add_command(command)
        return self.commands.get(name)

    def format_commands(self, ctx: click.Context, formatter) -> None:
        for name in COMMAND_MODULES:  # --help lists every command: import them all
            self.get_command(ctx, name)
        super().format_commands(ctx, formatter)

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
            except (click.exceptions.Exit, click.ClickException, click.Abort, KeyboardInterrupt, SystemExit):
                raise
            except BrokenPipeError:
                _stop_writing_to_a_closed_pipe()
                raise SystemExit(141) from None
            except OSError as exc:
                raise click.ClickException(os_error_line(exc)) from exc
            except Exception as exc:
                raise Bug(exc) from exc


class Bug(click.ClickException):
    """An exception kinectdata did not expect: one line, the traceback saved to a file it names."""

    exit_code = 70

    def __init__(self, exc: BaseException) -> None:
        saved = save_traceback(exc)
        where = f"the traceback is in {saved}" if saved else "the traceback could not be saved"
        super().__init__(
            f"internal error, a bug in kinectdata {__version__} ({type(exc).__name__}: {exc}); {where}: "
            "please report it with that file"
        )


def _stop_writing_to_a_closed_pipe() -> None:
    """Point standard output at the null device, so that the interpreter's last flush at exit does
    not fail on the closed pipe again (the Python documentation's advice on SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no file descriptor (a test's captured stream): nothing to flush
        pass


def os_error_line(exc: OSError) -> str:
    """``path: reason`` of an OSError (both paths of a failed rename or copy)."""
    reason = exc.strerror or str(exc)
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    return f"{' -> '.join(paths)}: {reason}" if paths else reason


def save_traceback(exc: BaseException) -> Path | None:
    """Write the traceback of ``exc`` with the command line and versions to a new file in the
    temporary folder; its path, or None when even that cannot be written."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    path = Path(tempfile.gettempdir()) / f"kinectdata-crash-{stamp}-{os.getpid()}.txt"
    text = (
        f"kinectdata {__version__}, Python {sys.version.split()[0]}, {sys.platform}\n"
        f"command: {' '.join(sys.argv)}\n\n" + "".join(traceback.format_exception(exc))
    )
    try:
        path.write_text(text, encoding="utf-8")
    except OSError:
        return None
    return path


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="kinectdata")
def main() -> None:
    """kinectdata: skeleton recordings + music -> aligned data for music-driven dance research.

    Units everywhere: seconds, metres, Hz; quaternions (x, y, z, w). Run any command with
    --help for its options.
    """


def all_commands() -> dict[str, click.Command]:
    """Every command by name, their modules imported (for tests and documentation tools)."""
    return {name: main.get_command(None, name) for name in COMMAND_MODULES}
