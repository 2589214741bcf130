"""Writing a Motion as CSV in any dialect a CSV schema describes (the reader: :mod:`.csv`).

``canonical`` is kinectdata's own lossless CSV; the Kinect dialects are written as their
programs write them (invalid positions as zeros with a not-tracked state, missing orientations
as ``0 0 0 0``), so that files made here exercise the same reading code as real ones.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.core.jointsets import is_shipped, joint_set_text
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import xyzw_to_wxyz
from kinectdata.formats.csv_schema import JOINT, CsvSchema, joint_set_of, load_csv_schema
from kinectdata.formats.writers import register_writer


def _state_column(motion: Motion, spec: dict, states: np.ndarray | None) -> np.ndarray:
    """[T, J] cells of the tracking column."""
    if spec.get("scale") == "confidence":
        return np.char.mod("%g", np.round(motion.confidence.astype(np.float64), 6)).astype(object)
    keys = list(spec["values"])
    if states is not None:
        allowed = {str(k) for k in keys}
        cells = np.asarray(states).astype(str).astype(object)
        bad = sorted(set(np.unique(cells)) - allowed)
        if bad:
            raise ConfigError(f"states {bad} are not among the dialect's tracking values {keys}")
        return cells
    values = np.array([spec["values"][k] for k in keys])
    nearest = np.argmin(np.abs(motion.confidence[..., None] - values), axis=-1)
    return np.array(keys, dtype=object)[nearest]


def write_csv(
    motion: Motion,
    path: str | Path,
    schema: str | Path | CsvSchema = "canonical",
    *,
    states: np.ndarray | None = None,
    time_origin: float = 0.0,
    comments: dict[str, str] | None = None,
    decimals: int = 6,
) -> None:
    """Write a Motion as a CSV file in a schema's dialect (atomically).

    Args:
        motion: the recording. Its joint set must be the schema's (any, for ``auto`` schemas).
        path: output file.
        schema: dialect name or schema file; ``canonical`` keeps everything kinectdata reads.
        states: optional [T, J] tracking states to write verbatim (e.g. Kinect 0/1/2); by
            default they come from ``motion.confidence`` (nearest state value).
        time_origin: value of the first timestamp, in the schema's time unit.
        comments: ``# key: value`` lines to write first, for dialects with a comment prefix
            (the reader keeps them as the file's metadata).
        decimals: digits after the point of positions and orientations (6: micrometres), and of times in
            seconds when more than 6 (a motion scored again from the file needs its times as exact as
            its positions: a jerk is a third difference).

    Invalid positions are written as the dialect's missing-value text when it has one, else as
    zeros (with a not-tracked state, as the Kinect SDK does); missing orientations likewise, or
    as ``0 0 0 0``.
    """
    sch = load_csv_schema(schema)
    js = motion.joint_set
    if sch.joint_set != "auto" and joint_set_of(sch).names != js.names:
        raise KinectDataError(f"the {sch.name} dialect is for joint set {sch.joint_set}, the motion has {js.name}")
    doc = sch.document
    T, J = motion.n_frames, len(js)
    fnames = sch.file_joint_names(js)
    missing_text = sorted(sch.missing_values)[0] if sch.missing_values else None

    written = sch.joints_in_file(js)  # the joints the dialect holds (all of the set unless it lists some)

    def fmt(a: np.ndarray, spec: str) -> np.ndarray:
        text = np.char.mod(spec, np.nan_to_num(a))
        if sch.decimal != ".":
            text = np.char.replace(text, ".", sch.decimal)
        cells = text.astype(object)
        if missing_text is not None:
            cells[~np.isfinite(a)] = missing_text
        return cells

    cols: dict[str, np.ndarray] = {}  # template -> [T] or [T, J] cells
    tspec = doc["time"]
    if "column" in tspec:
        t = motion.times / sch.time_scale() + time_origin
        cols[tspec["column"]] = (
            np.char.mod("%d", np.round(t)).astype(object)
            if tspec["unit"] in ("ticks", "ns")
            else fmt(t, f"%.{max(6, decimals)}f")
        )
    if "body" in doc:
        cols[doc["body"]["column"]] = np.full(T, str(motion.metadata.get("body", 0)), dtype=object)
    pos = motion.positions / sch.position_scale()
    for d, tmpl in enumerate(doc["position"]["columns"]):
        cols[tmpl] = fmt(pos[..., d], f"%.{decimals}f")
    o = doc.get("orientation")
    if o is not None and (motion.has_orientations or o.get("required", True)):
        q = motion.orientations if motion.has_orientations else np.zeros((T, J, 4))
        q = np.where(np.isfinite(q), q, np.nan if missing_text is not None else 0.0)
        if o["order"] == "wxyz":
            q = xyzw_to_wxyz(q)
        for c, tmpl in enumerate(o["columns"]):
            cols[tmpl] = fmt(q[..., c], f"%.{decimals}f")
    if "tracking" in doc:
        cols[doc["tracking"]["column"]] = _state_column(motion, doc["tracking"], states)

    per_joint = set(sch.per_joint_columns())
    if sch.layout == "wide":
        names = (
            sch.headerless_columns_of(js)
            if not sch.has_header
            else (
                [c for c in cols if c not in per_joint]
                + [t.replace(JOINT, fnames[j]) for j in written for t in cols if t in per_joint]
            )
        )
        table = {}
        for j in written:
            for t in per_joint & cols.keys():
                table[t.replace(JOINT, fnames[j])] = cols[t][:, j]
        for c in cols:
            if c not in per_joint:
                table[c] = cols[c]
        data = pd.DataFrame({n: table[n] for n in names})
    else:
        jcol = doc["joint"]["column"]
        cols[jcol] = np.tile(
            np.arange(J).astype(str) if doc["joint"]["values"] == "index" else np.array(fnames), (T, 1)
        ).astype(object)
        names = sch.headerless_columns(fnames) if not sch.has_header else list(cols)
        n = len(written)
        data = pd.DataFrame(
            {c: (cols[c][:, written].reshape(-1) if cols[c].ndim == 2 else np.repeat(cols[c], n)) for c in names}
        )
    preamble = list(doc.get("preamble", []))
    if sch.joint_set == "auto" and is_shipped(js):
        preamble.append(f"# joint_set: {js.name}")
    elif sch.joint_set == "auto":  # a user's joint set travels with the file: bones, roles, SMPL-24 mapping
        preamble.append(f"# joint_set_document: {joint_set_text(js)}")
    if comments:
        prefix = sch.get("comment")
        if prefix is None:
            raise KinectDataError(f"the {sch.name} dialect has no comment lines to hold {sorted(comments)}")
        preamble += [f"{prefix} {key}: {value}" for key, value in comments.items()]
    with atomic_output(path) as tmp:
        with open(tmp, "w", newline="\n", encoding="utf-8") as f:
            for line in preamble:
                f.write(line + "\n")
            data.to_csv(
                f,
                sep=sch.delimiter,
                header=sch.has_header,
                index=False,
                lineterminator=",\n" if doc.get("trailing_delimiter") else "\n",
            )


@register_writer("csv", extensions=(".csv",), description="kinectdata's canonical CSV (lossless)")
def write_canonical_csv(motion: Motion, path: str | Path, *, decimals: int = 6) -> Path:
    """Write ``motion`` as kinectdata's canonical CSV (:func:`write_csv` with ``canonical``): every
    joint, confidence and orientation, the frame times, a joint set kinectdata does not ship, and
    the recording's source and placement as comment lines. Returns the path."""
    kept = {key: str(motion.metadata[key]) for key in ("source", "placement") if motion.metadata.get(key)}
    write_csv(motion, path, "canonical", comments={k: v.replace("\n", " ") for k, v in kept.items()}, decimals=decimals)
    return Path(path)
