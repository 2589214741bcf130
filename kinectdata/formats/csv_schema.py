"""CSV dialect schemas: declarative descriptions of skeleton CSV files.

A schema is a JSON file validated against ``schemas/csv-schema.schema.json`` (the format is
documented in ``docs/csv-schemas.md``). kinectdata ships schemas for the Microsoft KinectReader,
LSL-Kinect and DumpKinectSkeleton dialects and for its own canonical CSV
(``schemas/csv/*.json``); a user supports another dialect by writing a schema file, with no code.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from kinectdata.core.errors import SchemaError
from kinectdata.core.jointsets import JointSet, load_joint_set, shipped_joint_sets
from kinectdata.core.resources import load_json, resolve_resource, shipped_names, shipped_path, validate

JOINT = "{joint}"
TIME_UNITS_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "ticks": 1e-7}
"""Seconds per unit of a time column (ticks: the Kinect SDK's 100-nanosecond TimeSpan ticks)."""
POSITION_UNITS_M = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "px": 1.0}
"""Metres per unit of a position column (px is kept as pixels, for 2-D joint sets)."""


@dataclass(frozen=True)
class CsvSchema:
    """A parsed, validated CSV dialect schema (field meanings: ``docs/csv-schemas.md``)."""

    name: str
    path: str
    document: dict[str, Any]

    # -- plain accessors over the validated document -------------------------------------------
    def get(self, key: str, default: Any = None) -> Any:
        return self.document.get(key, default)

    @property
    def layout(self) -> str:
        return self.document["layout"]

    @property
    def joint_set(self) -> str:
        return self.document["joint_set"]

    @property
    def delimiter(self) -> str:
        return self.document.get("delimiter", ",")

    @property
    def decimal(self) -> str:
        """The decimal separator of numbers: ``.`` (default) or ``,``."""
        return self.document.get("decimal", ".")

    @property
    def zero_is_untracked(self) -> bool:
        """A joint written as exactly all zeros is untracked (NiTE / OpenNI loggers, OpenPose)."""
        return bool(self.document["position"].get("zero_is_untracked", False))

    @property
    def has_header(self) -> bool:
        return _has_header(self.document)

    @property
    def missing_values(self) -> frozenset[str]:
        return frozenset(self.document.get("missing_values", []))

    @property
    def signature(self) -> re.Pattern[str] | None:
        sig = self.document.get("signature")
        return None if sig is None else re.compile(sig)

    @property
    def joint_names_in_file(self) -> dict[str, str]:
        """File spelling -> joint-set name."""
        return dict(self.document.get("joint_names", {}))

    def file_joint_names(self, joint_set: JointSet) -> list[str]:
        """How each joint of the set is spelled in the file, in joint-set order."""
        to_file = {v: k for k, v in self.joint_names_in_file.items()}
        return [to_file.get(n, n) for n in joint_set.names]

    def joints_in_file(self, joint_set: JointSet) -> list[int]:
        """Joint-set indices of the joints the schema says a file holds (``joints``), in file order;
        all of the set's joints when it does not say."""
        return [joint_set.index(n) for n in self.get("joints", joint_set.names)]

    def time_scale(self) -> float | None:
        """Seconds per time unit, or None when times come from a fixed frame rate."""
        t = self.document.get("time", {})
        return TIME_UNITS_S[t["unit"]] if "column" in t else None

    def position_scale(self) -> float:
        return POSITION_UNITS_M[self.document["position"]["unit"]]

    def per_joint_columns(self) -> list[str]:
        """Every column template that names a joint field (position, orientation, tracking)."""
        return _joint_field_templates(self.document)

    def headerless_columns_of(self, joint_set: JointSet) -> list[str]:
        """Column names of a headerless file of ``joint_set``: ``per_joint`` entries expanded over
        the joints the file holds (:meth:`joints_in_file`), in file order."""
        spelled = self.file_joint_names(joint_set)
        return self.headerless_columns([spelled[j] for j in self.joints_in_file(joint_set)])

    def headerless_columns(self, joint_file_names: list[str]) -> list[str]:
        """Column names of a headerless file, expanding ``per_joint`` entries over the joints."""
        names: list[str] = []
        for spec in self.document["columns"]:
            if isinstance(spec, str):
                names.append(spec)
            else:
                for joint in joint_file_names:
                    names.extend(t.replace(JOINT, joint) for t in spec["per_joint"])
        return names


def _check_semantics(doc: dict[str, Any], path: Path) -> None:
    """What JSON Schema cannot say: {joint} placement, column references, regex syntax."""
    wide = doc["layout"] == "wide"
    for tmpl in _joint_field_templates(doc):
        if wide and JOINT not in tmpl:
            raise SchemaError(path, f"wide layout: joint column {tmpl!r} must contain {JOINT}")
        if not wide and JOINT in tmpl:
            raise SchemaError(
                path, f"long layout: column {tmpl!r} must not contain {JOINT} (a 'joint' column names the joint)"
            )
    for key in ("time", "joint", "body"):
        col = doc.get(key, {}).get("column")
        if col is not None and JOINT in col:
            raise SchemaError(path, f"{key}.column {col!r} must not contain {JOINT}")
    if "signature" in doc:
        try:
            re.compile(doc["signature"])
        except re.error as exc:
            raise SchemaError(path, f"signature is not a valid regular expression: {exc}") from exc
    if doc.get("decimal", ".") == doc.get("delimiter", ","):
        raise SchemaError(path, f"decimal {doc['decimal']!r} is also the delimiter: set a different delimiter")
    if doc["joint_set"] == "auto" and not _has_header(doc):
        raise SchemaError(path, 'joint_set "auto" needs a header naming the joints')
    if "time" not in doc:
        raise SchemaError(path, "the schema must say where frame times come from: time.column + time.unit, or time.fps")
    if "columns" in doc:
        plain = {c for c in doc["columns"] if isinstance(c, str)}
        templates = {t for c in doc["columns"] if not isinstance(c, str) for t in c["per_joint"]}
        for key in ("time", "joint", "body"):
            col = doc.get(key, {}).get("column")
            if col is not None and col not in plain:
                raise SchemaError(path, f"{key}.column {col!r} is not among 'columns'")
        for tmpl in _joint_field_templates(doc):
            if tmpl not in (templates if wide else plain):
                raise SchemaError(path, f"column {tmpl!r} is not among 'columns'")


def _has_header(doc: dict[str, Any]) -> bool:
    return bool(doc.get("header", "columns" not in doc))


def _joint_field_templates(doc: dict[str, Any]) -> list[str]:
    cols = list(doc["position"]["columns"]) + list(doc.get("orientation", {}).get("columns", []))
    if "tracking" in doc:
        cols.append(doc["tracking"]["column"])
    return cols


def _from_file(path: Path) -> CsvSchema:
    doc = load_json(path)
    validate(doc, "csv-schema.schema.json", path)
    _check_semantics(doc, path)
    return CsvSchema(name=doc["name"], path=str(path), document=doc)


@cache
def _shipped(name: str) -> CsvSchema:
    return _from_file(shipped_path("csv", name))


def joint_set_of(schema: CsvSchema) -> JointSet:
    """The joint set a (non-``auto``) schema names, checked against the schema's ``joints`` and
    ``joint_names``; a SchemaError names the schema file and the field.

    ``joint_set`` is a shipped name or a joint-set JSON file; a relative file path is resolved
    from the folder of the schema file that names it, not from the working folder.
    """
    file = _joint_set_file(schema)
    try:
        js = load_joint_set(file or schema.joint_set)
    except SchemaError as exc:
        raise SchemaError(schema.path, f"joint_set {schema.joint_set!r}: {exc.reason}") from exc
    known = set(js.names) | set(js.aliases)
    seen: dict[int, str] = {}
    for name in schema.get("joints", []):
        if name not in known:
            raise SchemaError(schema.path, f"joints: {name!r} is not a joint of {js.name} ({', '.join(js.names)})")
        if js.index(name) in seen:
            raise SchemaError(schema.path, f"joints: {name!r} and {seen[js.index(name)]!r} are the same joint")
        seen[js.index(name)] = name
    for spelling, name in schema.joint_names_in_file.items():
        if name not in known:
            raise SchemaError(schema.path, f"joint_names: {spelling!r} maps to {name!r}, not a joint of {js.name}")
    return js


def _joint_set_file(schema: CsvSchema) -> Path | None:
    """The joint-set file a schema's ``joint_set`` names, resolved from the schema file's folder;
    None for a shipped joint-set name (or a bare name that is no file there: an unknown name)."""
    text = schema.joint_set
    if text in shipped_joint_sets():
        return None
    path = Path(schema.path).parent / Path(text).expanduser()  # an absolute path stays as it is
    if path.is_file():
        return path
    if path.suffix.lower() == ".json" or "/" in text or "\\" in text:
        raise SchemaError(
            schema.path,
            f"joint_set {text!r}: joint-set file not found: {path} (a relative path is resolved from the "
            "folder of the schema file)",
        )
    return None


def shipped_csv_schemas() -> list[str]:
    """Names of the CSV dialect schemas shipped with kinectdata."""
    return shipped_names("csv")


def load_csv_schema(name_or_path: str | Path | CsvSchema) -> CsvSchema:
    """A shipped schema by name, or a schema file by path; SchemaError if invalid."""
    if isinstance(name_or_path, CsvSchema):
        return name_or_path
    name, path = resolve_resource("csv", name_or_path, "CSV schema")
    return _shipped(name) if name else _from_file(path)
