"""The registry of skeleton readers: format names, file extensions and content sniffers.

A reader is a function ``read(path, **options) -> Motion`` registered under a format name with
the extensions it claims and, optionally, a ``sniff(path, head) -> bool`` that recognises the
file from its first bytes. :func:`read_motion` picks the reader from ``format`` when given, else
from the extension (sniffing when several readers claim it), else by sniffing every reader.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinectdata.core.errors import ConfigError, FormatError
from kinectdata.core.motion import Motion

SNIFF_BYTES = 4096


@dataclass(frozen=True)
class Reader:
    """A registered reader."""

    name: str
    read: Callable[..., Motion]
    extensions: tuple[str, ...]
    sniff: Callable[[Path, bytes], bool] | None
    description: str
    claims: Callable[[dict[str, Any]], bool] | None = None

    @property
    def options(self) -> set[str]:
        """Keyword options the reader accepts besides the path."""
        params = inspect.signature(self.read).parameters.values()
        return {p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY}


_READERS: dict[str, Reader] = {}


def register_reader(
    name: str,
    *,
    extensions: tuple[str, ...] = (),
    sniff: Callable[[Path, bytes], bool] | None = None,
    description: str = "",
    claims: Callable[[dict[str, Any]], bool] | None = None,
) -> Callable[[Callable[..., Motion]], Callable[..., Motion]]:
    """Decorator registering ``read(path, *, options...) -> Motion`` as format ``name``.

    ``claims(options)``: True when the options given (e.g. an array schema as ``schema``) say the
    file is this reader's whatever its name; ``read_motion`` asks it before the name and content."""

    def decorate(read: Callable[..., Motion]) -> Callable[..., Motion]:
        if name in _READERS:
            raise ConfigError(f"a reader named {name!r} is already registered")
        exts = tuple(e.lower() for e in extensions)
        _READERS[name] = Reader(name, read, exts, sniff, description or (read.__doc__ or "").split("\n")[0], claims)
        return read

    return decorate


SENSOR_RECORDINGS = {
    b"\x1a\x45\xdf\xa3": "a Matroska file (an Azure Kinect or Orbbec Femto .mkv recording holds depth, colour and "
    "IMU frames, not a skeleton): see `kinectdata mkv info`; its body-tracking JSON is read as azure_json",
    b"NI10": "an OpenNI .oni recording (depth and colour frames, not a skeleton): see `kinectdata oni info`, or "
    "`kinectdata oni skeleton` to track the dancer with NiTE2",
}
"""Files of the depth sensors' own recordings by their first bytes: they hold frames, not a skeleton
(the EBML header's ID, RFC 8794; the .oni file header's magic)."""


def readers() -> dict[str, Reader]:
    """The registered readers by format name."""
    return dict(_READERS)


def _suffix(path: Path) -> str:
    return path.suffix.lower()


def detect_format(path: str | Path) -> str:
    """Name of the reader for a file, from its extension and, where needed, its content."""
    path = Path(path)
    if not path.exists():
        raise FormatError(path, "no such file or folder")
    head = b""
    if path.is_file():
        with open(path, "rb") as f:
            head = f.read(SNIFF_BYTES)
    claimed = [r for r in _READERS.values() if _suffix(path) in r.extensions]
    if len(claimed) == 1:
        return claimed[0].name
    candidates = claimed or list(_READERS.values())
    sniffed = [r.name for r in candidates if r.sniff is not None and r.sniff(path, head)]
    if len(sniffed) == 1:
        return sniffed[0]
    if not sniffed:
        for magic, what in SENSOR_RECORDINGS.items():
            if head.startswith(magic):
                raise FormatError(path, what)
        known = ", ".join(sorted(_READERS))
        raise FormatError(
            path, f"cannot tell the recording format from the name or content; pass --format (one of {known})"
        )
    raise FormatError(path, f"the content fits several formats ({', '.join(sniffed)}); pass --format")


def read_motion(path: str | Path, format: str | None = None, **options: Any) -> Motion:
    """Read a skeleton recording with the registered reader for it.

    Args:
        path: the recording file.
        format: a registered format name; when None, the reader the options claim the file for
            (an array schema given as ``schema``: ``arrays``), else detected from extension and content.
        **options: reader options (``schema`` for CSV, ``body`` for multi-body formats...).
            Options left as None are ignored; an option the reader does not take is an error.
    """
    path = Path(path)
    given = {k: v for k, v in options.items() if v is not None}
    claimed = [r.name for r in _READERS.values() if format is None and r.claims is not None and r.claims(given)]
    name = format or (claimed[0] if len(claimed) == 1 else detect_format(path))
    if name not in _READERS:
        raise FormatError(path, f"unknown format {name!r} (known: {', '.join(sorted(_READERS))})")
    reader = _READERS[name]
    unknown = set(given) - reader.options
    if unknown:
        raise FormatError(path, f"option(s) {', '.join(sorted(unknown))} do not apply to format {name!r}")
    if not path.exists():
        raise FormatError(path, "no such file or folder")
    motion = reader.read(path, **given)
    motion.metadata.setdefault("format", name)
    motion.metadata.setdefault("source", str(path))
    return motion
