"""Access to the declarative files shipped inside the package (``kinectdata/schemas``).

They are package data, so they are found the same way after an editable install, a wheel
install or from a source checkout.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

from kinectdata.core.errors import SchemaError


def schemas_dir() -> Path:
    """Folder of the shipped schema files (``kinectdata/schemas``)."""
    return Path(str(resources.files("kinectdata") / "schemas"))


def shipped_names(kind: str) -> list[str]:
    """Names (file stems) of the shipped files of one kind (a folder of ``schemas/``: ``jointsets``, ``csv``)."""
    return list(_shipped_names(kind))


@cache
def _shipped_names(kind: str) -> tuple[str, ...]:  # the package's files do not change while it runs
    return tuple(sorted(p.stem for p in (schemas_dir() / kind).glob("*.json")))


def shipped_path(kind: str, name: str) -> Path:
    """Path of the shipped file ``schemas/<kind>/<name>.json``; SchemaError if there is none."""
    path = schemas_dir() / kind / f"{name}.json"
    if not path.is_file():
        known = ", ".join(shipped_names(kind)) or "none"
        raise SchemaError(path, f"no shipped {kind} file named {name!r} (shipped: {known})")
    return path


def resolve_resource(kind: str, name_or_path: str | Path, what: str) -> tuple[str | None, Path]:
    """Where a resource given as "a shipped name or a path" is: ``(name, path)`` for a shipped file
    (``schemas/<kind>/<name>.json``), ``(None, path)`` for a file of the user's.

    A shipped name wins over a file of that name in the working folder. SchemaError when neither
    exists: naming the path when the text looks like one (it ends in ``.json`` or holds a ``/``),
    else listing the shipped names (``what`` is how the message calls the resource, e.g.
    "CSV schema").
    """
    text = str(name_or_path)
    if text in shipped_names(kind):
        return text, shipped_path(kind, text)
    path = Path(text)
    if path.exists():
        return None, path
    if path.suffix.lower() == ".json" or "/" in text:
        raise SchemaError(path, f"{what} file not found")
    raise SchemaError(
        None,
        f"unknown {what} {text!r}: no such file, and no shipped {what} has that name "
        f"(shipped: {', '.join(shipped_names(kind)) or 'none'})",
    )


def load_json(path: str | Path) -> Any:
    """Parse a JSON file, raising SchemaError with the line and column of a syntax error."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SchemaError(path, f"cannot read file: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise SchemaError(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise SchemaError(path, f"invalid JSON: {exc.msg} (column {exc.colno})", line=exc.lineno) from exc


@cache
def _validator(meta_schema_name: str):
    import jsonschema

    schema = load_json(schemas_dir() / meta_schema_name)
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema)


def validate(document: Any, meta_schema_name: str, path: str | Path) -> None:
    """Validate a parsed document against a shipped JSON Schema (``schemas/<meta_schema_name>``).

    Raises SchemaError naming the file, the JSON path of the first problem and what is wrong.
    """
    errors = sorted(_validator(meta_schema_name).iter_errors(document), key=lambda e: list(e.absolute_path))
    if errors:
        err = errors[0]
        where = "/".join(str(p) for p in err.absolute_path) or "(top level)"
        more = f" (and {len(errors) - 1} more problems)" if len(errors) > 1 else ""
        raise SchemaError(path, f"at {where}: {err.message}{more}")
