"""Datasets for training: recordings in, HDF5 shards and a manifest out (see :mod:`.build`).

Modules, in the order the data flows: :mod:`.layout` (the names in a dataset folder, importing
nothing), :mod:`.collection` (session folders), :mod:`.pipelines` (the named presets),
:mod:`.config` (:class:`BuildConfig`), :mod:`.inputs` (what to build from, splits),
:mod:`.prepare` (one recording: alignment, targets, streamed features), :mod:`.shards` (the
shard layout, writer and validator), :mod:`.build` (the recipe), :mod:`.verify`, :mod:`.inspect`
and :mod:`.report` (checks and reports) and :mod:`.windows` (a PyTorch dataset of training
windows; needs torch).

The names below load on first use, so ``from kinectdata.dataset import WindowDataset`` (what
every DataLoader worker pays) imports torch and h5py but no reader, pandas or feature code.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "BuildConfig": "kinectdata.dataset.config",
    "build_dataset": "kinectdata.dataset.build",
    "WindowDataset": "kinectdata.dataset.windows",
    "verify_dataset": "kinectdata.dataset.verify",
    "read_manifest": "kinectdata.dataset.verify",
    "PIPELINES": "kinectdata.dataset.pipelines",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
