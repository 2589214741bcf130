"""A recording from one format to another: any file the readers know to any format a writer
writes (:mod:`kinectdata.formats.writers`: canonical CSV, BVH, joint arrays with their schema,
OpenPose JSON, and the field's SMPL-24 array, whose writer maps the joints as the field's metrics
do and so lives beside them in :mod:`kinectdata.evaluation.motion_sets`).

``kinectdata convert IN -o OUT`` is :func:`convert`; ``kd.write_motion`` is
:func:`kinectdata.formats.writers.write_motion`, re-exported here once the module that registers the
SMPL-24 writer is imported: with it every writer is available.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kinectdata.evaluation import motion_sets as _smpl24_writer  # noqa: F401  registers the smpl24 writer
from kinectdata.formats.registry import read_motion
from kinectdata.formats.writers import Written, write_motion, writers

__all__ = ["convert", "write_motion", "writers"]


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
