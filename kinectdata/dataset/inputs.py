"""What a dataset is built from: a recordings manifest, or a folder, and the split of each recording.

A recordings manifest (JSON, YAML or CSV; fields in ``schemas/recordings.schema.json``) lists
recordings with their audio, optional split, offset, format, schema and body. A folder is either
one of aligned ``.h5`` files (written by ``kinectdata align``) or one of sessions (a skeleton
file and its audio sharing a name, as ``sample_data/``).

Splits are by recording, so the frames of one recording never land in two splits: recordings
with an explicit split keep it, the others are shuffled with the seed (after sorting by name) and
cut by the ratios.
"""

from __future__ import annotations

import csv
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..collection import find_sessions
from ..errors import KinectDataError, SchemaError
from ..resources import validate

SPLITS = ("train", "val", "test")


@dataclass(frozen=True)
class RecordingEntry:
    """One recording to build from. ``audio`` is None for an aligned ``.h5`` recording."""

    name: str
    recording: str
    audio: str | None = None
    split: str | None = None
    offset: float | str = "auto"
    format: str | None = None
    schema: str | None = None
    body: str | None = None

    @property
    def aligned(self) -> bool:
        return self.audio is None

    def to_dict(self) -> dict[str, Any]:
        return {k: v for k, v in asdict(self).items() if v is not None}


def _is_aligned_file(path: Path) -> bool:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == "kinectdata.aligned"
    except OSError:
        return False


def _read_manifest(path: Path) -> list[dict[str, Any]]:
    suffix = path.suffix.lower()
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise SchemaError(path, f"cannot read file: {exc.strerror or exc}") from exc
    if suffix == ".csv":
        rows = list(csv.DictReader(text.splitlines()))
        docs = [{k.strip(): v.strip() for k, v in row.items() if k and v is not None and v.strip()} for row in rows]
        for d in docs:
            if "offset" in d and d["offset"] != "auto":
                try:
                    d["offset"] = float(d["offset"])
                except ValueError:
                    pass  # the JSON Schema reports it
        return docs
    try:
        if suffix in (".yaml", ".yml"):
            import yaml

            doc = yaml.safe_load(text)
        else:
            doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SchemaError(path, f"invalid JSON: {exc.msg}", line=exc.lineno) from exc
    except Exception as exc:  # yaml.YAMLError and its subclasses
        mark = getattr(exc, "problem_mark", None)
        raise SchemaError(path, f"invalid YAML: {exc}", line=None if mark is None else mark.line + 1) from exc
    if isinstance(doc, dict) and "recordings" in doc:
        doc = doc["recordings"]
    return doc


def read_recordings(source: str | Path) -> list[RecordingEntry]:
    """The recordings listed by a manifest file, or found in a folder, with resolved paths."""
    source = Path(source)
    if source.is_dir():
        aligned = sorted(p for p in source.glob("*.h5") if _is_aligned_file(p))
        if aligned:
            return [RecordingEntry(name=p.stem, recording=str(p)) for p in aligned]
        sessions = find_sessions(source)
        if not sessions:
            raise KinectDataError(
                f"{source}: no aligned .h5 files and no sessions (a skeleton file with audio beside it)"
            )
        return [RecordingEntry(name=s.name, recording=str(s.skeleton), audio=str(s.audio)) for s in sessions]
    if not source.is_file():
        raise KinectDataError(f"{source}: no such manifest file or folder")
    docs = _read_manifest(source)
    validate(docs, "recordings.schema.json", source)
    base = source.parent
    entries, seen = [], {}
    for i, d in enumerate(docs):
        recording = base / d["recording"]
        if "audio" not in d and not _is_aligned_file(recording):
            raise SchemaError(source, f"recordings[{i}]: {d['recording']} needs an 'audio' (it is not an aligned .h5)")
        name = d.get("name", Path(d["recording"]).stem)
        if name in seen:
            raise SchemaError(source, f"recordings[{i}]: name {name!r} is already used by recordings[{seen[name]}]")
        seen[name] = i
        entries.append(
            RecordingEntry(
                name=name,
                recording=str(recording),
                audio=str(base / d["audio"]) if "audio" in d else None,
                split=d.get("split"),
                offset=d.get("offset", "auto"),
                format=d.get("format"),
                schema=str(base / d["schema"]) if "schema" in d and (base / d["schema"]).exists() else d.get("schema"),
                body=d.get("body"),
            )
        )
    return entries


def assign_splits(entries: list[RecordingEntry], ratios: tuple[float, float, float], seed: int) -> dict[str, str]:
    """Split of each recording (by name): explicit ones kept, the others drawn.

    The unassigned recordings are sorted by name, shuffled with ``seed`` and cut in the
    proportions ``ratios`` (train, val, test); at least one lands in train when any is drawn.
    """
    if len(ratios) != 3 or min(ratios) < 0 or sum(ratios) <= 0:
        raise KinectDataError(f"split ratios must be three non-negative numbers (train, val, test), got {ratios}")
    splits = {e.name: e.split for e in entries if e.split is not None}
    free = sorted(e.name for e in entries if e.split is None)
    if free:
        order = np.random.default_rng(seed).permutation(len(free))
        shares = np.array(ratios, float) / sum(ratios)
        n_train = max(1, int(round(shares[0] * len(free))))
        n_val = min(len(free) - n_train, int(round(shares[1] * len(free))))
        for rank, i in enumerate(order):
            splits[free[i]] = "train" if rank < n_train else "val" if rank < n_train + n_val else "test"
    return splits
