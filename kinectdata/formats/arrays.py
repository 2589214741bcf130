"""Joint positions saved as arrays (``.npy``, ``.npz``, JSON, pickles), read as an array schema declares them.

Corpora and models save joints as arrays of shape [T, J, 3] (or [T, J * 3]) with no word of their
joint set, clock, unit or axes. An array schema (``schemas/array-schema.schema.json``, a small JSON
file like a CSV dialect's) says it, so that such files read with no code:

```json
{"name": "my_corpus", "joint_set": "my_joints.json", "positions": "keypoints3d",
 "time": {"fps": 60}, "unit": "cm", "up": "y", "add": "root_translation"}
```

- ``positions``: the array's key in an ``.npz`` or a JSON object (an ``.npy``, or a JSON list, is
  the array itself);
- ``joint_set``: a shipped joint set or a joint-set file, a relative path read from the schema's
  folder; J must be its size;
- ``time``: ``{"fps": 60}`` (frames evenly spaced) or ``{"key": "timestamps", "unit": "s"}`` (a [T]
  array in the file, ``s``, ``ms``, ``us`` or ``ns``);
- ``unit``: ``m`` (default), ``cm``, ``mm`` or ``in``, converted to metres;
- ``up``: the file's up axis, ``y`` (default), ``z``, ``-y`` or ``-z``, turned into y up by a
  rotation about x (z up: (x, y, z) -> (x, z, -y)); ``handedness: "left"`` (Unity, Unreal) negates x
  first, which makes the axes right-handed as kinectdata's are;
- ``add``: the key of a [T, 3] track (a root translation) added to every joint, for files whose
  joints are relative to it;
- ``root_track``: the key of a [T, 3] track that is the root joint's own position, every joint of
  the file being relative to it (the tang2018 corpus' ``center``): it is added to them, and the joint
  set's last joint, its root, is placed on it;
- ``confidence``: the key of a [T, J] array of each joint's confidence, 0 to 1 (default: 1 where
  a position is given); ``orientations``: the key of a [T, J, 4] array of unit quaternions x, y, z,
  w in the file's axes (turned with them), as :mod:`.arrays_writer` writes them (not with
  ``derived`` or ``root_track``, whose joints the file does not hold);
- ``derived``: joints the file lacks, each a weighted sum of the file's joints (``{"pelvis":
  {"left_hip": 0.5, "right_hip": 0.5}}``), the joint set's last joints in this order: so that
  keypoint layouts with no root (COCO-17) make one tree.

A schema is a file, or the name of one shipped in ``schemas/arrays/`` (``aistpp_keypoints3d``).
Values that are not finite mark that joint's frame invalid. Pickles (``.pkl``) are read with
:func:`~kinectdata.core.safe_pickle.load_arrays_pickle`, which accepts numpy arrays in plain
containers and refuses anything else (the way a pickle runs code).
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import FormatError, SchemaError
from kinectdata.core.jointsets import JointSet, load_joint_set_named_in
from kinectdata.core.motion import Motion
from kinectdata.core.resources import load_json, resolve_resource, validate
from kinectdata.core.safe_pickle import PICKLE_SUFFIXES, load_arrays_pickle
from kinectdata.formats.common import UNITS_TO_M, brief, first_bad_time, load_numpy, to_kinectdata_axes
from kinectdata.formats.registry import register_reader

TIME_UNITS_TO_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def load_array_schema(name_or_path: str | Path) -> dict[str, Any]:
    """The array schema shipped under that name or at that path, validated, with ``joint_set``
    loaded (``"_joint_set"``) and ``derived`` checked against it."""
    path, doc = _schema_document(name_or_path)
    joint_set = load_joint_set_named_in(doc["joint_set"], path)
    if joint_set.dimensions != 3:
        raise SchemaError(
            path, f"joint_set: {joint_set.name} is {joint_set.dimensions}-D; joint arrays hold 3-D joints"
        )
    derived = list(doc.get("derived", {}))
    tracked = 1 if "root_track" in doc else 0
    if tracked and "add" in doc:
        raise SchemaError(
            path, "root_track and add: give one (root_track adds the track too, and places the root on it)"
        )
    if tracked and joint_set.parents[-1] >= 0:
        last = joint_set.names[-1]
        raise SchemaError(
            path,
            f"root_track: the track is the root's, so {joint_set.name}'s last joint must be its root, not {last!r}",
        )
    per_joint = [k for k in ("confidence", "orientations") if k in doc]
    if per_joint and (derived or tracked):
        raise SchemaError(
            path, f"{per_joint[0]}: a file whose joints are derived or tracked holds no value for those joints"
        )
    n_file = len(joint_set) - len(derived) - tracked
    if derived and list(joint_set.names[n_file : n_file + len(derived)]) != derived:
        raise SchemaError(
            path,
            f"derived: {', '.join(derived)} must be the last joints of {joint_set.name}"
            + (" before its root" if tracked else "")
            + f", in that order (there: {', '.join(joint_set.names[n_file : n_file + len(derived)])})",
        )
    for name, weights in doc.get("derived", {}).items():
        unknown = [j for j in weights if j not in joint_set.names[:n_file]]
        if unknown:
            raise SchemaError(path, f"derived: {name} is made of {', '.join(unknown)}, not joints the file holds")
    return {**doc, "_joint_set": joint_set, "_path": path, "_file_joints": n_file}


def _schema_document(name_or_path: str | Path) -> tuple[Path, dict[str, Any]]:
    """(path, document) of the array schema shipped under that name or at that path, valid against
    ``array-schema.schema.json`` (SchemaError otherwise)."""
    _, path = resolve_resource("arrays", name_or_path, "array schema")
    doc = load_json(path)
    validate(doc, "array-schema.schema.json", path)
    return path, doc


def _contents(path: Path) -> tuple[Any, str]:
    """The file's arrays: an array, a dict of arrays (``.npz``, a JSON object) or a list; and its kind."""
    suffix = path.suffix.lower()
    if suffix in (".npy", ".npz"):
        contents = load_numpy(path, "joint arrays")
        return contents, "npy" if isinstance(contents, np.ndarray) else "npz"
    if suffix in PICKLE_SUFFIXES:
        return _pickled(path)
    try:
        return json.loads(path.read_text(encoding="utf-8")), "json"
    except (ValueError, RecursionError) as exc:  # not UTF-8, not JSON, nested beyond Python's limit
        raise FormatError(path, f"cannot read it as JSON arrays ({brief(exc)})") from None


def _pickled(path: Path) -> tuple[Any, str]:
    with open(path, "rb") as f:
        try:
            contents = load_arrays_pickle(f)
        except MemoryError:
            raise FormatError(path, "the pickle declares more data than memory can hold (a damaged file?)") from None
        except pickle.UnpicklingError as exc:
            raise FormatError(path, f"cannot read it as a pickle of arrays ({brief(exc)})") from None
        except Exception as exc:  # a damaged pickle can call an allowed class with any arguments
            raise FormatError(path, f"not a readable pickle of arrays ({brief(exc)})") from None
    if isinstance(contents, np.ndarray) and contents.dtype == object and contents.shape == ():
        contents = contents.item()
    return contents, "npy" if isinstance(contents, np.ndarray) else "pickle"


def _array(path: Path, contents: Any, kind: str, key: str | None, what: str) -> np.ndarray:
    if kind == "npy" or (kind in ("json", "pickle") and isinstance(contents, list) and key is None):
        value = contents
    elif key is None:
        keys = ", ".join(sorted(contents)) if isinstance(contents, dict) else "none"
        raise FormatError(path, f"the schema names no key for the {what}, and the file holds several (keys: {keys})")
    elif not isinstance(contents, dict) or key not in contents:
        keys = ", ".join(sorted(contents)) if isinstance(contents, dict) else "none: it is one array"
        raise FormatError(path, f"no {key!r} for the {what} (keys: {keys})")
    else:
        value = contents[key]
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError(path, f"the {what} ({key or 'the array'}) are not numbers in a regular array") from None
    return array


def names_an_array_schema(options: dict[str, Any]) -> bool:
    """Whether the reading options' ``schema`` is an array schema (shipped, or a file valid as one):
    then the file is joint arrays whatever its suffix (a ``.json`` of nested lists included)."""
    schema = options.get("schema")
    if schema is None:
        return False
    try:
        _schema_document(schema)
    except (SchemaError, FormatError):
        return False
    return True


@register_reader(
    "arrays",
    extensions=(".npy", ".npz", *PICKLE_SUFFIXES),
    description="Joint arrays (.npy, .npz, .pkl, JSON) read as an array schema declares them (--schema NAME|FILE)",
    claims=names_an_array_schema,
)
def read_arrays(path: Path, *, schema: str | Path | None = None, array_fps: float | None = None) -> Motion:
    """Read joint positions saved as arrays (see the module docstring).

    Args:
        path: the ``.npy``, ``.npz``, ``.pkl`` or ``.json`` file.
        schema: the array schema, shipped name or file (required: arrays say nothing of their
            joints, clock or unit).
        array_fps: this file's frame rate, instead of the schema's ``time`` (a corpus whose files
            each have their own fixed rate: one schema, the rate in each recordings-manifest entry).

    Returns:
        A Motion: ``times`` [T] seconds from the first frame, ``positions`` [T, J, 3] metres, y up,
        right-handed; no orientations.

    Raises:
        FormatError / SchemaError: one line naming the file and what does not fit.
    """
    path = Path(path)
    if schema is None:
        raise FormatError(
            path,
            "joint arrays say nothing of their joints, clock or unit: give an array schema (--schema FILE; "
            "schemas/array-schema.schema.json)",
        )
    spec = load_array_schema(schema)
    fps = array_fps
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise FormatError(path, f"a frame rate must be a positive number of frames per second, not {fps!r}")
    js: JointSet = spec["_joint_set"]
    contents, kind = _contents(path)
    positions = _array(path, contents, kind, spec.get("positions"), "positions")
    J = spec["_file_joints"]
    if positions.ndim == 2 and positions.shape[1] == 3 * J:
        positions = positions.reshape(len(positions), J, 3)
    if positions.ndim != 3 or positions.shape[1:] != (J, 3):
        raise FormatError(
            path,
            f"positions of shape {list(positions.shape)}; the {js.name} joint set needs [T, {J}, 3] or [T, {3 * J}]",
        )
    if spec.get("derived"):
        made = [
            np.einsum("tkc,k->tc", positions[:, [js.index(j) for j in w]], np.array(list(w.values()), dtype=float))
            for w in spec["derived"].values()
        ]
        positions = np.concatenate([positions, np.stack(made, axis=1)], axis=1)
    T = len(positions)
    if T < 1:
        raise FormatError(path, "no frames")
    key = spec.get("add", spec.get("root_track"))
    if key is not None:
        track = _array(path, contents, kind, key, "root track" if "root_track" in spec else "track to add")
        if track.shape != (T, 3):
            raise FormatError(path, f"{key!r} has shape {list(track.shape)}, not [{T}, 3] like the positions")
        positions = positions + track[:, None, :]
        if "root_track" in spec:  # the root itself, where the track says
            positions = np.concatenate([positions, track[:, None, :]], axis=1)
    time = spec["time"] if fps is None else {"fps": fps}
    times, origin = _times(path, contents, kind, time, T)
    positions = positions * UNITS_TO_M[spec.get("unit", "m")]
    confidence, orientations = _per_joint(path, contents, kind, spec, T, len(js))
    positions, orientations = to_kinectdata_axes(
        positions, orientations, up=spec.get("up", "y"), handedness=spec.get("handedness", "right")
    )
    valid = np.isfinite(positions).all(axis=-1)
    return Motion(
        times=times,
        positions=positions,
        joint_set=js,
        position_mask=valid,
        confidence=None if confidence is None else np.where(valid, confidence, 0.0),
        orientations=orientations,
        metadata={
            "format": "arrays",
            "schema": spec["name"],
            "schema_path": str(spec["_path"]),
            **({"time_source": "frame index at the schema's fps"} if "fps" in time else {}),
            **({"time_origin": {"value": origin, "unit": time["unit"]}} if "key" in time else {}),
        },
    )


def _per_joint(
    path: Path, contents: Any, kind: str, spec: dict[str, Any], T: int, J: int
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The schema's ``confidence`` [T, J] (0 to 1) and ``orientations`` [T, J, 4] arrays, None where
    it names none; FormatError for a shape or value that does not fit."""
    confidence = orientations = None
    if "confidence" in spec:
        confidence = _array(path, contents, kind, spec["confidence"], "confidences")
        if confidence.shape != (T, J):
            raise FormatError(path, f"{spec['confidence']!r} has shape {list(confidence.shape)}, not [{T}, {J}]")
        outside = np.isfinite(confidence) & ((confidence < 0) | (confidence > 1))
        if outside.any():
            t, j = np.argwhere(outside)[0]
            raise FormatError(
                path, f"{spec['confidence']!r}: {confidence[t, j]:g} at frame {t}, joint {j} is not in 0..1"
            )
        confidence = np.nan_to_num(confidence, nan=0.0)
    if "orientations" in spec:
        orientations = _array(path, contents, kind, spec["orientations"], "orientations")
        if orientations.shape != (T, J, 4):
            raise FormatError(path, f"{spec['orientations']!r} has shape {list(orientations.shape)}, not [{T}, {J}, 4]")
        norms = np.linalg.norm(orientations, axis=-1)
        bad = np.isfinite(norms) & (np.abs(norms - 1.0) > 1e-3)
        if bad.any():
            t, j = np.argwhere(bad)[0]
            raise FormatError(
                path,
                f"{spec['orientations']!r}: the quaternion at frame {t}, joint {j} has length {norms[t, j]:g}, not 1",
            )
    return confidence, orientations


def _times(path: Path, contents: Any, kind: str, time: dict, T: int) -> tuple[np.ndarray, float]:
    """[T] seconds from the first frame, and the first frame's time in the file's unit (0 at an fps)."""
    if "fps" in time:
        return np.arange(T) / float(time["fps"]), 0.0
    raw = _array(path, contents, kind, time["key"], "timestamps")
    if raw.shape != (T,):
        raise FormatError(path, f"{time['key']!r} has shape {list(raw.shape)}, not [{T}] like the positions")
    times = (raw - raw[0]) * TIME_UNITS_TO_S[time["unit"]]
    bad = first_bad_time(times)
    if bad is not None:
        raise FormatError(path, f"{time['key']!r}: time {raw[bad]:g} at frame {bad} does not come after the one before")
    return times, float(raw[0])
