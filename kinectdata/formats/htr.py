"""Motion Analysis HTR ("Hierarchical Translation-Rotation"), as exported by Brekel Kinect tools.

The file is text (usually CRLF); ``#`` at the start of a line or after a blank starts a comment
(``1.#QNAN``, old MSVC's NaN, is a value). Sections:

- ``[Header]``: ``Key Value`` lines (keys matched case-insensitively): ``NumSegments``,
  ``NumFrames``, ``DataFrameRate``, ``EulerRotationOrder`` (one of the six orders of X, Y, Z),
  ``CalibrationUnits`` (mm, cm, m, in), ``RotationUnits`` (Degrees, Radians),
  ``GlobalAxisofGravity``, ``BoneLengthAxis``, ``ScaleFactor``...
- ``[SegmentNames&Hierarchy]``: ``child parent`` lines, ``GLOBAL`` as the parent of a root.
- ``[BasePosition]``: ``segment Tx Ty Tz Rx Ry Rz BoneLength``, the segment's base pose in its
  parent's frame.
- ``[segment]``, one block per segment: ``frame Tx Ty Tz Rx Ry Rz SF`` per frame, relative to the
  base pose.
- ``[EndOfFile]``; its absence is an error, since it is how a truncated export shows.

The maths. Euler angles of order ``"XYZ"`` mean R = Rx(Rx) · Ry(Ry) · Rz(Rz), i.e. scipy's
intrinsic ``Rotation.from_euler("XYZ", [Rx, Ry, Rz])``; likewise for the other orders (``"ZYX"``
is Rz · Ry · Rx). A segment's local transform is

    L = Translate(T_base) · Translate(T_frame) · Rot(R_base) · Rot(R_frame)

and its global transform G = G_parent · L (identity for ``GLOBAL``). A joint's position is the
origin of G and its orientation the rotation part of G, as a quaternion (x, y, z, w), both in the
HTR world frame (no axis change: ``metadata["gravity_axis"]`` says which axis is up); the
quaternions are made sign-continuous over time. Translations and bone lengths are in
``CalibrationUnits`` times the header ``ScaleFactor``, converted to metres.
The per-frame ``SF`` scales the segment's bone (its end point, not its origin), so it does not
move any joint; it is kept in ``metadata["segment_scale"]`` [T, J].

Values with magnitude >= 9e6 (Motion Analysis writes 9999999 for "no data") or not finite (NaN,
1.#QNAN...) mask that segment's frame, and the frames of all its descendants, in positions and orientations.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import JointSet, find_cycle
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import make_continuous
from kinectdata.formats.common import first_bad_time, read_text
from kinectdata.formats.registry import register_reader

BOGUS = 9e6
"""Values with at least this magnitude are Motion Analysis's 9999999 "no data" marker."""

_UNITS_TO_M = {
    "mm": 1e-3,
    "millimeter": 1e-3,
    "millimeters": 1e-3,
    "millimetre": 1e-3,
    "millimetres": 1e-3,
    "cm": 1e-2,
    "centimeter": 1e-2,
    "centimeters": 1e-2,
    "centimetre": 1e-2,
    "centimetres": 1e-2,
    "m": 1.0,
    "meter": 1.0,
    "meters": 1.0,
    "metre": 1.0,
    "metres": 1.0,
    "in": 0.0254,
    "inch": 0.0254,
    "inches": 0.0254,
}
_ANGLE_UNITS = {"degrees": True, "degree": True, "deg": True, "radians": False, "radian": False, "rad": False}
_FIXED_SECTIONS = ("header", "segmentnames&hierarchy", "baseposition", "endoffile")
# A comment starts at a "#" at the start of a line or after a blank, so that 1.#QNAN survives.
_COMMENT = re.compile(r"(^|\s)#.*")
# Old MSVC runtimes print NaN and infinity as 1.#QNAN, -1.#IND, 1.#INF.
_MSVC_NAN = re.compile(r"[-+]?1\.#(QNAN|SNAN|IND|INF)\d*", re.IGNORECASE)


class _Section:
    """A ``[name]`` section: the line of its title and its data lines with their line numbers."""

    def __init__(self, title: str, line: int) -> None:
        self.title, self.line = title, line
        self.rows: list[str] = []
        self.lines: list[int] = []


def _sniff(path: Path, head: bytes) -> bool:
    text = head.decode("latin-1").lower()
    return "[segmentnames&hierarchy]" in text or re.search(r"^\s*filetype\s+htr\b", text, re.MULTILINE) is not None


def _split_sections(path: Path) -> list[_Section]:
    """The file's sections in order, up to ``[EndOfFile]`` (content after it is ignored)."""
    text = read_text(path)
    sections: list[_Section] = []
    current: _Section | None = None
    for number, raw in enumerate(text.replace("\r\n", "\n").replace("\r", "\n").split("\n"), start=1):
        line = _COMMENT.sub("", raw).strip() if "#" in raw else raw.strip()
        if not line:
            continue
        last = number
        if line[0] == "[" and line[-1] == "]":
            current = _Section(line[1:-1].strip(), number)
            if current.title.lower() == "endoffile":
                return sections
            sections.append(current)
        elif current is None:
            raise FormatError(path, f"data before the first [section]: {line[:40]!r}", line=number)
        else:
            current.rows.append(line)
            current.lines.append(number)
    if not sections:
        raise FormatError(path, "the file is empty (no HTR sections)")
    raise FormatError(path, "no [EndOfFile] section: the file looks truncated", line=last)


def _bogus(a: np.ndarray) -> np.ndarray:
    """Where values are Motion Analysis "no data" markers, or not finite."""
    return ~np.isfinite(a) | (np.abs(a) >= BOGUS)


def _number(path: Path, token: str, line: int, what: str) -> float:
    try:
        return float(token)
    except ValueError:
        if _MSVC_NAN.fullmatch(token):
            return float("nan")
        raise FormatError(path, f"{what} is not a number: {token!r}", line=line) from None


def _integer(path: Path, token: str, line: int, what: str) -> int:
    value = _number(path, token, line, what)
    if not np.isfinite(value) or value != int(value):
        raise FormatError(path, f"{what} must be a whole number, got {token!r}", line=line)
    return int(value)


def _table(path: Path, sec: _Section, ncols: int, what: str) -> np.ndarray:
    """The numeric rows of a section as a float64 [N, ncols] array (fast path, then a precise error)."""
    try:
        table = np.loadtxt(sec.rows, dtype=np.float64, comments=None, ndmin=2)
        if table.shape[1] == ncols:
            return table
    except ValueError:
        pass
    table = np.empty((len(sec.rows), ncols))
    for i, (row, line) in enumerate(zip(sec.rows, sec.lines)):
        tokens = row.split()
        if len(tokens) != ncols:
            raise FormatError(path, f"{what} needs {ncols} values per row, found {len(tokens)}", line=line)
        table[i] = [_number(path, t, line, f"{what} value") for t in tokens]
    return table


def _header(sec: _Section) -> tuple[dict[str, str], dict[str, tuple[str, int]]]:
    """The header as written, and by lower-case key: (value, line)."""
    raw: dict[str, str] = {}
    by_key: dict[str, tuple[str, int]] = {}
    for row, line in zip(sec.rows, sec.lines):
        key, _, value = row.replace("\t", " ").partition(" ")
        raw[key] = value.strip()
        by_key[key.lower()] = (value.strip(), line)
    return raw, by_key


def _hierarchy(path: Path, sec: _Section) -> tuple[list[str], list[str | None], dict[str, int]]:
    """Segment names in file order, their parents' names (None for GLOBAL) and their lines."""
    names: list[str] = []
    parents: list[str | None] = []
    lines: dict[str, int] = {}
    for row, line in zip(sec.rows, sec.lines):
        tokens = row.split()
        if len(tokens) != 2:
            raise FormatError(path, f"a hierarchy row needs 'child parent', found {len(tokens)} values", line=line)
        child, parent = tokens
        if child in lines or child.upper() == "GLOBAL":
            raise FormatError(path, f"segment {child!r} is declared twice or named GLOBAL", line=line)
        names.append(child)
        parents.append(None if parent.upper() == "GLOBAL" else parent)
        lines[child] = line
    if not names:
        raise FormatError(path, "[SegmentNames&Hierarchy] lists no segment", line=sec.line)
    for child, parent in zip(names, parents):
        if parent is not None and parent not in lines:
            raise FormatError(path, f"segment {child!r} has unknown parent {parent!r}", line=lines[child])
    cyclic = find_cycle([-1 if p is None else names.index(p) for p in parents])
    if cyclic is not None:
        node = names[cyclic]
        raise FormatError(path, f"the hierarchy has a cycle through segment {node!r}", line=lines[node])
    return names, parents, lines


def _settings(path: Path, by_key: dict[str, tuple[str, int]], header_line: int) -> tuple[float, str, bool, str, float]:
    """DataFrameRate, EulerRotationOrder (upper case), degrees?, CalibrationUnits and ScaleFactor."""

    def value(key: str) -> tuple[str, int]:
        if not by_key.get(key.lower(), ("",))[0]:
            raise FormatError(path, f"the header has no {key}", line=header_line)
        return by_key[key.lower()]

    fps = _number(path, *value("DataFrameRate"), "DataFrameRate")
    if not 0 < fps < np.inf:
        raise FormatError(path, f"DataFrameRate must be positive, got {fps:g}", line=value("DataFrameRate")[1])
    order, line = value("EulerRotationOrder")
    if sorted(order.upper()) != ["X", "Y", "Z"]:
        raise FormatError(path, f"unknown EulerRotationOrder {order!r} (expected e.g. XYZ or ZYX)", line=line)
    units, line = value("CalibrationUnits")
    if units.lower() not in _UNITS_TO_M:
        raise FormatError(path, f"unknown CalibrationUnits {units!r} (expected mm, cm, m or in)", line=line)
    angle_units, line = value("RotationUnits")
    if angle_units.lower() not in _ANGLE_UNITS:
        raise FormatError(path, f"unknown RotationUnits {angle_units!r} (expected Degrees or Radians)", line=line)
    scale = 1.0
    if "scalefactor" in by_key:
        scale = _number(path, *by_key["scalefactor"], "ScaleFactor")
        if not 0 < scale < np.inf:
            raise FormatError(path, f"ScaleFactor must be positive, got {scale:g}", line=by_key["scalefactor"][1])
    return fps, order.upper(), _ANGLE_UNITS[angle_units.lower()], units, scale


def _base_positions(path: Path, sec: _Section, index: dict[str, int]) -> np.ndarray:
    """[J, 7] Tx Ty Tz Rx Ry Rz BoneLength of each segment, in file units and angle units."""
    base = np.zeros((len(index), 7))
    seen: set[str] = set()
    for row, line in zip(sec.rows, sec.lines):
        name, *tokens = row.split()
        if len(tokens) != 7:
            raise FormatError(
                path, f"a base position needs a segment name and 7 values, found {len(tokens)} values", line=line
            )
        if name not in index or name in seen:
            raise FormatError(path, f"base position for an unknown or repeated segment {name!r}", line=line)
        seen.add(name)
        base[index[name]] = [_number(path, t, line, "base position value") for t in tokens]
    for name in index:
        if name not in seen:
            raise FormatError(path, f"segment {name!r} has no row in [BasePosition]", line=sec.line)
    return base


def _segment_data(
    path: Path, names: list[str], blocks: list[_Section], promised: tuple[int, int] | None
) -> tuple[np.ndarray, np.ndarray]:
    """Frame numbers [T] and values [T, J, 7] (Tx Ty Tz Rx Ry Rz SF) of the segment blocks.

    ``promised`` is the header's (NumFrames, its line), if given.
    """
    tables = []
    for name, sec in zip(names, blocks):
        if promised is not None and len(sec.rows) != promised[0]:
            raise FormatError(
                path,
                f"NumFrames says {promised[0]} (line {promised[1]}), but segment {name!r} has {len(sec.rows)} frames",
                line=sec.line,
            )
        if not sec.rows:
            raise FormatError(path, f"segment {name!r} has no frames", line=sec.line)
        tables.append(_table(path, sec, 8, f"segment {name!r}"))
    frames = tables[0][:, 0]
    if not np.isfinite(frames[0]) or frames[0] != round(frames[0]):
        raise FormatError(path, f"frame number {frames[0]:g} is not a whole number", line=blocks[0].lines[0])
    steps = np.flatnonzero(np.diff(frames) != 1)
    if steps.size:
        i = int(steps[0]) + 1
        raise FormatError(
            path,
            f"frame numbers must be consecutive and increasing; frame {frames[i]:g} follows {frames[i - 1]:g}",
            line=blocks[0].lines[i],
        )
    for name, sec, table in zip(names[1:], blocks[1:], tables[1:]):
        if len(table) != len(frames):
            raise FormatError(
                path, f"segment {name!r} has {len(table)} frames, segment {names[0]!r} has {len(frames)}", line=sec.line
            )
        differ = np.flatnonzero(table[:, 0] != frames)
        if differ.size:
            i = int(differ[0])
            raise FormatError(
                path, f"frame number {table[i, 0]:g} where segment {names[0]!r} has {frames[i]:g}", line=sec.lines[i]
            )
    return frames, np.stack([t[:, 1:] for t in tables], axis=1)


def _forward_kinematics(
    base: np.ndarray,
    values: np.ndarray,
    parents: list[int],
    order: str,
    degrees: bool,
    to_m: float,
    bad: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Global positions [T, J, 3] (metres) and orientations [T, J, 4] (x, y, z, w) of every segment.

    ``base`` [J, 7] and ``values`` [T, J, 7] as in the file; ``bad`` [T, J] is extended in place
    to the descendants of each bad segment frame.
    """
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

    T, J = values.shape[:2]
    axes = ["XYZ".index(c) for c in order]  # the angle columns in the order's sequence
    positions = np.zeros((T, J, 3))
    rotations: list[Rotation | None] = [None] * J
    pending = list(range(J))
    while pending:  # parents before children, whatever order the hierarchy lists them in
        ready = [j for j in pending if parents[j] < 0 or rotations[parents[j]] is not None]
        for j in ready:
            local_t = (base[j, :3] + values[:, j, :3]) * to_m
            local_r = Rotation.from_euler(order, base[j, 3:6][axes], degrees=degrees) * Rotation.from_euler(
                order, values[:, j, 3:6][:, axes], degrees=degrees
            )
            p = parents[j]
            if p < 0:
                positions[:, j], rotations[j] = local_t, local_r
            else:
                positions[:, j] = positions[:, p] + rotations[p].apply(local_t)
                rotations[j] = rotations[p] * local_r
                bad[:, j] |= bad[:, p]
        pending = [j for j in pending if j not in ready]
    return positions, np.stack([r.as_quat() for r in rotations], axis=1)


@register_reader(
    "htr",
    extensions=(".htr",),
    sniff=_sniff,
    description="Motion Analysis HTR skeleton (Brekel Kinect exports)",
)
def read_htr(path: Path) -> Motion:
    """Read an HTR file into a Motion (see the module docstring for the maths).

    Returns:
        A Motion with ``times`` [T] seconds from the first frame, ``positions`` [T, J, 3] metres
        and ``orientations`` [T, J, 4] (x, y, z, w), both global in the HTR world frame; J is the
        segments in hierarchy order. ``metadata`` holds ``time_origin`` (the first frame number,
        unit "frame"), ``nominal_fps``, ``header`` (as written), ``euler_rotation_order``, ``calibration_units``,
        ``gravity_axis``, ``bone_length_axis``, ``bone_length_m`` [J] and ``segment_scale``
        [T, J] (the per-frame SF, NaN where masked).

    Raises:
        FormatError: the file does not follow the format; the message names the file and line.
    """
    path = Path(path)
    sections = _split_sections(path)
    fixed: dict[str, _Section] = {}
    blocks: dict[str, _Section] = {}
    for sec in sections:
        key = sec.title.lower()
        target, name = (fixed, key) if key in _FIXED_SECTIONS else (blocks, sec.title)
        if name in target:
            raise FormatError(path, f"section [{sec.title}] appears twice", line=sec.line)
        target[name] = sec
    for key, title in zip(_FIXED_SECTIONS[:3], ("Header", "SegmentNames&Hierarchy", "BasePosition")):
        if key not in fixed:
            raise FormatError(path, f"no [{title}] section")

    raw_header, by_key = _header(fixed["header"])
    fps, order, degrees, units, scale = _settings(path, by_key, fixed["header"].line)
    to_m = _UNITS_TO_M[units.lower()] * scale

    names, parent_names, decl_lines = _hierarchy(path, fixed["segmentnames&hierarchy"])
    J = len(names)
    index = {n: j for j, n in enumerate(names)}
    if "numsegments" in by_key:
        promised = _integer(path, *by_key["numsegments"], "NumSegments")
        if promised != J:
            raise FormatError(
                path,
                f"NumSegments says {promised}, but the hierarchy lists {J} segments",
                line=by_key["numsegments"][1],
            )

    base = _base_positions(path, fixed["baseposition"], index)
    for title, sec in blocks.items():
        if title not in index:
            raise FormatError(path, f"section [{title}] is not a segment of the hierarchy", line=sec.line)
    for n in names:
        if n not in blocks:
            raise FormatError(path, f"segment {n!r} has no [{n}] data block", line=decl_lines[n])
    num_frames = None
    if "numframes" in by_key:
        num_frames = (_integer(path, *by_key["numframes"], "NumFrames"), by_key["numframes"][1])
    frames, values = _segment_data(path, names, [blocks[n] for n in names], num_frames)

    base_bad = _bogus(base).any(axis=-1)  # [J]
    bad = _bogus(values).any(axis=-1) | base_bad  # [T, J]
    parents = [-1 if p is None else index[p] for p in parent_names]
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is reported below
        positions, quats = _forward_kinematics(
            np.where(base_bad[:, None], 0.0, base),
            np.where(bad[..., None], 0.0, values),
            parents,
            order,
            degrees,
            to_m,
            bad,
        )
    valid = ~bad
    overflow = valid & ~np.isfinite(positions).all(axis=-1)
    if overflow.any():
        t, j = np.argwhere(overflow)[0]
        raise FormatError(
            path,
            f"segment {names[j]!r} lies beyond 64-bit floating point in frame {frames[t]:g} "
            f"(CalibrationUnits {units} times ScaleFactor {scale:g})",
            line=blocks[names[j]].lines[t],
        )
    quats = make_continuous(quats, valid)
    with np.errstate(over="ignore"):
        times = (frames - frames[0]) / fps
    if first_bad_time(times) is not None:
        message = f"DataFrameRate {fps:g} makes {len(frames)} frames last beyond 64-bit floating point"
        raise FormatError(path, message, line=by_key["dataframerate"][1])

    return Motion(
        times=times,
        positions=positions,
        joint_set=JointSet.custom("htr", names, parent_names),
        position_mask=valid,
        confidence=valid.astype(np.float32),
        orientations=quats,
        orientation_mask=valid.copy(),
        metadata={
            "format": "htr",
            "time_origin": {"value": int(frames[0]), "unit": "frame"},
            "time_source": "frame number / the header's DataFrameRate",
            "nominal_fps": fps,
            "header": raw_header,
            "euler_rotation_order": order,
            "calibration_units": units,
            "scale_factor": scale,
            "gravity_axis": by_key.get("globalaxisofgravity", (None,))[0],
            "bone_length_axis": by_key.get("bonelengthaxis", (None,))[0],
            "bone_length_m": np.where(_bogus(base[:, 6]), np.nan, base[:, 6] * to_m),
            "segment_scale": np.where(valid, values[..., 6], np.nan),
        },
    )
