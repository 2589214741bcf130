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
import re
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataError, SchemaError
from kinectdata.core.resources import validate
from kinectdata.dataset.collection import find_sessions

MUSIC_FACTS = ("style", "beats_per_bar")
"""Entry fields that describe the music: no reading option (:meth:`RecordingEntry.options`), but the
features that hear a style or count bars are built from them, and evaluate reads them from the
dataset's manifest, so the build key counts them."""


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
    person: str | None = None
    video_fps: float | None = None
    fps: float | None = None
    unit: str | None = None
    rest_joints: str | None = None
    style: str | None = None
    beats_per_bar: int | None = None
    clean: bool | dict[str, Any] | None = None

    @property
    def aligned(self) -> bool:
        return self.audio is None

    def read_motion(self):
        """The skeleton recording, read with this entry's reading options (not for aligned files)."""
        from kinectdata.formats import read_motion

        return read_motion(
            self.recording,
            format=self.format,
            schema=self.schema,
            body=self.body,
            person=self.person,
            video_fps=self.video_fps,
            array_fps=self.fps,
            unit=self.unit,
            rest_joints=self.rest_joints,
        )

    def to_dict(self) -> dict[str, Any]:
        return {k: v for k, v in asdict(self).items() if v is not None}

    def options(self) -> dict[str, Any]:
        """What identifies the recording besides its files' contents: name and reading options
        (a schema file by its name; its contents are hashed with the sources). What is said about
        the music (style, metre) is no reading option and is left out: the keys that depend on it add
        it (:data:`MUSIC_FACTS`)."""
        opts = {k: v for k, v in self.to_dict().items() if k not in ("recording", "audio", "split", *MUSIC_FACTS)}
        for key in ("schema", "rest_joints"):
            if opts.get(key) is not None and Path(opts[key]).is_file():
                opts[key] = Path(opts[key]).name
        return opts


def _is_aligned_file(path: Path) -> bool:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == "kinectdata.aligned"
    except OSError:
        return False


CSV_NUMBERS = (
    ("video_fps", float, "not a number"),
    ("fps", float, "not a number"),
    ("beats_per_bar", int, "not a whole number"),
    ("offset", float, "neither a number nor auto"),
)
"""The CSV manifest columns read as numbers: (column, conversion, what a value that fails is not)."""
CSV_BOOLEANS = {"true": True, "yes": True, "1": True, "false": False, "no": False, "0": False}
"""The values a CSV manifest's ``clean`` column may take."""
MANIFEST_KEYS = ("recordings", "root", "corpus", "description", "songs")
"""What a JSON or YAML manifest written as an object may hold (its recordings under ``recordings``,
its labelled songs without a recording under ``songs``)."""


@dataclass(frozen=True)
class LabelledSong:
    """A song whose dance style is known but that has no recording (its dance was never captured,
    or its motion file is lost): its music teaches the build's music style classifier
    (:mod:`kinectdata.dataset.song_styles`) and nothing else. ``audio``: the song's file."""

    name: str
    audio: str
    style: str

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _read_manifest(path: Path) -> tuple[list[dict[str, Any]], list[int] | None, str | None, list | None]:
    """The entries of a manifest file, for CSV the line of each (None for JSON and YAML), the
    folder its paths are relative to (``root``, itself relative to the manifest's folder) if it names
    one, and its ``songs`` (None when it lists none)."""
    suffix = path.suffix.lower()
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise SchemaError(path, f"cannot read file: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise SchemaError(
            path, f"not a recordings manifest: byte {exc.start} is not UTF-8 text (a manifest is CSV, JSON or YAML)"
        ) from None
    if suffix == ".csv":
        reader = csv.DictReader(text.splitlines())
        docs, lines = [], []
        for row in reader:
            line = reader.line_num
            if None in row:
                raise SchemaError(path, f"more fields than the header's {len(reader.fieldnames)}", line=line)
            doc = {k.strip(): v.strip() for k, v in row.items() if k and v is not None and v.strip()}
            for key, convert, what in CSV_NUMBERS:
                if key in doc and not (key == "offset" and doc[key] == "auto"):
                    try:
                        doc[key] = convert(doc[key])
                    except ValueError:
                        raise SchemaError(path, f"{key} {doc[key]!r} is {what}", line=line) from None
            if "clean" in doc:
                if doc["clean"].lower() not in CSV_BOOLEANS:
                    raise SchemaError(path, f"clean {doc['clean']!r} is neither true nor false", line=line)
                doc["clean"] = CSV_BOOLEANS[doc["clean"].lower()]
            docs.append(doc)
            lines.append(line)
        return docs, lines, None, None
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
    root, songs = None, None
    if isinstance(doc, dict) and "recordings" in doc:
        unknown = sorted(set(map(str, doc)) - set(MANIFEST_KEYS))
        if unknown:
            keys = ", ".join(MANIFEST_KEYS)
            raise SchemaError(path, f"unknown key(s) {', '.join(unknown)} (a manifest holds {keys})")
        root = doc.get("root")
        if root is not None and not (isinstance(root, str) and root):
            raise SchemaError(path, f"root: {root!r} is not a folder path")
        songs = doc.get("songs")
        doc = doc["recordings"]
    return doc, None, root, songs


_NAME = re.compile(r"[A-Za-z0-9_.+-]+")


def _given_name(doc: dict[str, Any], file_key: str) -> str:
    """An entry's ``name``, else the stem of the file it names under ``file_key``."""
    return str(doc.get("name", Path(str(doc.get(file_key, ""))).stem))


def _checked_name(name: str, where: str, source: Path) -> str:
    if not _NAME.fullmatch(name):
        raise SchemaError(
            source, f"{where}: name {name!r} may hold only letters, digits and _ . + - (give a 'name' for it)"
        )
    return name


def _existing(source: Path, base: Path, doc: dict, key: str, where: str, line: int | None, allow_outside: bool) -> Path:
    """The resolved path of a manifest field naming a file (or, for a recording, an OpenPose
    folder), which must exist and, unless ``allow_outside``, be relative and stay inside ``base``
    (the manifest's folder, or the ``root`` it names) once ``..`` and symbolic links are resolved."""
    path = (base / doc[key]).resolve()
    if not allow_outside:
        why = None
        if Path(doc[key]).is_absolute():
            why = "is an absolute path"
        elif not path.is_relative_to(base.resolve()):
            why = f"leads outside the manifest's folder or root {base} (to {path})"
        if why is not None:
            raise SchemaError(
                source,
                f"{where}: {key} {doc[key]} {why}: paths in a manifest are relative to its folder (or its root) "
                "and stay inside it (--allow-outside-paths, or allow_outside_paths=True, allows others)",
                line=line,
            )
    if not (path.is_file() or (key == "recording" and path.is_dir())):
        raise SchemaError(source, f"{where}: {key} {doc[key]} does not exist (looked for {path})", line=line)
    return path


def _manifest_root(source: Path, root: str, allow_outside: bool) -> Path:
    """The folder a manifest's ``root`` names, which must exist and, unless ``allow_outside``, lie
    inside the manifest's folder: a root elsewhere reads files from there, as an outside path would."""
    base = (source.parent / Path(root).expanduser()).resolve()
    if not allow_outside and not base.is_relative_to(source.parent.resolve()):
        raise SchemaError(
            source,
            f"root {root} leads outside the manifest's folder (to {base}): build with --allow-outside-paths "
            "(allow_outside_paths=True) if you trust this manifest",
        )
    if not base.is_dir():
        raise SchemaError(source, f"root: {root} is not a folder (looked for {base})")
    return base


def read_recordings(
    source: str | Path, *, video_fps: float | None = None, allow_outside_paths: bool = False
) -> list[RecordingEntry]:
    """The recordings listed by a manifest file, or found in a folder, with resolved paths.

    Every listed file must exist and, unless ``allow_outside_paths``, be given relative to the
    manifest's folder and lie inside it (no absolute paths, no ``..`` or symbolic link leading out);
    errors name the manifest, the record (its line in CSV) and the path. ``video_fps`` is given to
    the OpenPose recordings (folders) that do not state their own.
    """
    entries = _read_recordings(Path(source), allow_outside_paths)
    if video_fps is None:
        return entries
    return [replace(e, video_fps=video_fps) if e.video_fps is None and _is_openpose(e) else e for e in entries]


def _is_openpose(entry: RecordingEntry) -> bool:
    if entry.aligned:
        return False
    if entry.format is not None:
        return entry.format == "openpose"
    from kinectdata.formats import detect_format

    try:
        return detect_format(entry.recording) == "openpose"
    except KinectDataError:
        return False  # reported when the recording is read


def _read_recordings(source: Path, allow_outside: bool) -> list[RecordingEntry]:
    if source.is_dir():
        aligned = sorted(p for p in source.glob("*.h5") if _is_aligned_file(p))
        if aligned:
            return [
                RecordingEntry(name=_checked_name(p.stem, p.name, source), recording=str(p.resolve())) for p in aligned
            ]
        sessions = find_sessions(source)
        if not sessions:
            raise KinectDataError(
                f"{source}: no aligned .h5 files and no sessions (a skeleton file with audio beside it)"
            )
        return [
            RecordingEntry(
                name=_checked_name(s.name, s.skeleton.name, source),
                recording=str(s.skeleton.resolve()),
                audio=str(s.audio.resolve()),
            )
            for s in sessions
        ]
    if not source.is_file():
        raise KinectDataError(f"{source}: no such manifest file or folder")
    docs, lines, root, _ = _read_manifest(source)
    if lines is None:
        validate(docs, "recordings.schema.json", source)
    else:
        for doc, line in zip(docs, lines):  # CSV: one record at a time, so that errors name its line
            try:
                validate([doc], "recordings.schema.json", source)
            except SchemaError as exc:
                raise SchemaError(
                    source, exc.reason.replace("at 0/", "column ").replace("at 0:", "row:"), line=line
                ) from None
        if not docs:
            raise SchemaError(source, "no recordings listed")
    base = source.parent
    if root is not None:
        base = _manifest_root(source, root, allow_outside)
    entries, seen = [], {}
    for i, d in enumerate(docs):
        where = f"recordings[{i}]" if lines is None else f"line {lines[i]}"
        line = None if lines is None else lines[i]
        recording = _existing(source, base, d, "recording", where, line, allow_outside)
        if "audio" not in d and not _is_aligned_file(recording):
            raise SchemaError(
                source, f"{where}: {d['recording']} needs an 'audio' (it is not an aligned .h5)", line=line
            )
        name = _checked_name(_given_name(d, "recording"), where, source)
        if name in seen:
            raise SchemaError(source, f"{where}: name {name!r} is already used by {seen[name]}", line=line)
        seen[name] = where
        schema = d.get("schema")
        if schema is not None and (base / schema).suffix.lower() == ".json":
            schema = str(_existing(source, base, d, "schema", where, line, allow_outside))
        entries.append(
            RecordingEntry(
                name=name,
                recording=str(recording),
                audio=str(_existing(source, base, d, "audio", where, line, allow_outside)) if "audio" in d else None,
                split=d.get("split"),
                offset=d.get("offset", "auto"),
                format=d.get("format"),
                schema=schema,
                body=d.get("body"),
                person=None if d.get("person") is None else str(d["person"]),
                video_fps=None if d.get("video_fps") is None else float(d["video_fps"]),
                fps=None if d.get("fps") is None else float(d["fps"]),
                unit=d.get("unit"),
                rest_joints=(
                    str(_existing(source, base, d, "rest_joints", where, line, allow_outside))
                    if "rest_joints" in d
                    else None
                ),
                style=d.get("style"),
                beats_per_bar=None if d.get("beats_per_bar") is None else int(d["beats_per_bar"]),
                clean=d.get("clean"),
            )
        )
    return entries


def read_songs(source: str | Path, *, allow_outside_paths: bool = False) -> list[LabelledSong]:
    """The labelled songs a recordings manifest lists under ``songs`` (:class:`LabelledSong`), with
    resolved paths; none for a folder, a CSV manifest or a manifest without ``songs``.

    Their files must exist and lie where a recording's may; their names (default the audio file's
    stem) are unique among the songs and the recordings. Errors name the manifest and the song
    (``songs[2]``).
    """
    source = Path(source)
    if not source.is_file() or source.suffix.lower() == ".csv":
        return []
    docs, _, root, songs = _read_manifest(source)
    if songs is None:
        return []
    try:
        validate(songs, "songs.schema.json", source)
    except SchemaError as exc:
        raise SchemaError(source, f"songs: {exc.reason}") from None
    base = source.parent if root is None else _manifest_root(source, root, allow_outside_paths)
    taken = {
        _given_name(d, "recording"): f"recordings[{i}]"
        for i, d in enumerate(docs if isinstance(docs, list) else [])
        if isinstance(d, dict)
    }
    found = []
    for i, d in enumerate(songs):
        where = f"songs[{i}]"
        audio = _existing(source, base, d, "audio", where, None, allow_outside_paths)
        name = _checked_name(_given_name(d, "audio"), where, source)
        if name in taken:
            raise SchemaError(source, f"{where}: name {name!r} is already used by {taken[name]}")
        taken[name] = where
        found.append(LabelledSong(name=name, audio=str(audio), style=d["style"]))
    return found


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
        n_train, n_val, _ = split_counts(len(free), ratios)
        for rank, i in enumerate(order):
            splits[free[i]] = "train" if rank < n_train else "val" if rank < n_train + n_val else "test"
    return splits


def split_counts(n: int, ratios: tuple[float, float, float]) -> tuple[int, int, int]:
    """How many of ``n`` drawn recordings :func:`assign_splits` puts in train, val and test: the
    proportions ``ratios`` rounded, at least one in train."""
    shares = np.array(ratios, float) / sum(ratios)
    n_train = max(1, int(round(shares[0] * n)))
    n_val = min(n - n_train, int(round(shares[1] * n)))
    return n_train, n_val, n - n_train - n_val
