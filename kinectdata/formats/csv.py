"""Skeleton CSV files in any dialect a CSV schema describes (see :mod:`.csv_schema`).

Reading: the dialect is the ``schema`` given (a shipped name or a schema file) or, when none is
given, the one shipped schema that recognises the file (by its signature line, header or field
count). Every cell that must be a number is checked; a bad cell, a row with the wrong number of
fields, time going backwards, a repeated timestamp or joint, an unknown joint name, a missing
column or a file that does not look like the dialect at all raises
:class:`~kinectdata.core.errors.FormatError` naming the file, line and column (with a hint when
numbers look written with decimal commas). A headered file may hold only some joints of its set:
the absent ones are masked.

Writing is :mod:`.csv_writer`, over the same schemas.
"""

from __future__ import annotations

import csv
import functools
import itertools
import math
import re
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from kinectdata.core.errors import FormatError, KinectDataError, SchemaError
from kinectdata.core.jointsets import (
    JointSet,
    find_joint_set,
    joint_set_from_text,
    load_joint_set,
    shipped_joint_sets,
)
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import reorder, split_missing_and_normalise
from kinectdata.formats.common import choose_body, count_bodies, first_bad_time, to_kinectdata_axes
from kinectdata.formats.csv_schema import JOINT, CsvSchema, joint_set_of, load_csv_schema, shipped_csv_schemas
from kinectdata.formats.registry import register_reader

if TYPE_CHECKING:  # pandas is imported where a file is parsed: it costs 0.25 s at start-up
    import pandas as pd

_META_LINE = re.compile(r"^\s*([A-Za-z_][\w.-]*)\s*:\s*(.*?)\s*$")
_DETECT_LINES = 64


# ---------------------------------------------------------------------------------------------
# Reading the text into a table with line numbers
# ---------------------------------------------------------------------------------------------
_CHUNK_ROWS = 4096  # rows parsed at a time: memory grows with the columns kept, not the text


@dataclass
class _Table:
    """A CSV file's layout from a first pass over its lines, and the cells of the columns a
    reader needs from a second, chunked pass (:meth:`load`), so that the whole text is never
    held in memory."""

    path: Path
    schema: CsvSchema
    names: list[str]
    lines: np.ndarray  # [R] 1-based line number of each data row
    skipped: list[int]  # 0-based indices of the lines that are not data rows
    encoding: str
    header_line: int | None = None
    meta: dict[str, str] = field(default_factory=dict)
    bad_row: tuple[int, int, str] | None = None  # (line, fields, text) of the first row with a wrong field count

    def __post_init__(self) -> None:
        self._position = {n: i for i, n in enumerate(self.names)}
        self._numbers: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._texts: dict[str, np.ndarray] = {}

    def has(self, column: str) -> bool:
        return column in self._position

    def load(self, numeric: set[str], text: set[str]) -> None:
        """Parse the given columns (numbers checked cell by cell, text kept as strings)."""
        import pandas as pd

        if self.bad_row is not None:
            line, found, text = self.bad_row
            what = "the header" if self.header_line is not None else f"the {self.schema.name} schema"
            reason = f"expected {len(self.names)} fields as {what} says, found {found}"
            raise FormatError(self.path, reason + _decimal_comma_hint(text, self.schema), line=line)
        columns = sorted(numeric | text, key=self._position.__getitem__)
        if not columns:
            return
        missing_text = sorted(self.schema.missing_values)
        reader = pd.read_csv(
            self.path,
            sep=self.schema.delimiter,
            decimal=self.schema.decimal,
            header=None,
            names=list(range(len(self.names))),
            index_col=False,  # a trailing delimiter's empty field is dropped, whether or not the first row has one
            usecols=[self._position[c] for c in columns],
            skiprows=set(self.skipped),
            chunksize=_CHUNK_ROWS,
            encoding=self.encoding,
            skipinitialspace=True,
            na_filter=bool(missing_text),
            na_values=missing_text,
            keep_default_na=False,
            dtype={self._position[c]: str for c in text},
            skip_blank_lines=False,
            low_memory=False,
            quoting=csv.QUOTE_NONE,  # rows and fields as the first pass split them: a stray quote spans no lines
            encoding_errors="replace",  # cp1252 leaves 5 bytes undefined; the first pass replaced them too
        )
        # numbers go straight into arrays of the first pass's row count: no per-chunk pieces to join,
        # which would hold every column twice at the end
        rows = len(self.lines)
        numbers = {c: (np.empty(rows), np.empty(rows, bool)) for c in columns if c not in text}
        texts: dict[str, list] = {c: [] for c in columns if c in text}
        done = 0
        for chunk, lines in self._chunks(reader):
            for c in columns:
                series = chunk[self._position[c]]
                if c in text:
                    texts[c].append(_unquote(series.fillna("").astype(str)).to_numpy(dtype=object))
                else:
                    rows_here = slice(done, done + len(chunk))
                    values, missing = numbers[c]
                    values[rows_here], missing[rows_here] = self._convert(series, c, lines)
            done += len(chunk)
        for c, (values, missing) in numbers.items():
            self._numbers[c] = (values[:done], missing[:done])
        for c, pieces in texts.items():
            self._texts[c] = np.concatenate(pieces) if pieces else np.zeros(0, object)

    def _chunks(self, reader: Iterator[pd.DataFrame]) -> Iterator[tuple[pd.DataFrame, np.ndarray]]:
        """pandas' chunks with the line numbers of their rows, checking that pandas finds the rows the
        first pass found (the line numbers of every error depend on it)."""
        import pandas as pd

        start = 0
        while True:
            at = int(self.lines[min(start, len(self.lines) - 1)])
            try:
                chunk = next(reader)
            except StopIteration:
                break
            except pd.errors.ParserError as exc:
                raise FormatError(self.path, f"cannot parse the rows from here on ({exc})", line=at) from None
            if start + len(chunk) > len(self.lines):
                break
            yield chunk, self.lines[start : start + len(chunk)]
            start += len(chunk)
        if start != len(self.lines):
            message = "the CSV parser and the line scan disagree on the rows from here on (a stray line end?)"
            raise FormatError(self.path, message, line=at)

    def _convert(self, series: pd.Series, column: str, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """([n] float64 values, [n] bool missing) of one chunk of a numeric column, checking every cell.

        Cells listed in the schema's ``missing_values`` are missing (value NaN). Any other cell
        that is not a finite number raises FormatError with its line and column.
        """
        import pandas as pd

        if pd.api.types.is_numeric_dtype(series.dtype):
            # NaN here can only be a missing_values cell: other text keeps the column as strings
            values = series.to_numpy(dtype=np.float64, copy=True)
            missing = np.isnan(values)
        else:
            # as text: pandas keeps integers beyond 64 bits as Python ints, which to_numeric cannot convert
            values = self._to_float(series.astype(str))
            missing = np.zeros(values.shape, bool)
            failed = np.flatnonzero(np.isnan(values))
            if failed.size:  # look at the text only where conversion failed
                text = _unquote(series.iloc[failed].fillna("").astype(str))
                is_missing = text.isin(self.schema.missing_values).to_numpy()
                missing[failed[is_missing]] = True
                values[failed] = self._to_float(text.mask(is_missing, "0"))
        bad = ~missing & ~np.isfinite(values)
        if bad.any():
            r = int(np.argmax(bad))
            cell = "" if pd.isna(series.iloc[r]) else str(series.iloc[r]).strip()
            raise FormatError(self.path, _describe_bad_cell(cell, self.schema), line=int(lines[r]), column=column)
        values[missing] = np.nan
        return values, missing

    def _to_float(self, cells: pd.Series) -> np.ndarray:
        """[n] float64 of number texts (NaN where a cell is not one), in the dialect's decimal
        separator: with a decimal comma a cell written with a point is not a number."""
        import pandas as pd

        if self.schema.decimal != ".":
            point = cells.str.contains(".", regex=False)
            cells = cells.str.replace(self.schema.decimal, ".", regex=False).mask(point, "")
        return pd.to_numeric(cells, errors="coerce").to_numpy(dtype=np.float64, copy=True)

    def numbers(
        self, column: str, rows: np.ndarray | None = None, *, release: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """([R] float64 values, [R] bool missing) of a loaded numeric column (or of ``rows``);
        ``release``: the table forgets the column (its last use), so its memory can go."""
        values, missing = self._numbers.pop(column) if release else self._numbers[column]
        return (values, missing) if rows is None else (values[rows], missing[rows])

    def text(self, column: str) -> np.ndarray:
        """[R] cells of a loaded text column, stripped."""
        return self._texts[column]


def _unquote(cells: pd.Series) -> pd.Series:
    """Cells without surrounding blanks and double quotes (as :func:`_split_fields` reads the header)."""
    return cells.str.strip().str.strip('"').str.strip()


def _describe_bad_cell(cell: str, schema: CsvSchema) -> str:
    low = cell.lower()
    if low in ("nan", "-nan", "+nan", "na", "n/a", "null", "none"):
        return (
            f"{cell!r} is not a number (NaN is not allowed here; a dialect that writes it for missing joints "
            "lists it in the schema's missing_values)"
        )
    if low.lstrip("+-") in ("inf", "infinity"):
        return f"infinite value {cell!r}"
    if cell == "":
        return "empty cell"
    shown = repr(_clip(cell))
    plain = cell if "." in cell else cell.replace(schema.decimal, ".")  # a number in Python's spelling
    if _is_number(plain) and math.isinf(float(plain)):
        return f"{shown} is beyond the range of 64-bit floating point"
    if schema.decimal != "." and _is_number(cell):
        return f"non-numeric value {shown} (the {schema.name} dialect's decimal separator is {schema.decimal!r})"
    return f"non-numeric value {shown}" + _decimal_comma_hint(cell, schema)


_DECIMAL_COMMA = re.compile(r'(?:^|[;\t"])\s*([+-]?\d+,\d+(?:[eE][+-]?\d+)?)\s*(?:$|[;\t"])')


def _decimal_comma_hint(text: str, schema: CsvSchema) -> str:
    """A hint to add to an error about ``text`` (a cell or a row) when it holds numbers written with
    a decimal comma (``0,123;1,456`` or ``"1,5"``) that the dialect does not expect, else ''."""
    m = _DECIMAL_COMMA.search(text) if schema.decimal == "." else None
    if m is None:
        return ""
    what = "it" if m.group(1) == text.strip().strip('"') else repr(_clip(m.group(1)))
    hint = f": {what} looks like a number with a decimal comma (a locale's number format); "
    if schema.delimiter == "," and '"' in text:  # "1,5","2,5": commas inside quotes between commas
        return hint + (
            "quoted decimal commas in a comma-separated file are not read: export it again with decimal points, "
            'or with \';\' between fields and read it with a dialect that has "delimiter": ";", "decimal": ","'
        )
    return hint + (
        'read the file with a dialect that has "decimal": "," and a delimiter other than "," '
        '(e.g. "delimiter": ";"; see docs/csv-schemas.md)'
    )


def _head_lines(path: Path, count: int) -> list[str]:
    """The first ``count`` lines of a text file, decoded as :func:`read_text` decodes (only they are
    read: a recording's CSV can be hundreds of megabytes)."""
    try:
        with open(path, "rb") as f:
            raw = b"".join(itertools.islice(f, count))
    except OSError as exc:
        raise FormatError(path, f"cannot read file: {exc.strerror or exc}") from exc
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("cp1252", errors="replace")
    return text.splitlines()


def _split_fields(line: str, delimiter: str) -> list[str]:
    return [c.strip().strip('"') for c in line.split(delimiter)]


def _strip_trailing(line: str, delimiter: str) -> str:
    stripped = line.rstrip()
    return stripped[: -len(delimiter)] if stripped.endswith(delimiter) else line


_PREAMBLE_PAIR = re.compile(r"^\s*([A-Za-z][\w .-]*?)\s*:\s*(.+?)\s*$")


def _preamble_pairs(line: str) -> dict[str, str]:
    """``key : value`` pairs of a comma-separated preamble line (the file's own metadata)."""
    pairs = [_PREAMBLE_PAIR.match(part) for part in line.split(",")]
    return {m.group(1): m.group(2) for m in pairs if m}


def _load_table(path: Path, schema: CsvSchema, joint_set: JointSet | None) -> _Table:
    """First pass: which lines are comments, header and data; every data row's field count."""
    try:
        return _scan(path, schema, joint_set, "utf-8-sig")
    except UnicodeDecodeError:
        return _scan(path, schema, joint_set, "cp1252")  # Windows tools; the numbers are ASCII either way


def _scan(path: Path, schema: CsvSchema, joint_set: JointSet | None, encoding: str) -> _Table:
    delim = schema.delimiter
    comment = schema.get("comment")
    trailing = schema.get("trailing_delimiter", False)
    first_data = schema.get("skip_lines", 0)
    meta: dict[str, str] = {}
    header: list[str] | None = None
    header_line = None
    names = None if schema.has_header or joint_set is None else schema.headerless_columns_of(joint_set)
    skipped: list[int] = []
    data = array("q")
    bad_row: tuple[int, int, str] | None = None
    try:
        # UTF-8 must decode (else the caller falls back to cp1252, which leaves 5 bytes undefined: replaced)
        f = open(path, encoding=encoding, errors="strict" if encoding.startswith("utf") else "replace", newline=None)
    except OSError as exc:
        raise FormatError(path, f"cannot read file: {exc.strerror or exc}") from exc
    with f:
        for i, line in enumerate(f):
            stripped = line.strip()
            if i < first_data or not stripped:
                if i < first_data:  # a recorder's preamble: "Software : LSL_Kinect,Stream nominal rate : 30,..."
                    meta.update(_preamble_pairs(stripped))
                skipped.append(i)
                continue
            if comment and stripped.startswith(comment):
                m = _META_LINE.match(stripped[len(comment) :])
                if m:
                    meta[m.group(1)] = m.group(2)
                skipped.append(i)
                continue
            row = _strip_trailing(line.rstrip("\r\n"), delim) if trailing else line.rstrip("\r\n")
            if schema.has_header and header is None:
                names = header = _split_fields(row, delim)
                header_line = i + 1
                _check_header_is_the_dialects(path, schema, joint_set, header, header_line, row)
                skipped.append(i)
                continue
            if names is None:
                raise FormatError(path, f"the {schema.name} schema has no header and no fixed joint set")
            if not data and header is None:
                _check_row_is_the_dialects(path, schema, names, row, i + 1)
            if bad_row is None and row.count(delim) + 1 != len(names):
                bad_row = (i + 1, row.count(delim) + 1, row[:200])  # reported after the header is checked
            data.append(i + 1)
    if schema.has_header and header is None:
        raise FormatError(path, f"empty file: no header line (the {schema.name} dialect has one)")
    if header is not None:
        dup = sorted({c for c in header if header.count(c) > 1})
        if dup:
            named = ", ".join(map(repr, dup[:5])) + (f" and {len(dup) - 5} more" if len(dup) > 5 else "")
            raise FormatError(path, f"the header repeats column(s) {named}", line=header_line)
    if not data:
        raise FormatError(path, "no data rows" + (f" after the header (line {header_line})" if header_line else ""))
    return _Table(
        path, schema, names, np.frombuffer(data, dtype=np.int64).copy(), skipped, encoding, header_line, meta, bad_row
    )


def _shown(names: list[str], first: int = 4, count: bool = True) -> str:
    """The first names quoted, and how many there are in all (``count``) when not all are shown."""
    more = "" if len(names) <= first else f" ... ({len(names)} in all)" if count else ", ..."
    return ", ".join(repr(_clip(n)) for n in names[:first]) + more


def _clip(text: str, at: int = 40) -> str:
    """``text``, cut to ``at`` characters with "..." when longer (a damaged line can be huge)."""
    return text if len(text) <= at else text[: at - 3] + "..."


def _check_header_is_the_dialects(
    path: Path, schema: CsvSchema, joint_set: JointSet | None, header: list[str], line: int, row: str
) -> None:
    """FormatError saying that the file is not in the dialect when its header names no joint column
    of it (a wrong ``--schema``), rather than a complaint about the columns it does have."""
    templates = schema.per_joint_columns() if schema.layout == "wide" else schema.document["position"]["columns"]
    if schema.layout == "wide":
        matches = [m for rx in map(_template_regex, templates) for c in header if (m := rx.match(c))]
        if any(not re.search(r"[,;\t]", m.group("joint")) for m in matches):  # not a whole row split wrongly
            return
    elif any(t in header for t in templates):
        return
    joint = None if joint_set is None else schema.file_joint_names(joint_set)[schema.joints_in_file(joint_set)[0]]
    expected = [schema.get(k, {}).get("column") for k in ("time", "body", "joint")]
    expected = [c for c in expected if c] + [t.replace(JOINT, joint) if joint else t for t in templates]
    raise FormatError(
        path,
        f"the file does not look like the {schema.name} dialect: its header names none of that dialect's joint "
        f"columns (it expects columns like {_shown(expected, 5, False)}; the header has {_shown(header)})"
        + _delimiter_hint(header, row, schema),
        line=line,
    )


def _check_row_is_the_dialects(path: Path, schema: CsvSchema, names: list[str], row: str, line: int) -> None:
    """FormatError saying that the file is not in the (headerless) dialect when its first data row
    has another field count or is mostly not numbers (a wrong ``--schema``)."""
    fields = _split_fields(row, schema.delimiter)
    if len(fields) == len(names) and _numeric_share(fields, schema) >= 0.5:
        return
    raise FormatError(
        path,
        f"the file does not look like the {schema.name} dialect: its rows hold {len(names)} fields "
        f"({_shown(names)}), but its first row holds {len(fields)} ({_shown(fields)})"
        + (_decimal_comma_hint(row, schema) or _delimiter_hint(fields, row, schema)),
        line=line,
    )


def _delimiter_hint(fields: list[str], row: str, schema: CsvSchema) -> str:
    """When a line split by the dialect's delimiter is one field holding another common delimiter: say so."""
    other = next((d for d in (";", "\t", ",") if d != schema.delimiter and d in row), None)
    if len(fields) != 1 or other is None:
        return ""
    return f"; its fields look separated by {other!r}, the dialect's by {schema.delimiter!r}"


# ---------------------------------------------------------------------------------------------
# Interpreting the table
# ---------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=4096)
def _template_regex(template: str) -> re.Pattern[str]:
    """The pattern of a column template (``{joint}_x``): the joint's name as the group ``joint``."""
    return re.compile("^" + re.escape(template).replace(re.escape(JOINT), "(?P<joint>.+)") + "$")


def _resolve_joint_set(schema: CsvSchema, table_names: list[str] | None, meta: dict[str, str], path: Path) -> JointSet:
    if "joint_set_document" in meta:  # a joint set kinectdata does not ship, carried whole by the file
        try:
            return joint_set_from_text(meta["joint_set_document"], path)
        except SchemaError as exc:
            raise FormatError(path, f"the '# joint_set_document' line: {exc.reason}") from None
    if "joint_set" in meta:
        # shipped names only (the writer writes no other): a file must not make the reader open other files
        name = meta["joint_set"]
        if name not in shipped_joint_sets():
            shown = name if len(name) <= 40 else name[:37] + "..."
            raise FormatError(
                path,
                f"the file's '# joint_set: {shown}' line names no known joint set "
                f"(shipped: {', '.join(shipped_joint_sets())})",
            )
        return load_joint_set(name)
    rx = _template_regex(schema.document["position"]["columns"][0])
    mapping = schema.joint_names_in_file
    found = [mapping.get(m.group("joint"), m.group("joint")) for c in table_names or [] if (m := rx.match(c))]
    if not found:
        raise FormatError(path, "the header names no joint columns")
    shipped = find_joint_set(found)
    dims = len(schema.document["position"]["columns"])
    return shipped if shipped is not None else JointSet.custom("custom", found, dimensions=dims)


def _check_header(table: _Table, joint_set: JointSet, present: list[int] | None) -> list[int]:
    """The joints a headered wide file holds: ``present`` (the schema's ``joints``) or else every
    joint with a column in the header, the others to be masked. FormatError for an unknown joint
    name, and for missing columns: a joint's columns must be all there or all absent."""
    schema, path = table.schema, table.path
    known = set(joint_set.names) | set(joint_set.aliases) | set(schema.joint_names_in_file)
    for tmpl in schema.per_joint_columns():
        rx = _template_regex(tmpl)
        for col in table.names:
            m = rx.match(col)
            if m and m.group("joint") not in known:
                raise FormatError(
                    path,
                    f"unknown joint name {m.group('joint')!r} in the header (joint set {joint_set.name}: "
                    f"{', '.join(joint_set.names)})",
                    line=table.header_line,
                    column=col,
                )
    fnames = schema.file_joint_names(joint_set)
    required = [t for t in schema.per_joint_columns() if t not in _optional_orientation_templates(schema, table)]
    columns = [[t.replace(JOINT, name) for t in required] for name in fnames]  # [J][required]
    if present is None:
        present = [j for j in range(len(joint_set)) if any(map(table.has, columns[j]))]
        if not present:
            raise FormatError(
                path,
                f"the header names no joint of {joint_set.name} as the {schema.name} dialect spells it "
                f"(expected columns like {_shown(columns[0])})",
                line=table.header_line,
            )
    missing = [c for j in present for c in columns[j] if not table.has(c)]
    for key in ("time", "body"):
        col = schema.get(key, {}).get("column")
        if col is not None and not table.has(col):
            missing.insert(0, col)
    if missing:
        shown = ", ".join(missing[:6]) + (f" and {len(missing) - 6} more" if len(missing) > 6 else "")
        partial = next((j for j in present if 0 < sum(map(table.has, columns[j])) < len(required)), None)
        why = (
            ""
            if partial is None
            else f" (joint {joint_set.names[partial]!r} has {_shown([c for c in columns[partial] if table.has(c)])} "
            "but not all its columns: a joint's columns must be all present or all absent)"
        )
        raise FormatError(path, f"missing column(s) {shown}{why}", line=table.header_line)
    return present


def _optional_orientation_templates(schema: CsvSchema, table: _Table) -> list[str]:
    """Orientation templates to ignore: optional ones whose columns the file does not have."""
    o = schema.get("orientation")
    if not o or o.get("required", True):
        return []
    if any(_template_regex(o["columns"][0]).match(c) for c in table.names):
        return []
    return list(o["columns"])


def _select_body(table: _Table, body: str | None, frame_key: np.ndarray) -> tuple[np.ndarray | None, dict]:
    """Rows of the chosen body, and metadata about the bodies present."""
    col = table.schema.get("body", {}).get("column")
    if col is None:
        if body is not None:
            raise FormatError(
                table.path, f"--body {body} given, but the {table.schema.name} dialect has no body column"
            )
        return None, {}
    ids = table.text(col)
    pairs = dict.fromkeys(zip(frame_key.tolist(), ids.tolist()))  # one entry per (frame, body)
    frames = count_bodies(b for _, b in pairs)
    body = choose_body(table.path, frames, body, n_frames=len(np.unique(frame_key)), column=col)
    return np.flatnonzero(ids == body), {"body": body, "bodies": frames}


def _tracking_confidence(table: _Table, column: str, rows: np.ndarray | None) -> np.ndarray:
    spec = table.schema.document["tracking"]
    if spec.get("scale") == "confidence":
        conf, missing = table.numbers(column, rows)
        bad = ~missing & ((conf < 0) | (conf > 1))
        if bad.any():
            r = int(np.argmax(bad))
            lines = table.lines if rows is None else table.lines[rows]
            raise FormatError(table.path, f"confidence {conf[r]} outside 0..1", line=int(lines[r]), column=column)
        return np.where(missing, 0.0, conf)
    mapping = spec["values"]
    lines = table.lines if rows is None else table.lines[rows]
    if _numeric_states(spec):
        values, missing = table.numbers(column, rows)
        conf, known = np.zeros(values.shape), missing.copy()  # a missing state: not tracked
        for key, value in mapping.items():
            hit = values == float(key)
            conf[hit], known = value, known | hit
        if not known.all():
            r = int(np.argmax(~known))
            allowed = ", ".join(repr(k) for k in mapping)
            raise FormatError(
                table.path,
                f"unknown tracking state '{values[r]:g}' (expected one of {allowed})",
                line=int(lines[r]),
                column=column,
            )
        return conf
    cells = table.text(column) if rows is None else table.text(column)[rows]
    numeric_keys = {}
    for k, v in mapping.items():
        try:
            numeric_keys[float(k)] = v
        except ValueError:
            pass
    lookup = {k.lower(): v for k, v in mapping.items()}
    uniq, inverse = np.unique(cells, return_inverse=True)
    conf_of = np.empty(len(uniq))
    for i, cell in enumerate(uniq):
        if cell.lower() in lookup:
            conf_of[i] = lookup[cell.lower()]
            continue
        try:
            conf_of[i] = numeric_keys[float(cell)]
        except (ValueError, KeyError):
            r = int(np.argmax(inverse == i))
            allowed = ", ".join(repr(k) for k in mapping)
            raise FormatError(
                table.path,
                f"unknown tracking state {cell!r} (expected one of {allowed})",
                line=int(lines[r]),
                column=column,
            ) from None
    return conf_of[inverse]


def _check_times(path: Path, t: np.ndarray, lines: np.ndarray, unit: str) -> None:
    dt = np.diff(t)
    bad = dt <= 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        if dt[i - 1] == 0:
            raise FormatError(
                path, f"duplicated timestamp {t[i]:g} {unit} (also on line {lines[i - 1]})", line=int(lines[i])
            )
        raise FormatError(
            path,
            f"time goes backwards: {t[i]:g} {unit} after {t[i - 1]:g} {unit} on line {lines[i - 1]}",
            line=int(lines[i]),
        )


def _frame_times(table: _Table, rows: np.ndarray | None, n_rows: int) -> tuple[np.ndarray, float, str]:
    """Raw time values per row, seconds per unit, unit name."""
    spec = table.schema.document["time"]
    if "column" in spec:
        t, _ = table.numbers(spec["column"], rows)
        return t, table.schema.time_scale(), spec["unit"]
    return np.arange(n_rows, dtype=np.float64), 1.0 / spec["fps"], "frames"


def _load_columns(table: _Table, joint_names: list[str]) -> None:
    """Load what the reader uses: time, body, joint, and the per-joint columns of ``joint_names``
    (file spellings; long layout: the plain columns). Body ids, joint names and word-valued
    tracking states are text; the rest numbers."""
    doc = table.schema.document
    numeric, text = set(), set()
    for key in ("time",):
        if "column" in doc.get(key, {}):
            numeric.add(doc[key]["column"])
    if "body" in doc:
        text.add(doc["body"]["column"])
    if table.schema.layout == "long":
        (text if doc["joint"]["values"] == "name" else numeric).add(doc["joint"]["column"])
    templates = list(doc["position"]["columns"])
    if "orientation" in doc and not _optional_orientation_templates(table.schema, table):
        templates += doc["orientation"]["columns"]
    tracking = doc.get("tracking")
    for tmpl in templates + ([tracking["column"]] if tracking else []):
        cols = [tmpl.replace(JOINT, j) for j in joint_names] if table.schema.layout == "wide" else [tmpl]
        words = tracking is not None and tmpl == tracking["column"] and not _numeric_states(tracking)
        (text if words else numeric).update(cols)
    table.load(numeric, text)


def _numeric_states(tracking: dict) -> bool:
    """Tracking written as numbers (a confidence, or states whose names are all numbers)."""
    if tracking.get("scale") == "confidence":
        return True
    try:
        [float(k) for k in tracking["values"]]
    except ValueError:
        return False
    return True


def _read_wide(table: _Table, joint_set: JointSet, body: str | None) -> tuple:
    schema = table.schema
    declared = "joints" in schema.document or not schema.has_header
    present = schema.joints_in_file(joint_set) if declared else None  # joints: checked in joint_set_of
    if schema.has_header:
        present = _check_header(table, joint_set, present)
    fnames = schema.file_joint_names(joint_set)
    _load_columns(table, [fnames[j] for j in present])
    key = np.arange(len(table.lines))
    rows, body_meta = _select_body(table, body, key)
    lines = table.lines if rows is None else table.lines[rows]
    n = len(lines)
    t_raw, scale, unit = _frame_times(table, rows, n)
    _check_times(table.path, t_raw, lines, unit)
    fnames = schema.file_joint_names(joint_set)
    J, D = len(joint_set), joint_set.dimensions
    pos = np.full((n, J, D), np.nan)
    missing = np.ones((n, J), bool)
    conf = np.zeros((n, J))
    o = schema.get("orientation")
    with_q = o is not None and not _optional_orientation_templates(schema, table)
    quats = np.full((n, J, 4), np.nan) if with_q else None
    for j in present:
        missing[:, j] = False
        for d, tmpl in enumerate(schema.document["position"]["columns"]):
            pos[:, j, d], m = table.numbers(tmpl.replace(JOINT, fnames[j]), rows, release=True)
            missing[:, j] |= m
        if "tracking" in schema.document:
            conf[:, j] = _tracking_confidence(
                table, schema.document["tracking"]["column"].replace(JOINT, fnames[j]), rows
            )
        else:
            conf[:, j] = 1.0
        if with_q:
            for c, tmpl in enumerate(o["columns"]):
                quats[:, j, c], _ = table.numbers(tmpl.replace(JOINT, fnames[j]), rows, release=True)
    return t_raw, scale, lines, pos, missing, conf, quats, body_meta


def _read_long(table: _Table, joint_set: JointSet, body: str | None) -> tuple:
    schema = table.schema
    spec = schema.document["time"]
    if "column" not in spec:
        raise FormatError(table.path, "a long-layout dialect needs a time column to group rows into frames")
    _load_columns(table, [])
    t_all, _ = table.numbers(spec["column"])
    rows, body_meta = _select_body(table, body, t_all)
    lines = table.lines if rows is None else table.lines[rows]
    t_rows = t_all if rows is None else t_all[rows]
    jspec = schema.document["joint"]
    joint_idx = _joint_indices(table, jspec, joint_set, rows, lines)
    dt = np.diff(t_rows)
    if (dt < 0).any():
        i = int(np.argmax(dt < 0)) + 1
        raise FormatError(
            table.path,
            f"time goes backwards: {t_rows[i]:g} {spec['unit']} after {t_rows[i - 1]:g} "
            f"{spec['unit']} on line {lines[i - 1]}",
            line=int(lines[i]),
        )
    frame_id = np.concatenate([[0], np.cumsum(dt > 0)])
    n, J, D = int(frame_id[-1]) + 1, len(joint_set), joint_set.dimensions
    cell = frame_id * J + joint_idx
    order = np.argsort(cell, kind="stable")
    dup = np.flatnonzero(np.diff(cell[order]) == 0)
    if dup.size:
        a, b = sorted((order[dup[0]], order[dup[0] + 1]))
        raise FormatError(
            table.path,
            f"joint {joint_set.names[joint_idx[b]]!r} appears twice at time {t_rows[b]:g} "
            f"{spec['unit']} (also on line {lines[a]}): a duplicated timestamp or repeated rows",
            line=int(lines[b]),
        )
    pos = np.full((n, J, D), np.nan)
    missing = np.ones((n, J), bool)
    missing[frame_id, joint_idx] = False
    for d, col in enumerate(schema.document["position"]["columns"]):
        v, m = table.numbers(col, rows)
        pos[frame_id, joint_idx, d] = v
        missing[frame_id[m], joint_idx[m]] = True
    conf = np.zeros((n, J))
    if "tracking" in schema.document:
        conf[frame_id, joint_idx] = _tracking_confidence(table, schema.document["tracking"]["column"], rows)
    else:
        conf[frame_id, joint_idx] = 1.0
    quats = None
    if "orientation" in schema.document:
        quats = np.full((n, J, 4), np.nan)
        for c, col in enumerate(schema.document["orientation"]["columns"]):
            quats[frame_id, joint_idx, c], _ = table.numbers(col, rows)
    first_row = np.concatenate([[0], np.flatnonzero(dt > 0) + 1])
    line_of = np.repeat(lines[first_row][:, None], J, axis=1)  # [T, J]: the row of each joint value
    line_of[frame_id, joint_idx] = lines
    return t_rows[first_row], schema.time_scale(), line_of, pos, missing, conf, quats, body_meta


def _joint_indices(table: _Table, jspec: dict, joint_set: JointSet, rows, lines) -> np.ndarray:
    col = jspec["column"]
    if jspec["values"] == "index":
        v, _ = table.numbers(col, rows)
        bad = (v != np.round(v)) | (v < 0) | (v >= len(joint_set))
        if bad.any():
            r = int(np.argmax(bad))
            raise FormatError(
                table.path,
                f"joint index {v[r]:g} is not a joint of {joint_set.name} (0..{len(joint_set) - 1})",
                line=int(lines[r]),
                column=col,
            )
        return v.astype(np.int64)
    names = table.text(col) if rows is None else table.text(col)[rows]
    mapping = table.schema.joint_names_in_file
    uniq, inverse = np.unique(names, return_inverse=True)
    idx = np.empty(len(uniq), np.int64)
    for i, name in enumerate(uniq):
        try:
            idx[i] = joint_set.index(mapping.get(name, name))
        except KeyError:
            r = int(np.argmax(inverse == i))
            raise FormatError(
                table.path,
                f"unknown joint name {name!r} (joint set {joint_set.name}: {', '.join(joint_set.names)})",
                line=int(lines[r]),
                column=col,
            ) from None
    return idx[inverse]


def _build_motion(path: Path, schema: CsvSchema, joint_set: JointSet, parts: tuple, meta: dict) -> Motion:
    t_raw, scale, lines, pos, missing, conf, quats, body_meta = parts
    if schema.zero_is_untracked:  # NiTE / OpenNI loggers write a lost joint as (0, 0, 0)
        missing |= (pos == 0).all(axis=-1)
    pos *= schema.position_scale()
    position_mask = ~missing & (conf > 0)
    orientations = orientation_mask = None
    if quats is not None:
        order = schema.document["orientation"]["order"]
        q_missing = ~np.isfinite(quats).all(axis=-1)
        gated = schema.document["orientation"].get("gated_by_tracking", True)
        with np.errstate(over="ignore"):  # the norm of huge values overflows to inf: not a unit quaternion
            # in place: quats is this reader's own array, and a copy of it is [T, J, 4] float64 more at the peak
            unit, present, bad = split_missing_and_normalise(reorder(np.nan_to_num(quats, copy=False), order))
        bad &= ~q_missing & joint_set.orientation_mask[None, :]
        if gated:
            bad &= position_mask  # junk written for untracked joints is expected, and masked
        if bad.any():
            f, j = np.argwhere(bad)[0]
            column = schema.document["orientation"]["columns"][0]
            if schema.layout == "wide":
                column = column.replace(JOINT, schema.file_joint_names(joint_set)[j])
            raise FormatError(
                path,
                f"orientation of joint {joint_set.names[j]!r} is not a unit quaternion "
                f"(norm {math.hypot(*quats[f, j]):.3f}; is the quaternion order {order} right?)",
                line=int(lines[f] if lines.ndim == 1 else lines[f, j]),
                column=column,
            )
        orientations = unit
        orientation_mask = present & ~q_missing & (position_mask if gated else True)
    up, handedness = schema.document.get("up", "y"), schema.document.get("handedness", "right")
    if (up, handedness) != ("y", "right"):  # a dialect of another program's axes (Xsens: z up)
        shown = None if orientations is None else np.where(orientation_mask[..., None], orientations, np.nan)
        pos, shown = to_kinectdata_axes(pos, shown, up=up, handedness=handedness)
        if shown is not None:
            orientations = np.nan_to_num(shown)
    metadata = {
        "format": "csv",
        "schema": schema.name,
        "schema_path": schema.path,
        "time_origin": {"value": float(t_raw[0]), "unit": schema.document["time"].get("unit", "frame")},
        **body_meta,
        **({"file_metadata": meta} if meta else {}),
    }
    if "fps" in schema.document["time"]:
        metadata["nominal_fps"] = schema.document["time"]["fps"]
    times = (t_raw - t_raw[0]) * scale
    bad_time = first_bad_time(times)
    if bad_time is not None:
        unit = schema.document["time"].get("unit", "frame")
        raise FormatError(
            path,
            f"time {t_raw[bad_time]:g} {unit}, counted from the first frame's {t_raw[0]:g} {unit}, overflows or "
            "does not come after the frame before in 64-bit floating point (is the first time damaged?)",
            line=int(lines[bad_time] if lines.ndim == 1 else lines[bad_time].min()),
            column=schema.document["time"].get("column"),
        )
    # NaN where masked, written here into this reader's own arrays, so that Motion need not copy them
    pos[~position_mask] = np.nan
    if orientations is not None:
        orientation_mask &= joint_set.orientation_mask[None, :]
        orientations[~orientation_mask] = np.nan
    return Motion(
        times=times,
        positions=pos,
        joint_set=joint_set,
        position_mask=position_mask,
        confidence=np.where(position_mask, conf, 0.0),
        orientations=orientations,
        orientation_mask=orientation_mask,
        metadata=metadata,
    )


# ---------------------------------------------------------------------------------------------
# Dialect detection
# ---------------------------------------------------------------------------------------------
def _schema_matches(schema: CsvSchema, lines: list[str]) -> bool:
    if not lines:
        return False
    sig = schema.signature
    if sig is not None:
        return bool(sig.search(lines[0]))
    delim, comment = schema.delimiter, schema.get("comment")
    body = [
        ln
        for ln in lines[schema.get("skip_lines", 0) :]
        if ln.strip() and not (comment and ln.strip().startswith(comment))
    ]
    if not body:
        return False
    first = _strip_trailing(body[0], delim) if schema.get("trailing_delimiter") else body[0]
    fields = _split_fields(first, delim)
    if schema.has_header:
        time_col = schema.get("time", {}).get("column")
        if time_col is not None and time_col not in fields:
            return False
        rx = _template_regex(schema.document["position"]["columns"][0]) if schema.layout == "wide" else None
        return any(rx.match(f) for f in fields) if rx else schema.document["position"]["columns"][0] in fields
    if schema.joint_set == "auto":
        return False
    names = schema.headerless_columns_of(joint_set_of(schema))
    if len(fields) != len(names):
        return False
    # mostly numbers: a corrupt cell should be reported by the reader, not mistaken for a dialect
    return _numeric_share(fields, schema) >= 0.9


def _numeric_share(fields: list[str], schema: CsvSchema) -> float:
    """The share of ``fields`` that are numbers in the dialect's decimal separator (0 for none)."""
    return sum(_is_number(f.replace(schema.decimal, ".")) for f in fields) / max(len(fields), 1)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def detect_csv_schema(path: str | Path) -> CsvSchema:
    """The shipped CSV schema that recognises a file; FormatError if none or several do."""
    path = Path(path)
    head = _head_lines(path, _DETECT_LINES)
    if not any(ln.strip() for ln in head):
        raise FormatError(path, "empty file")
    matches = [s for s in (load_csv_schema(n) for n in shipped_csv_schemas()) if _schema_matches(s, head)]
    if len(matches) == 1:
        return matches[0]
    if not matches:
        raise FormatError(
            path,
            "no shipped CSV dialect recognises this file (shipped: "
            f"{', '.join(shipped_csv_schemas())}); describe it in a schema file and pass --schema FILE "
            "(see docs/csv-schemas.md)",
            line=1,
        )
    raise FormatError(path, f"several CSV dialects fit this file ({', '.join(s.name for s in matches)}); pass --schema")


def _sniff(path: Path, head: bytes) -> bool:
    try:
        lines = head.decode("utf-8-sig", errors="replace").splitlines()[:_DETECT_LINES]
        return any(_schema_matches(load_csv_schema(n), lines) for n in shipped_csv_schemas())
    except KinectDataError:
        return False


@register_reader(
    "csv",
    extensions=(".csv",),
    sniff=_sniff,
    description="Skeleton CSV in a dialect described by a CSV schema (--schema NAME or FILE)",
)
def read_csv_motion(
    path: str | Path, *, schema: str | Path | CsvSchema | None = None, body: str | None = None
) -> Motion:
    """Read a skeleton CSV file.

    Args:
        path: the CSV file.
        schema: a shipped dialect name (``kinectreader``, ``lsl_kinect``, ``dumpkinectskeleton``,
            ``canonical``), a schema file path, or None to detect the dialect.
        body: body id (as written in the body column) for dialects that interleave bodies; by
            default the body present in the most frames.

    Returns:
        A :class:`~kinectdata.core.motion.Motion` with times in seconds from the first frame.
    """
    path = Path(path)
    sch = load_csv_schema(schema) if schema is not None else detect_csv_schema(path)
    fixed = None if sch.joint_set == "auto" else joint_set_of(sch)
    table = _load_table(path, sch, fixed)
    joint_set = fixed or _resolve_joint_set(sch, table.names, table.meta, path)
    if len(sch.document["position"]["columns"]) != joint_set.dimensions:
        raise FormatError(
            path,
            f"the {sch.name} schema gives {len(sch.document['position']['columns'])} position "
            f"columns but joint set {joint_set.name} is {joint_set.dimensions}-D",
        )
    parts = (_read_wide if sch.layout == "wide" else _read_long)(table, joint_set, body)
    meta = table.meta
    del table  # its parsed columns are no longer needed: free them before the arrays are assembled
    return _build_motion(path, sch, joint_set, parts, meta)
