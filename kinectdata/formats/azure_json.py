"""Azure Kinect Body Tracking JSON, as written by the SDK's offline processor.

Top-level keys: ``k4abt_sdk_version``, ``source_file``, ``joint_names``, ``bone_list`` (pairs of
joint names) and ``frames``; each frame has ``timestamp_usec`` (device microseconds), ``frame_id``,
``num_bodies`` and ``bodies``, each body ``body_id``, ``joint_positions`` ([x, y, z] millimetres
per joint) and ``joint_orientations`` ([w, x, y, z] per joint). The tool writes its keys in
alphabetical order, so ``bone_list`` and ``frames`` come first and the version last.

Mapping to :class:`~kinectdata.core.motion.Motion`:

- joints are the file's ``joint_names``: the shipped ``azure_kinect`` set when they are its 32
  names in order (aliases such as SPINE_NAVAL allowed), else a custom set whose hierarchy comes
  from ``bone_list``;
- one body per Motion: ``body`` (the body_id, compared as text) or, by default, the body present
  in the most frames (ties: the first to appear). Frames without it stay, fully masked;
- ``times`` are seconds from the first frame's ``timestamp_usec``; positions are converted from
  millimetres to metres, quaternions from (w, x, y, z) to (x, y, z, w) (all-zero = no orientation);
- axes: Azure Kinect reports the depth camera's frame (x right, y down, z forward); kinectdata
  uses the Kinect v2 camera convention (x to the sensor's left, y up, z forward), so positions
  become (-x, -y, z) and orientations R become Rz(180 deg) R: a 180-degree turn about z, which
  keeps the frame right-handed and the skeleton upright and unmirrored next to Kinect v2 data;
- the tool writes no per-joint confidence: 1.0 wherever the body is present.

Errors name the 0-based frame index (and ``bodies[i]``), or the line of a JSON syntax error.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import JointSet, load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import split_missing_and_normalise, wxyz_to_xyzw
from kinectdata.formats.common import choose_body, count_bodies, first_bad_time, read_text
from kinectdata.formats.registry import register_reader


def _sniff(path: Path, head: bytes) -> bool:
    """True for a JSON object whose first 4096 bytes show the offline processor's keys."""
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff \t\r\n")
    if not text.startswith("{"):
        return False
    if '"k4abt_sdk_version"' in text:
        return True
    # The offline processor sorts keys: a 4 KB head holds bone_list and frames, not joint_names.
    keys = ('"joint_names"', '"bone_list"', '"body_id"', '"timestamp_usec"', '"joint_positions"')
    return '"frames"' in text and any(k in text for k in keys)


def _load(path: Path) -> Any:
    text = read_text(path, fallback_encoding=None)
    if not text.strip():
        raise FormatError(path, "the file is empty", line=1)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(path, f"invalid JSON: {exc.msg} (column {exc.colno})", line=exc.lineno) from exc
    except RecursionError:
        raise FormatError(path, "invalid JSON: nested too deeply") from None
    except ValueError as exc:  # e.g. an integer longer than Python's digit limit
        raise FormatError(path, f"invalid JSON: {exc}") from None


def _show(v: Any, limit: int = 80) -> str:
    text = repr(v)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _is_number(v: Any) -> bool:
    if isinstance(v, bool):
        return False
    if isinstance(v, int):
        return -(2**63) <= v < 2**63
    return isinstance(v, float) and math.isfinite(v)


def _joint_set(path: Path, names: Any, bone_list: Any) -> JointSet:
    if not isinstance(names, list) or not names or not all(isinstance(n, str) and n for n in names):
        raise FormatError(path, "'joint_names' must be a non-empty list of joint names")
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise FormatError(path, f"'joint_names' lists {dup!r} twice")
    shipped = load_joint_set("azure_kinect")
    if tuple(shipped.aliases.get(n, n) for n in names) == shipped.names:
        return shipped
    return JointSet.custom(f"azure_kinect_{len(names)}", names, _parents(path, names, bone_list))


def _parents(path: Path, names: list[str], bone_list: Any) -> list[str | None]:
    """Parent of each joint from ``bone_list``, rooting each connected part at its first joint.

    The SDK's own bone list does not keep (parent, child) order (it has [SPINE_NAVEL, PELVIS]
    beside [PELVIS, HIP_LEFT]), so the pairs are taken as undirected edges and the tree is rooted
    at the lowest-index joint, which is PELVIS in every SDK joint list.
    """
    if bone_list is None:
        return [None] * len(names)
    if not isinstance(bone_list, list):
        raise FormatError(path, "'bone_list' must be a list of [joint, joint] pairs")
    index = {n: i for i, n in enumerate(names)}
    neighbours: list[set[int]] = [set() for _ in names]
    for i, pair in enumerate(bone_list):
        valid = isinstance(pair, list) and len(pair) == 2 and all(isinstance(p, str) and p in index for p in pair)
        if not valid or pair[0] == pair[1]:
            raise FormatError(
                path, f"bone_list[{i}] must be a pair of two different names from 'joint_names', found {_show(pair)}"
            )
        a, b = index[pair[0]], index[pair[1]]
        neighbours[a].add(b)
        neighbours[b].add(a)
    parent = [-2] * len(names)  # -2: not reached yet
    for root in range(len(names)):
        if parent[root] != -2:
            continue
        parent[root] = -1
        stack = [root]
        while stack:
            j = stack.pop()
            for c in neighbours[j]:
                if c == parent[j]:
                    continue
                if parent[c] != -2:
                    raise FormatError(path, f"bone_list has a cycle through joint {names[c]!r}")
                parent[c] = j
                stack.append(c)
    return [None if p < 0 else names[p] for p in parent]


def _numbers(
    path: Path, lists: list, where: list[tuple[int, int]], key: str, width: int, names: list[str]
) -> np.ndarray:
    """[n, J, width] float64 from n bodies' per-joint lists; errors locate the bad value.

    ``where`` holds the (frame index, index in ``bodies``) of each of the n bodies.
    """
    J = len(names)
    try:
        values = np.array(lists, dtype=np.float64)
        ok = values.shape == (len(lists), J, width)
    except (ValueError, TypeError, OverflowError):
        ok = False
    if ok:
        finite = np.isfinite(values).all(axis=-1)
        if finite.all():
            return values
        o, j = np.argwhere(~finite)[0]
        frame, b = where[o]
        message = f"bodies[{b}].{key}[{j}] ({names[j]}) is not a finite number: {_show(lists[o][j])}"
        raise FormatError(path, message, frame=frame)
    for o, per_joint in enumerate(lists):
        for j, v in enumerate(per_joint):
            if not (isinstance(v, list) and len(v) == width and all(_is_number(x) for x in v)):
                frame, b = where[o]
                message = f"bodies[{b}].{key}[{j}] ({names[j]}) must be {width} finite numbers, found {_show(v)}"
                raise FormatError(path, message, frame=frame)
    raise FormatError(path, f"'{key}' values cannot be read as numbers")


_TURN_Z = np.array([-1.0, -1.0, 1.0])  # Azure depth-camera axes -> Kinect v2 camera axes
_Z180_XYZW = [0.0, 0.0, 1.0, 0.0]  # half a turn about z, as a quaternion


@register_reader(
    "azure_json",
    extensions=(),
    sniff=_sniff,
    description="Azure Kinect Body Tracking JSON (offline processor)",
)
def read_azure_json(path: Path, *, body: str | None = None) -> Motion:
    """Read one body of an Azure Kinect offline-processor JSON file.

    Args:
        path: the JSON file.
        body: body_id as written in the file (compared as text); default the body present in the
            most frames.

    Returns:
        A Motion: ``times`` [T] seconds from the first frame, ``positions`` [T, J, 3] metres,
        ``orientations`` [T, J, 4] (x, y, z, w), ``confidence`` [T, J] (1.0 where the body is
        present, 0.0 elsewhere), with J the file's joint count. ``metadata`` holds ``time_origin``
        (first ``timestamp_usec``), ``body``, ``bodies`` (id and frame count of each),
        ``k4abt_sdk_version`` and ``source_file``.
    """
    path = Path(path)
    doc = _load(path)
    if not isinstance(doc, dict):
        raise FormatError(path, "the top level must be a JSON object with 'joint_names' and 'frames'")
    for key in ("joint_names", "frames"):
        if key not in doc:
            raise FormatError(path, f"missing top-level key {key!r} (not an Azure Kinect body-tracking JSON?)")
    joint_set = _joint_set(path, doc["joint_names"], doc.get("bone_list"))
    names, J = list(joint_set.names), len(joint_set)
    frames = doc["frames"]
    if not isinstance(frames, list):
        raise FormatError(path, "'frames' must be a list")
    if not frames:
        raise FormatError(path, "'frames' is empty: the file holds no frames")

    stamps: list[int | float] = []
    where: list[tuple[int, int]] = []  # (frame index, index in its 'bodies') of each body occurrence
    ids: list[str] = []
    pos_lists: list = []
    ori_lists: list = []
    for f, frame in enumerate(frames):
        if not isinstance(frame, dict):
            raise FormatError(path, "a frame must be a JSON object", frame=f)
        for key in ("timestamp_usec", "num_bodies", "bodies"):
            if key not in frame:
                raise FormatError(path, f"missing key {key!r}", frame=f)
        t, n, bodies = frame["timestamp_usec"], frame["num_bodies"], frame["bodies"]
        if not _is_number(t):
            message = f"timestamp_usec must be a number of microseconds (64-bit), found {_show(t)}"
            raise FormatError(path, message, frame=f)
        if not isinstance(bodies, list):
            raise FormatError(path, f"'bodies' must be a list, found {type(bodies).__name__}", frame=f)
        if not isinstance(n, int) or isinstance(n, bool) or n != len(bodies):
            raise FormatError(path, f"num_bodies {n!r} does not match the {len(bodies)} entries of 'bodies'", frame=f)
        stamps.append(t)
        seen: set[str] = set()
        for b, entry in enumerate(bodies):
            if not isinstance(entry, dict):
                raise FormatError(path, f"bodies[{b}] must be a JSON object", frame=f)
            for key in ("body_id", "joint_positions", "joint_orientations"):
                if key not in entry:
                    raise FormatError(path, f"bodies[{b}] has no {key!r}", frame=f)
            body_id = entry["body_id"]
            if not isinstance(body_id, (int, str)) or isinstance(body_id, bool):
                message = f"bodies[{b}].body_id must be an integer or text, found {_show(body_id)}"
                raise FormatError(path, message, frame=f)
            body_id = str(body_id)
            if body_id in seen:
                raise FormatError(path, f"body_id {body_id} appears twice in this frame", frame=f)
            seen.add(body_id)
            for key in ("joint_positions", "joint_orientations"):
                value = entry[key]
                if not isinstance(value, list) or len(value) != J:
                    found = f"{len(value)} entries" if isinstance(value, list) else type(value).__name__
                    message = f"bodies[{b}].{key} must list {J} joints (one per joint name), found {found}"
                    raise FormatError(path, message, frame=f)
            where.append((f, b))
            ids.append(body_id)
            pos_lists.append(entry["joint_positions"])
            ori_lists.append(entry["joint_orientations"])

    first = stamps[0]
    # Python numbers subtract exactly (int64 arrays would wrap); device clocks run to ~1e12 us
    times = np.array([t - first for t in stamps], dtype=np.float64) / 1e6
    f = first_bad_time(times)
    if f is not None:
        if stamps[f] <= stamps[f - 1]:
            message = f"timestamp_usec {stamps[f]} is not after the previous frame's {stamps[f - 1]}"
        else:
            message = (
                f"timestamp_usec {stamps[f]}, counted from the first frame's {first}, overflows or does not come "
                "after the previous frame's in 64-bit floating point (is the first timestamp damaged?)"
            )
        raise FormatError(path, message, frame=f)

    bodies_meta = count_bodies(ids)
    body = choose_body(path, bodies_meta, body, n_frames=len(frames))

    positions_mm = _numbers(path, pos_lists, where, "joint_positions", 3, names)
    quats = _numbers(path, ori_lists, where, "joint_orientations", 4, names)
    chosen = np.array([i for i, b in enumerate(ids) if b == body])
    frame_idx = np.array([where[i][0] for i in chosen])
    with np.errstate(over="ignore"):  # the norm of huge values overflows to inf: not a unit quaternion
        unit, present, bad = split_missing_and_normalise(wxyz_to_xyzw(quats[chosen]))
    if bad.any():
        o, j = np.argwhere(bad)[0]
        f, b = where[chosen[o]]
        norm = math.hypot(*quats[chosen[o], j])  # inf, not an overflow warning, for huge values
        raise FormatError(path, f"bodies[{b}].joint_orientations[{j}] ({names[j]}) has norm {norm:.4g}, not 1", frame=f)

    T = len(frames)
    positions = np.full((T, J, 3), np.nan)
    positions[frame_idx] = positions_mm[chosen] / 1000.0 * _TURN_Z
    valid = present.reshape(-1)
    flat = unit.reshape(-1, 4)
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

    flat[valid] = (Rotation.from_quat(_Z180_XYZW) * Rotation.from_quat(flat[valid])).as_quat(canonical=False)
    unit = flat.reshape(unit.shape)
    position_mask = np.zeros((T, J), bool)
    position_mask[frame_idx] = True
    orientations = np.full((T, J, 4), np.nan)
    orientations[frame_idx] = unit
    orientation_mask = np.zeros((T, J), bool)
    orientation_mask[frame_idx] = present

    return Motion(
        times=times,
        positions=positions,
        joint_set=joint_set,
        position_mask=position_mask,
        confidence=position_mask.astype(np.float32),
        orientations=orientations,
        orientation_mask=orientation_mask,
        metadata={
            "format": "azure_json",
            "time_origin": {"value": first, "unit": "us"},
            "time_source": "timestamp_usec (device clock)",
            "axes": "Kinect v2 camera space (converted from Azure's x right, y down, z forward)",
            "body": body,
            "bodies": bodies_meta,
            "k4abt_sdk_version": doc.get("k4abt_sdk_version"),
            "source_file": doc.get("source_file"),
        },
    )
