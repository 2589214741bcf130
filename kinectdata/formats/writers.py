"""The registry of recording writers: format names, the extensions they claim, and what each
format cannot carry.

A writer is a function ``write(motion, path, **options) -> Path`` registered under a format name
with its extensions and ``loses(motion) -> list[str]``: what of that motion the file will not hold
(a BVH has no confidences), each a short phrase (none for a lossless format: the default).
:func:`write_motion` picks the writer from ``format`` when given, else from the output's extension,
writes atomically (the writers use :func:`~kinectdata.core.atomic.atomic_output`) and returns a
:class:`Written` naming what was left out, so that a conversion says it in one line instead of
losing it silently.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinectdata.core.errors import ConfigError, FormatError
from kinectdata.core.motion import Motion


@dataclass(frozen=True)
class Writer:
    """A registered writer."""

    name: str
    write: Callable[..., Path]
    extensions: tuple[str, ...]
    loses: Callable[[Motion], list[str]]
    description: str

    @property
    def options(self) -> set[str]:
        """Keyword options the writer accepts besides the motion and the path."""
        params = inspect.signature(self.write).parameters.values()
        return {p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY}


@dataclass(frozen=True)
class Written:
    """What :func:`write_motion` wrote.

    Attributes:
        path: the file written (a writer may write companions beside it: an array schema).
        format: the writer's name.
        lost: what of the motion the format cannot carry, each a short phrase; empty when nothing.
    """

    path: Path
    format: str
    lost: tuple[str, ...] = ()

    def describe(self) -> str:
        """One line: what was written, and what was left out."""
        line = f"wrote {self.path} ({self.format})"
        return line + (f"; not carried: {'; '.join(self.lost)}" if self.lost else "")


_WRITERS: dict[str, Writer] = {}


def register_writer(
    name: str,
    *,
    extensions: tuple[str, ...],
    loses: Callable[[Motion], list[str]] | None = None,
    description: str = "",
) -> Callable[[Callable[..., Path]], Callable[..., Path]]:
    """Decorator registering ``write(motion, path, *, options...) -> Path`` as format ``name``."""

    def decorate(write: Callable[..., Path]) -> Callable[..., Path]:
        if name in _WRITERS:
            raise ConfigError(f"a writer named {name!r} is already registered")
        exts = tuple(e.lower() for e in extensions)
        text = description or (write.__doc__ or "").split("\n")[0]
        _WRITERS[name] = Writer(name, write, exts, loses or _lossless, text)
        return write

    return decorate


def _lossless(motion: Motion) -> list[str]:
    return []


def writers() -> dict[str, Writer]:
    """The registered writers by format name."""
    return dict(_WRITERS)


def writer_for(path: str | Path, format: str | None = None) -> Writer:
    """The writer ``format`` names, else the one claiming ``path``'s extension (``.schema.json``
    style double suffixes included); ConfigError naming the choices otherwise."""
    if format is not None:
        if format not in _WRITERS:
            raise ConfigError(f"unknown output format {format!r} (known: {', '.join(sorted(_WRITERS))})")
        return _WRITERS[format]
    name = Path(path).name.lower()
    claiming = [w for w in _WRITERS.values() if any(name.endswith(e) for e in w.extensions)]
    if len(claiming) != 1:
        known = ", ".join(f"{w.name} ({' '.join(w.extensions)})" for w in _WRITERS.values())
        why = "no writer claims" if not claiming else "several writers claim"
        raise ConfigError(f"{path}: {why} its extension; give the format (known: {known})")
    return claiming[0]


def write_motion(motion: Motion, path: str | Path, format: str | None = None, **options: Any) -> Written:
    """Write ``motion`` to ``path`` in ``format`` (default: from the extension), atomically.

    Args:
        motion: any recording kinectdata reads or makes.
        path: the output file.
        format: a registered writer's name (:func:`writers`).
        **options: the writer's options (``unit`` of a BVH, ``fps`` of an SMPL-24 array...); options
            left as None are ignored, an option the writer does not take is an error.

    Returns:
        :class:`Written`: the path, the format, and what the format could not carry.

    Raises:
        ConfigError: an unknown format or option; FormatError / KinectDataError: a motion the format
            cannot hold (a 2-D joint set as BVH), one line naming the output.
    """
    writer = writer_for(path, format)
    given = {k: v for k, v in options.items() if v is not None}
    unknown = set(given) - writer.options
    if unknown:
        raise ConfigError(f"option(s) {', '.join(sorted(unknown))} do not apply to the {writer.name} writer")
    if motion.n_frames < 1:
        raise FormatError(Path(path), "the recording has no frame to write")
    lost = tuple(writer.loses(motion))
    written = writer.write(motion, Path(path), **given)
    return Written(Path(written), writer.name, lost)
