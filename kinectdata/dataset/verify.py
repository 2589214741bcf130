"""``verify``: a dataset folder checked against its manifest, every problem reported at once.

What is checked:

- ``manifest.json`` is JSON that follows ``schemas/dataset-manifest.schema.json`` (every violation
  is listed), and its own accounts agree: each shard listed once, each record in a listed shard of
  its split, each split's shards, rows and recordings and the totals those of the shards and records;
- every listed shard is there, with the manifest's size and SHA-256, follows the layout
  ``schemas/shard-layout.json`` (:func:`.shards.validate_shard`), has the split, normalisation,
  target spec and features the manifest states, and holds the rows and recordings index the
  manifest lists for it.

When the manifest is missing, unreadable or breaks its schema, the files named like shards are
still checked against the layout. Each problem is a :class:`~kinectdata.core.errors.FormatError` or
:class:`~kinectdata.core.errors.SchemaError` naming the file it lies in.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py

from kinectdata.core.errors import FormatError, InputError, SchemaError
from kinectdata.core.hashing import file_sha256
from kinectdata.core.resources import load_json, schemas_dir
from kinectdata.dataset.layout import MANIFEST, MANIFEST_SCHEMA, SHARD_NAME, SPLITS
from kinectdata.dataset.shards import json_attribute, read_index, validate_shard


def _schema_problems(manifest: Any, path: Path) -> list[InputError]:
    """Every violation of the manifest schema, by place in the document."""
    import jsonschema

    schema = load_json(schemas_dir() / MANIFEST_SCHEMA)
    validator = jsonschema.validators.validator_for(schema)(schema)
    errors = sorted(validator.iter_errors(manifest), key=lambda e: [str(p) for p in e.absolute_path])
    return [
        SchemaError(path, f"at {'/'.join(str(p) for p in e.absolute_path) or '(top level)'}: {e.message}")
        for e in errors
    ]


def manifest_problems(folder: str | Path) -> tuple[dict[str, Any] | None, list[InputError]]:
    """A dataset folder's manifest and what is wrong with it as a document: missing, not JSON, each
    schema violation. The manifest is None unless it is valid."""
    folder = Path(folder)
    path = folder / MANIFEST
    if folder.is_file():
        return None, [FormatError(folder, "a file, not a dataset folder (give the folder build-dataset wrote)")]
    if not folder.is_dir():
        return None, [FormatError(folder, "not a dataset folder (no such folder)")]
    if not path.is_file():
        missing = "no manifest.json: not a dataset, or a build that did not finish (run it again)"
        return None, [FormatError(folder, missing)]
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        return None, [FormatError(path, f"not valid JSON ({exc})")]
    problems = _schema_problems(manifest, path)
    return (None if problems else manifest), problems


def _first_of(problems: list[InputError], command: str) -> InputError:
    """The first problem, saying how many more there are and how to list them."""
    first = problems[0]
    if len(problems) == 1:
        return first
    where = {"line": first.line, "frame": first.frame, "record": first.record, "column": first.column}
    return type(first)(first.path, f"{first.reason} (and {len(problems) - 1} more problems: {command})", **where)


def read_manifest(folder: str | Path) -> dict[str, Any]:
    """The manifest of a dataset folder, checked against its schema (not against the shards).

    Raises:
        FormatError: no such folder, no manifest or one that is not JSON.
        SchemaError: the manifest breaks its schema (the first violation, and how many more).
    """
    manifest, problems = manifest_problems(folder)
    if problems:
        raise _first_of(problems, f"kinectdata verify {folder} lists them")
    return manifest


def verify_dataset(folder: str | Path, *, checksums: bool = True) -> list[InputError]:
    """Every problem of a dataset folder (see the module's description); empty when it is intact.
    ``checksums=False`` skips the shards' SHA-256 (sizes, layout and the manifest's accounts are
    still checked): about 1 s per GB saved."""
    folder = Path(folder)
    manifest, problems = manifest_problems(folder)
    if manifest is None:
        if folder.is_dir():
            for path in sorted(p for p in folder.iterdir() if SHARD_NAME.fullmatch(p.name)):
                problems += _layout_problems(path)
        return problems
    problems += _account_problems(folder / MANIFEST, manifest)
    for listed in manifest["shards"]:
        problems += _shard_problems(folder, manifest, listed, checksums)
    return problems


def verified_manifest(folder: str | Path, *, checksums: bool = True) -> dict[str, Any]:
    """The manifest of a dataset folder in which :func:`verify_dataset` finds nothing wrong
    (``checksums``: as there).

    Raises:
        FormatError, SchemaError: the first problem found, and how many more there are.
    """
    problems = verify_dataset(folder, checksums=checksums)
    if problems:
        raise _first_of(problems, f"kinectdata verify {folder} lists them")
    return json.loads((Path(folder) / MANIFEST).read_text(encoding="utf-8"))


def _layout_problems(path: Path) -> list[InputError]:
    try:
        validate_shard(path)
    except FormatError as exc:
        return [exc]
    return []


def _account_problems(path: Path, manifest: dict[str, Any]) -> list[InputError]:
    """Where the manifest's accounts of shards, records, splits and totals disagree with each other."""
    problems: list[InputError] = []
    shards, records = manifest["shards"], manifest["recordings"]
    split_of = {s["file"]: s["split"] for s in shards}
    if len(split_of) != len(shards):
        problems.append(FormatError(path, "a shard is listed twice"))
    for i, r in enumerate(records):
        if r["shard"] not in split_of:
            problems.append(FormatError(path, f"recordings[{i}] ({r['name']}) is in {r['shard']}, a shard not listed"))
        elif r["split"] != split_of[r["shard"]]:
            problems.append(
                FormatError(path, f"recordings[{i}] ({r['name']}) is {r['split']} but in {split_of[r['shard']]} shard")
            )
    for split in SPLITS:
        said = manifest["splits"].get(split, {"recordings": [], "rows": 0, "shards": []})
        actual = {
            "shards": [s["file"] for s in shards if s["split"] == split],
            "rows": sum(s["frames"] for s in shards if s["split"] == split),
            "recordings": sorted({r["recording"] for r in records if r["split"] == split}),
        }
        for key, value in actual.items():
            if said[key] != value:
                problems.append(FormatError(path, f"splits.{split}.{key} is {said[key]}, the shards hold {value}"))
    totals = {"rows": sum(s["frames"] for s in shards), "recordings": len(records), "shards": len(shards)}
    for key, value in totals.items():
        if manifest["totals"][key] != value:
            problems.append(FormatError(path, f"totals.{key} is {manifest['totals'][key]}, the shards hold {value}"))
    return problems


def _shard_problems(
    folder: Path, manifest: dict[str, Any], listed: dict[str, Any], checksums: bool = True
) -> list[InputError]:
    """A listed shard against the manifest's account of it and the layout."""
    path = folder / listed["file"]
    if not path.is_file():
        return [FormatError(path, f"missing: {MANIFEST} lists it ({listed['split']} split, {listed['frames']} rows)")]
    problems: list[InputError] = []
    size = path.stat().st_size
    if size != listed["bytes"]:
        problems.append(FormatError(path, f"is {size} bytes, the manifest says {listed['bytes']}"))
    if checksums and file_sha256(path) != listed["sha256"]:
        problems.append(FormatError(path, "checksum differs from the manifest's: the shard was changed or damaged"))
    try:
        sizes = validate_shard(path)
    except FormatError as exc:
        return problems + [exc]
    with h5py.File(path, "r") as f:
        own = [(r["name"], r["start"], r["length"]) for r in read_index(f)]
        attributes = {
            "split": (str(f.attrs["split"]), listed["split"]),
            "normalisation": (json_attribute(f, "normalisation"), manifest["normalisation"]),
            "target_spec": (json_attribute(f, "target_spec"), manifest["config"]["target"]),
            "features": (
                _without_extractor(json_attribute(f, "features")),
                _without_extractor(manifest["config"]["features"]),
            ),
        }
    for key, (value, said) in attributes.items():
        if value != said:
            problems.append(FormatError(path, f"attribute {key!r} differs from the manifest's"))
    if sizes["N"] != listed["frames"]:
        problems.append(FormatError(path, f"holds {sizes['N']} rows, the manifest says {listed['frames']}"))
    if len(own) != listed["recordings"]:
        problems.append(FormatError(path, f"holds {len(own)} recordings, the manifest says {listed['recordings']}"))
    said = [(r["name"], r["start"], r["frames"]) for r in manifest["recordings"] if r["shard"] == listed["file"]]
    if own != said:
        problems.append(
            FormatError(
                folder / MANIFEST,
                f"its recordings in {path.name} ({said[:3]}...) differ from the shard's own index ({own[:3]}...)",
            )
        )
    return problems


def _without_extractor(features: Any) -> Any:
    """A feature configuration without its ``extractor`` key, which shards state and manifests may not."""
    return {k: v for k, v in features.items() if k != "extractor"} if isinstance(features, dict) else features
