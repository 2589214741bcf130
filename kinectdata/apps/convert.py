"""A recording from one format to another: any file the readers know to any format a writer
writes (:mod:`kinectdata.formats.writers`: canonical CSV, BVH, joint arrays with their schema,
OpenPose JSON, and the field's SMPL-24 array, whose writer maps the joints as the field's metrics
do and so lives beside them in :mod:`kinectdata.evaluation.motion_sets`).

``kinectdata convert IN -o OUT`` is :func:`convert`; ``kd.write_motion`` is :func:`write_motion`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kinectdata.core.motion import Motion
from kinectdata.evaluation import motion_sets as _smpl24_writer  # noqa: F401  registers the smpl24 writer
from kinectdata.formats.registry import read_motion
from kinectdata.formats.writers import Written, writers
from kinectdata.formats.writers import write_motion as _write_motion

__all__ = ["convert", "write_motion", "writers"]


def write_motion(motion: Motion, path: str | Path, format: str | None = None, **options: Any) -> Written:
    """Write ``motion`` to ``path`` in ``format`` (default: from the extension: ``.csv``, ``.bvh``,
    ``.npz``, ``.jsonl``, ``.npy``), atomically, with every registered writer available; the options
    are the writer's (``unit`` and ``decimals`` of a BVH, ``fps`` and ``mapping`` of an SMPL-24
    array). Returns :class:`~kinectdata.formats.writers.Written`, whose ``lost`` names what the
    format could not carry (:func:`kinectdata.formats.writers.write_motion`)."""
    return _write_motion(motion, path, format, **options)


def convert(
    source: str | Path,
    out: str | Path,
    format: str | None = None,
    *,
    reading: dict[str, Any] | None = None,
    **options: Any,
) -> Written:
    """Read ``source`` (``reading``: :func:`~kinectdata.formats.registry.read_motion`'s options,
    ``format`` and ``schema`` among them) and write it to ``out`` as :func:`write_motion` does."""
    motion = read_motion(source, **(reading or {}))
    return write_motion(motion, out, format, **options)
