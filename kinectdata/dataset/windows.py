"""Training windows for PyTorch: L consecutive frames of one recording, with the poses around them.

Item i of :class:`WindowDataset` is a window of ``length`` frames starting at frame s of one
recording (never crossing into another): ``audio`` [L, *feature shape] ([L, 1, 129, 5] STFT or
[L, 80] mel), ``pose`` [L, D] (the targets at frames s..s+L-1), ``previous`` [L, D] (at
s-1..s+L-2), ``next`` [L, D] (at s+1..s+L), ``mask`` [L, D] for ``pose``, ``previous_mask`` [L, D]
for ``previous``, ``padded`` [L]. Windows start every ``stride`` frames from frame 1 (so the
first has a previous pose) and end by the recording's second-to-last frame (so the last has a
next one). With ``lead`` > 0, windows also start up to ``lead`` frames earlier, every ``stride``
frames from frame ``1 - lead`` (``lead`` < ``length``): their frames before the recording's first
are silence (audio zeros, the features of silence for the mel and pulse features; poses zero and
masked), so a model whose first ``lead`` frames are input only (``TrainConfig.context``) trains on
a song's first seconds too. Each window is one contiguous read per dataset; files are opened lazily
in each DataLoader worker process.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import torch
from torch.utils.data import Dataset

from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.layout import BALANCE_FIELDS, MANIFEST


class WindowDataset(Dataset):
    """Windows of ``length`` frames from one split of a dataset folder."""

    def __init__(
        self,
        dataset: str | Path,
        split: str = "train",
        length: int = 150,
        stride: int | None = None,
        *,
        verify: bool = True,
        checksums: bool = True,
        lead: int = 0,
    ):
        """``verify``: check the folder against its manifest first (shards, sizes, layout and,
        with ``checksums``, their SHA-256: :func:`~kinectdata.dataset.verify.verify_dataset`);
        False for a caller that has just checked it. ``lead``: frames a window may start before
        the recording's second frame, silence there (module docstring)."""
        self.root = Path(dataset)
        if verify:
            from kinectdata.dataset.verify import verified_manifest  # here: importing the class stays light

            manifest = verified_manifest(self.root, checksums=checksums)
        else:
            try:
                manifest = json.loads((self.root / MANIFEST).read_text())
            except OSError as exc:
                raise KinectDataError(f"{self.root}: no readable manifest.json ({exc.strerror or exc})") from exc
        if length < 1:
            raise KinectDataError(f"window length must be at least 1 frame, not {length}")
        if not 0 <= lead < length:
            raise KinectDataError(
                f"a window's lead must be at least 0 frames and shorter than the window ({length}), not {lead}"
            )
        self.length, self.stride = length, stride or length
        self.manifest = manifest
        # (shard file, the window's first row (before the recording's first when led), the recording's first row)
        self.windows: list[tuple[str, int, int]] = []
        self.recordings: list[str] = []
        for r in manifest["recordings"]:
            if r["split"] != split:
                continue
            starts = [*range(1 - lead, 1, self.stride), *range(1, r["frames"] - length, self.stride)]
            for s in starts:
                if s + length <= r["frames"] - 1:  # the last frame has a next one
                    self.windows.append((r["shard"], r["start"] + s, r["start"]))
                    self.recordings.append(r["name"])
        self._files: dict[str, h5py.File] = {}
        self._pid = os.getpid()

    def __len__(self) -> int:
        return len(self.windows)

    def groups(self, field: str) -> list[str | None]:
        """Each window's recording's ``field`` (:data:`BALANCE_FIELDS`: the recording itself, or a fact
        its recordings-manifest entry gives, as the dataset manifest's ``inputs`` keep it: ``style``,
        ``beats_per_bar``), None where the entry has none. [windows]."""
        if field not in BALANCE_FIELDS:
            raise KinectDataError(f"cannot group windows by {field!r}: one of {', '.join(BALANCE_FIELDS)}")
        if field == "recording":
            return list(self.recordings)
        facts = {entry.get("name"): entry.get(field) for entry in self.manifest.get("inputs", [])}
        return [None if facts.get(name) is None else str(facts[name]) for name in self.recordings]

    def balanced_weights(self, field: str) -> np.ndarray | None:
        """Sampling weights that give each group of windows (:meth:`groups`) the same share of an
        epoch: ``1 / (groups x the group's windows)`` per window, summing to 1. [windows]. None when
        the windows form one group (nothing to balance).

        A corpus with 27 waltzes (3 beats to the bar) and 6 dances in 4, balanced by
        ``beats_per_bar``, draws half of its windows from the six."""
        groups = self.groups(field)
        _, index, counts = np.unique([str(g) for g in groups], return_inverse=True, return_counts=True)
        if len(counts) < 2:
            return None
        return 1.0 / (len(counts) * counts[index])

    def _file(self, name: str) -> h5py.File:
        if os.getpid() != self._pid:  # a forked DataLoader worker: its own handles
            self._files, self._pid = {}, os.getpid()
        if name not in self._files:
            self._files[name] = h5py.File(self.root / name, "r")
        return self._files[name]

    def __getitem__(self, i: int) -> dict[str, Any]:
        shard, row, first = self.windows[i]
        f = self._file(shard)
        L = self.length
        ahead = max(0, first - (row - 1))  # rows before the recording's first (its previous pose's included)
        current = _padded(f["current"], row - 1 + ahead, row + L + 1, ahead, 0)  # previous, window, next
        mask = _padded(f["mask"], row - 1 + ahead, row + L, ahead, False)
        inside = max(0, first - row)
        return {
            "audio": torch.from_numpy(_padded(f["input"], row + inside, row + L, inside, 0)),
            "pose": torch.from_numpy(current[1 : L + 1].copy()),
            "previous": torch.from_numpy(current[:L].copy()),
            "next": torch.from_numpy(current[2:].copy()),
            "mask": torch.from_numpy(mask[1:].copy()),
            "previous_mask": torch.from_numpy(mask[:L].copy()),
            "padded": torch.from_numpy(_padded(f["audio_padded"], row + inside, row + L, inside, True)),
        }

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_files"] = {}  # handles do not cross process boundaries
        return state

    def close(self) -> None:
        for f in self._files.values():
            f.close()
        self._files = {}


def _padded(data: h5py.Dataset, start: int, stop: int, before: int, fill) -> np.ndarray:
    """Rows ``start..stop-1`` of ``data`` after ``before`` rows of ``fill`` (one read)."""
    rows = data[start:stop]
    if not before:
        return rows
    return np.concatenate([np.full((before, *rows.shape[1:]), fill, dtype=rows.dtype), rows])
