"""What the exports of sensor recordings (``oni export``, ``mkv export``) share: the frames a
``--start`` / ``--end`` selection keeps, and the HDF5 filter a ``--compression`` names."""

from __future__ import annotations

from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataError

COMPRESSIONS = ("gzip", "lzf", "none")


def frames_between(seconds: np.ndarray, start_s: float | None, end_s: float | None) -> np.ndarray:
    """Indices of the frames whose times ([N] seconds) are at or after ``start_s`` and before
    ``end_s`` (None: no bound)."""
    keep = np.ones(len(seconds), bool)
    if start_s is not None:
        keep &= seconds >= start_s
    if end_s is not None:
        keep &= seconds < end_s
    return np.flatnonzero(keep)


def check_span(start_s: float | None, end_s: float | None) -> None:
    if start_s is not None and end_s is not None and end_s <= start_s:
        raise KinectDataError(f"--end ({end_s:g} s) must be after --start ({start_s:g} s)")


def hdf5_filter(compression: str) -> dict[str, Any]:
    """h5py's ``create_dataset`` keywords for ``gzip`` (level 4), ``lzf`` or ``none``."""
    if compression not in COMPRESSIONS:
        raise KinectDataError(f"compression must be one of {', '.join(COMPRESSIONS)}, not {compression!r}")
    if compression == "none":
        return {}
    return {"compression": compression, **({"compression_opts": 4} if compression == "gzip" else {})}
