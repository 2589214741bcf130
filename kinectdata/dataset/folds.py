"""Cross-validation folds of a recordings manifest: choosing a recipe on a small corpus.

A corpus of a few dozen recordings has a validation split of a few: three songs cannot tell two
training recipes apart (no rank correlation or pairing figure over three songs reaches p < 0.05),
and a test split must never be used to choose. ``k`` folds deal the recordings that are not in the
test split into ``k`` groups; fold ``i``'s manifest validates on group ``i`` and trains on the
others, so every recording is validated on once, by a model that did not train on it, and the
test recordings appear in no fold at all. Each group gets its share of each ``by`` value (a
style's or a metre's recordings are dealt round the folds in turn), so a rare style is validated
on in as many folds as it has recordings.

The fold manifests are written beside the source (``tang.yaml`` -> ``tang.fold1of3.yaml``...), so
that the paths they list, relative to the manifest's folder or its ``root``, stay as they are.
"""

from __future__ import annotations

import random
import re
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import ConfigError
from kinectdata.dataset.inputs import _read_manifest, read_recordings

GROUPINGS = ("style", "beats_per_bar", "none")
"""What a fold's share is balanced by: a manifest field, or nothing."""


@dataclass(frozen=True)
class Fold:
    """One fold: its manifest file and the recordings it validates and trains on (names)."""

    index: int
    count: int
    path: Path
    validation: list[str]
    training: list[str]


def fold_path(source: Path, index: int, count: int) -> Path:
    """Where fold ``index`` of ``count`` of ``source`` is written: beside it, ``<stem>.fold<i>of<k>.yaml``."""
    return source.with_name(f"{source.stem}.fold{index}of{count}.yaml")


def deal_folds(entries: list[dict[str, Any]], count: int, by: str = "style", seed: int = 0) -> list[list[str]]:
    """The names of the recordings each of ``count`` folds validates on.

    Recordings the manifest puts in the test split are in none; the others are grouped by their
    ``by`` field (``"none"``: one group; a recording without the field: a group of its own kind),
    shuffled within each group by ``seed``, and dealt round the folds in turn, each group starting
    where the last one stopped, so the folds differ in size by at most one.

    Raises:
        ConfigError: fewer than 2 folds, or more folds than recordings to deal.
    """
    if by not in GROUPINGS:
        raise ConfigError(f"folds are balanced by one of {', '.join(GROUPINGS)}, not {by!r}")
    dealt = [e for e in entries if e.get("split") != "test"]
    if count < 2 or count > len(dealt):
        raise ConfigError(f"{count} folds of {len(dealt)} recordings (not in the test split): give 2 to {len(dealt)}")
    groups: dict[str, list[str]] = defaultdict(list)
    for entry in dealt:
        groups["" if by == "none" else str(entry.get(by, ""))].append(entry["name"])
    rng = random.Random(seed)
    folds: list[list[str]] = [[] for _ in range(count)]
    turn = 0
    for key in sorted(groups):
        names = sorted(groups[key])
        rng.shuffle(names)
        for name in names:
            folds[turn % count].append(name)
            turn += 1
    return folds


def write_folds(source: str | Path, count: int, by: str = "style", seed: int = 0) -> list[Fold]:
    """Write ``count`` fold manifests beside the recordings manifest ``source`` (:func:`fold_path`).

    Each is the source with its test recordings left out and every other recording's ``split``
    set to ``val`` (its fold's group, :func:`deal_folds`) or ``train``; everything else is kept.

    Raises:
        SchemaError: the manifest cannot be read or lists a file that does not exist.
        ConfigError: see :func:`deal_folds`; a manifest that is a folder (it has no file to sit beside).
    """
    import yaml

    source = Path(source)
    if source.is_dir():
        raise ConfigError(f"{source}: folds are made from a recordings manifest file, not a folder")
    listed = read_recordings(source, allow_outside_paths=True)  # every entry valid, named, its files there
    docs = _read_manifest(source)[0]
    entries = [{**doc, "name": entry.name} for doc, entry in zip(docs, listed)]
    document = _document(source)
    folds, texts = [], []
    for index, validation in enumerate(deal_folds(entries, count, by, seed), start=1):
        chosen = set(validation)
        recordings = [
            {**doc, "split": "val" if e["name"] in chosen else "train"}
            for doc, e in zip(docs, entries)
            if e.get("split") != "test"
        ]
        texts.append(yaml.safe_dump({**document, "recordings": recordings}, sort_keys=False, allow_unicode=True))
        training = [e["name"] for e in entries if e.get("split") != "test" and e["name"] not in chosen]
        folds.append(Fold(index, count, fold_path(source, index, count), sorted(validation, key=_natural), training))
    written = []
    try:
        for fold, text in zip(folds, texts):
            with atomic_output(fold.path) as tmp:
                tmp.write_text(text, encoding="utf-8")
            written.append(fold.path)
    except BaseException:  # all the folds or none: a set missing one would be compared as if whole
        for path in written:
            path.unlink(missing_ok=True)
        raise
    return folds


def _natural(name: str) -> list:
    """Sort key putting W_5 before W_10."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", name)]


def _document(source: Path) -> dict[str, Any]:
    """The source manifest's keys other than its recordings (root, corpus, description, songs), kept."""
    import yaml

    if source.suffix.lower() == ".csv":
        return {}
    loaded = yaml.safe_load(source.read_text(encoding="utf-8-sig"))  # JSON is YAML too
    return {k: v for k, v in loaded.items() if k != "recordings"} if isinstance(loaded, dict) else {}
