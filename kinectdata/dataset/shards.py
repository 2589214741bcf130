"""Dataset shards: HDF5 files of whole recordings, in the layout ``schemas/shard-layout.json``.

A shard holds the rows (motion frames) of one split's recordings, each recording's rows
contiguous: ``input`` [N, 1, 129, 5] features, ``current`` [N, D] normalised targets, ``mask``
[N, D], ``audio_padded`` [N] and a ``recordings`` index (name, start, length, info). Rows are
chunked along N in blocks of :data:`CHUNK_ROWS` so that reading a training sequence touches few
chunks. :func:`validate_shard` checks a file against the layout.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from kinectdata.core.atomic import atomic_hdf5
from kinectdata.core.errors import FormatError, KinectDataError
from kinectdata.core.resources import load_json, schemas_dir
from kinectdata.core.version import __version__
from kinectdata.dataset.isolation import check_isolated
from kinectdata.features import feature_config
from kinectdata.targets.specs import TargetSpec

FORMAT = "kinectdata.shard"
FORMAT_VERSION = 1
CHUNK_ROWS = 256


def layout() -> dict[str, Any]:
    """The shard layout specification (``schemas/shard-layout.json``)."""
    return load_json(schemas_dir() / "shard-layout.json")


@dataclass
class ShardRecording:
    """One recording's rows, ready to be written into a shard."""

    name: str
    input: Any  # [n, F, B, T] float32 array or h5py dataset
    current: np.ndarray  # [n, D] float32
    mask: np.ndarray  # [n, D] bool
    audio_padded: np.ndarray  # [n] bool
    info: dict[str, Any]

    @property
    def n_rows(self) -> int:
        return int(self.current.shape[0])


def row_bytes(feature_shape: tuple[int, ...], dim: int) -> int:
    """Bytes one row takes in a shard (uncompressed): features, target, mask and padding flag."""
    return int(np.prod(feature_shape)) * 4 + dim * 5 + 1


def write_shard(
    path: str | Path,
    recordings: list[ShardRecording],
    attributes: dict[str, Any],
    *,
    compression: str | None = None,
) -> None:
    """Write a shard atomically (a temporary file renamed into place).

    ``attributes`` hold the layout's attributes (JSON ones as dicts); format, version and
    created_by are added here.
    """
    n = sum(r.n_rows for r in recordings)
    feature_shape = tuple(recordings[0].input.shape[1:])
    dim = recordings[0].current.shape[1]
    kw: dict[str, Any] = {"track_times": False}
    if compression:
        kw["compression"] = compression
        kw["shuffle"] = True

    with atomic_hdf5(path) as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        for key, value in attributes.items():
            f.attrs[key] = json.dumps(value, sort_keys=True) if isinstance(value, (dict, list)) else value
        f.attrs["created_by"] = f"kinectdata {__version__}"

        def dataset(name: str, shape: tuple[int, ...], dtype) -> h5py.Dataset:
            chunks = (min(CHUNK_ROWS, max(n, 1)), *shape[1:])
            return f.create_dataset(name, shape=shape, dtype=dtype, chunks=chunks, **kw)

        d_in = dataset("input", (n, *feature_shape), np.float32)
        d_cur = dataset("current", (n, dim), np.float32)
        d_mask = dataset("mask", (n, dim), bool)
        d_pad = dataset("audio_padded", (n,), bool)
        start = 0
        for r in recordings:
            for s in range(0, r.n_rows, CHUNK_ROWS * 16):  # copy features in slices: bounded memory
                e = min(r.n_rows, s + CHUNK_ROWS * 16)
                d_in[start + s : start + e] = r.input[s:e]
            d_cur[start : start + r.n_rows] = r.current
            d_mask[start : start + r.n_rows] = r.mask
            d_pad[start : start + r.n_rows] = r.audio_padded
            start += r.n_rows
        g = f.create_group("recordings")
        lengths = np.array([r.n_rows for r in recordings], np.int64)
        g.create_dataset("name", data=np.array([r.name for r in recordings], dtype=h5py.string_dtype()), **kw)
        g.create_dataset("start", data=np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64), **kw)
        g.create_dataset("length", data=lengths, **kw)
        infos = [json.dumps(r.info, sort_keys=True, default=str) for r in recordings]
        g.create_dataset("info", data=np.array(infos, dtype=h5py.string_dtype()), **kw)


_DAMAGE = (OSError, KeyError, ValueError, TypeError, RuntimeError)
"""What h5py raises on a damaged file (bad signatures or checksums, truncated heaps, odd types)."""


def read_index(f: h5py.File) -> list[dict[str, Any]]:
    """The recordings of an open shard: ``name``, ``start``, ``length``, ``info`` (dict).

    Raises:
        FormatError: naming the shard, when the index cannot be read or an entry is not a UTF-8
            name with a JSON object as info.
    """
    try:
        g = f["recordings"]
        columns = [g[k][()] for k in ("name", "start", "length", "info")]
    except _DAMAGE as exc:
        raise FormatError(f.filename, f"cannot read the recordings index ({exc})") from None
    if any(np.ndim(c) != 1 or len(c) != len(columns[0]) for c in columns):
        shapes = ", ".join(f"{k} {np.shape(c)}" for k, c in zip(("name", "start", "length", "info"), columns))
        raise FormatError(f.filename, f"the recordings index columns must be lists of one length, found {shapes}")
    index = []
    for i, (name, start, length, info) in enumerate(zip(*columns)):
        try:
            entry = {"name": _text(name), "start": int(start), "length": int(length), "info": json.loads(_text(info))}
        except (ValueError, TypeError) as exc:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
            raise FormatError(f.filename, f"recordings[{i}] cannot be read ({exc})") from None
        if not isinstance(entry["info"], dict):
            raise FormatError(f.filename, f"recordings[{i}] info is not a JSON object")
        index.append(entry)
    return index


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _parse_json(path: Path, key: str, value: Any) -> Any:
    try:
        return json.loads(value.decode() if isinstance(value, bytes) else value)
    except (TypeError, ValueError) as exc:  # not text; not JSON or not UTF-8
        raise FormatError(path, f"attribute {key!r} is not JSON text ({exc})") from None


def json_attribute(f: h5py.File, key: str) -> Any:
    """An attribute of an open shard holding JSON text, parsed; FormatError naming the shard if it
    is missing or not JSON."""
    try:
        value = f.attrs[key]
        return json.loads(value.decode() if isinstance(value, bytes) else value)
    except _DAMAGE as exc:  # KeyError: missing; TypeError: not text; ValueError: not JSON or not UTF-8
        raise FormatError(f.filename, f"attribute {key!r} is not JSON text ({exc})") from None


_DTYPES = {"float32": np.float32, "int64": np.int64, "bool": np.bool_}
_ATTRIBUTE_TYPES = {
    "string": (str,),
    "json": (str, bytes),
    "integer": (int, np.integer),
    "number": (int, float, np.integer, np.floating),
    "boolean": (bool, np.bool_),
}


ISOLATION_TIMEOUT_S = 120.0
"""Longest the child process of :func:`validate_shard` may take to read a shard's structure."""


def validate_shard(path: str | Path, *, isolated: bool = True) -> dict[str, int]:
    """Check a shard against the layout; returns its sizes ``{"N", "D", "R", ...}``.

    The HDF5 library itself can crash or loop forever on some damaged files (libhdf5 2.0 on a
    corrupted global heap collection or object header), which no exception handling contains:
    with ``isolated`` (the default) the check runs in a child process, so that such a file is a
    FormatError too (:mod:`kinectdata.dataset.isolation`: one child process serves the checks of a
    process in turn, so only the first pays for starting a Python interpreter, about 0.25 s).

    Raises:
        FormatError: naming the shard and the attribute or dataset that is wrong, or what HDF5
            reported about a damaged file.
    """
    path = Path(path)
    if isolated:
        return check_isolated(path, ISOLATION_TIMEOUT_S)
    spec = layout()
    try:
        f = h5py.File(path, "r")
    except _DAMAGE as exc:
        raise FormatError(path, f"not a readable HDF5 file ({exc})") from exc
    with f:
        attrs, datasets = _read_layout(f, path, spec)
        sizes = _validate(path, spec, attrs, datasets)
        _check_index(path, read_index(f), sizes)
        _check_json_attributes(f, path, sizes, datasets["input"][1])
        return sizes


_MISSING = object()


def _read_layout(f: h5py.File, path: Path, spec: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The layout's attributes (value or ``_MISSING``) and datasets (``(dtype, shape)`` or None where
    absent or not a dataset) of an open shard. Only this reading is guarded against what h5py raises
    on a damaged file (:data:`_DAMAGE`): the checks that follow are plain Python, so a bug in them
    surfaces as itself."""
    try:
        attrs = {key: f.attrs[key] if key in f.attrs else _MISSING for key in spec["attributes"]}
        datasets = {}
        for name in spec["datasets"]:
            d = f[name] if name in f else None
            datasets[name] = (d.dtype, tuple(d.shape)) if isinstance(d, h5py.Dataset) else None
        return attrs, datasets
    except _DAMAGE as exc:
        raise FormatError(path, f"damaged HDF5 file ({type(exc).__name__}: {exc})") from exc


def _validate(path: Path, spec: dict[str, Any], attrs: dict[str, Any], datasets: dict[str, Any]) -> dict[str, int]:
    """The attributes and datasets read by :func:`_read_layout` against the layout; the sizes."""
    for key, rule in spec["attributes"].items():
        value = attrs[key]
        if value is _MISSING:
            raise FormatError(path, f"missing attribute {key!r} ({rule.get('description', rule['type'])})")
        if not _has_type(value, rule["type"]):
            raise FormatError(path, f"attribute {key!r} is {_show(value)}, expected {rule['type']}")
        if "const" in rule and value != rule["const"]:
            raise FormatError(path, f"attribute {key!r} is {_show(value)}, expected {rule['const']!r}")
        if rule["type"] == "json":
            _parse_json(path, key, value)
    sizes: dict[str, int] = {}
    for name, rule in spec["datasets"].items():
        if datasets[name] is None:
            raise FormatError(path, f"missing dataset {name!r}")
        dtype, shape = datasets[name]
        if rule["dtype"] == "string":
            if dtype.kind not in "OSU":
                raise FormatError(path, f"dataset {name!r} has dtype {dtype}, expected strings")
        elif dtype != _DTYPES[rule["dtype"]]:
            raise FormatError(path, f"dataset {name!r} has dtype {dtype}, expected {rule['dtype']}")
        open_ended = rule["shape"][-1] == "..."  # any further axes (checked against an attribute)
        fixed = rule["shape"][:-1] if open_ended else rule["shape"]
        if len(shape) < len(fixed) or (not open_ended and len(shape) != len(fixed)):
            raise FormatError(path, f"dataset {name!r} has shape {shape}, expected {rule['shape']}")
        for axis, (want, got) in enumerate(zip(fixed, shape)):
            if isinstance(want, int):
                ok = want == got
            else:
                ok = sizes.setdefault(want, got) == got
            if not ok:
                raise FormatError(path, f"dataset {name!r} axis {axis} is {got}, expected {sizes.get(want, want)}")
    return sizes


def _check_index(path: Path, index: list[dict[str, Any]], sizes: dict[str, int]) -> None:
    """The recordings index covers the rows in order, each recording at least one row."""
    expected = 0
    for i, r in enumerate(index):
        where = f"recordings[{i}] ({r['name']})"
        if r["length"] <= 0:
            raise FormatError(path, f"{where} has {r['length']} rows")
        if r["start"] != expected:
            raise FormatError(path, f"{where} starts at row {r['start']}, expected {expected}")
        expected += r["length"]
    if expected != sizes["N"]:
        raise FormatError(path, f"the recordings cover {expected} rows, the shard has {sizes['N']}")


def _has_type(value: Any, kind: str) -> bool:
    if not isinstance(value, _ATTRIBUTE_TYPES[kind]):
        return False
    if kind in ("integer", "number") and isinstance(value, bool):
        return False
    return kind != "number" or bool(np.isfinite(value))


def _show(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


@cache
def _json_attribute_validator():
    """The JSON Schema of the shard's JSON attributes (``schemas/shard-json-attributes.schema.json``)."""
    import jsonschema

    schema = load_json(schemas_dir() / "shard-json-attributes.schema.json")
    return jsonschema.validators.validator_for(schema)(schema)


def _check_json_attributes(f: h5py.File, path: Path, sizes: dict[str, int], input_shape: tuple[int, ...]) -> None:
    """The JSON attributes say what the datasets hold: check they agree with them."""
    doc = {key: json_attribute(f, key) for key in ("target_spec", "normalisation", "features")}
    problem = next(iter(sorted(_json_attribute_validator().iter_errors(doc), key=lambda e: list(e.path))), None)
    if problem is not None:
        key = str(problem.path[0]) if problem.path else "?"
        what = {
            "target_spec": "is not a target spec (positions and orientations lists)",
            "normalisation": "must hold 'scale' and 'offset' lists of numbers",
            "features": "is not a feature configuration (a JSON object)",
        }.get(key, "is not valid")
        at = "/".join(str(p) for p in list(problem.path)[1:])
        raise FormatError(path, f"attribute {key!r} {what}: {problem.message}" + (f" at {at}" if at else ""))
    spec, norm, feats = doc["target_spec"], doc["normalisation"], doc["features"]
    try:
        dim = TargetSpec.from_dict(spec).dim
    except (KinectDataError, KeyError, TypeError, ValueError) as exc:
        raise FormatError(path, f"attribute 'target_spec' is not a valid target spec ({exc})") from None
    if dim != sizes["D"]:
        raise FormatError(path, f"'current' has {sizes['D']} components, the target spec {dim}")
    if any(len(norm[k]) != dim for k in ("scale", "offset")):
        raise FormatError(path, f"attribute 'normalisation' must hold 'scale' and 'offset' lists of {dim} numbers")
    try:
        shape = feature_config(feats).output_shape
    except (KeyError, TypeError, ValueError) as exc:
        raise FormatError(path, f"attribute 'features' is not a valid feature configuration ({exc})") from None
    if tuple(input_shape[1:]) != tuple(shape):
        raise FormatError(path, f"'input' holds frames of shape {list(input_shape[1:])}, the features {list(shape)}")
