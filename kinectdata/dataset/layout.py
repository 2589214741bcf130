"""The names inside a dataset folder, in one place: every module that reads or writes a dataset
takes them from here (importing this module costs nothing: no reader, no HDF5).

A dataset folder holds ``manifest.json`` (:data:`MANIFEST`, validated by
``schemas/dataset-manifest.schema.json``) and shards named ``<split>-<nnnnn>.h5``
(:func:`shard_name`), each an HDF5 file whose ``format`` attribute is :data:`SHARD_FORMAT`
(layout: ``schemas/shard-layout.json``). ``.work/`` (:data:`WORK`) holds a build's per-recording
intermediates until the build finishes. ``.build.lock`` (:data:`LOCK`) is held by the one build
writing the folder, and ``.build.owner`` (:data:`LOCK_OWNER`) says which build that is.
"""

from __future__ import annotations

import re

MANIFEST = "manifest.json"
MANIFEST_SCHEMA = "dataset-manifest.schema.json"
SHARD_FORMAT = "kinectdata.shard"
SHARD_NAME = re.compile(r"(train|val|test)-\d{5}\.h5")
WORK = ".work"
LOCK = ".build.lock"
LOCK_OWNER = ".build.owner"
SPLITS = ("train", "val", "test")
BALANCE_FIELDS = ("recording", "style", "beats_per_bar")
"""What training windows can be balanced by (``WindowDataset.balanced_weights``): the recording, or
a fact about its music that a recipe writes into the recordings manifest and the dataset manifest
keeps in ``inputs`` (its dance style, its metre)."""


def is_copy(record: dict) -> bool:
    """A manifest record of an augmented copy of a training recording (noisy: ``snr_db``; stretched:
    ``tempo``), not a recording of its own."""
    return record.get("snr_db") is not None or record.get("tempo") is not None


def shard_name(split: str, index: int) -> str:
    """The file name of a split's ``index``-th shard, e.g. ``train-00003.h5``."""
    return f"{split}-{index:05d}.h5"


def known_metre(entry: dict, info: dict) -> tuple[int | None, int | None]:
    """What a dataset says of a recording's metre, in beats per bar: (the recordings-manifest entry's
    ``beats_per_bar`` as the dataset manifest's ``inputs`` keeps it (``entry``), the metre the build
    found for features that count bars (``info["metre"]``, a recording's shard attributes)); None
    where it says nothing. The two are kept apart because a caller's own metre ranks between them
    (:func:`kinectdata.features.metre.recording_metre`)."""
    listed = entry.get("beats_per_bar")
    found = (info.get("metre") or {}).get("beats_per_bar")
    return (None if listed is None else int(listed)), (None if found is None else int(found))
