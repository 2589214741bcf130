"""Biovision BVH: a skeleton hierarchy with offsets, then one line of channel values per frame.

The file is text, whitespace-separated tokens:

- ``HIERARCHY``, then ``ROOT name { ... }``: each joint block holds ``OFFSET x y z`` (its origin in
  its parent's frame), ``CHANNELS n c1 .. cn`` and its children, ``JOINT name { ... }`` or one
  ``End Site { OFFSET x y z }`` (the tip of a chain: a point with no channels);
- ``MOTION``, ``Frames: N``, ``Frame Time: dt`` (seconds), then N lines of values, each joint's
  channels in the order the hierarchy declared them (depth first).

Channels are ``Xposition Yposition Zposition Xrotation Yrotation Zrotation`` in any order and any
subset (case is not significant). The maths, as Blender, MotionBuilder and ``bvhio`` read it:

- a joint's rotation is its rotation channels in their written order, intrinsic: channels
  ``Zrotation Xrotation Yrotation`` mean R = Rz(z) · Rx(x) · Ry(y), scipy's
  ``Rotation.from_euler("ZXY", [z, x, y], degrees=True)`` (angles are degrees);
- its translation from its parent is the OFFSET, with each position channel replacing the
  matching coordinate (files that give every joint position channels write the offset there at
  rest);
- global transforms chain down the hierarchy, G = G_parent · [R | t]: a joint's position is the
  origin of G and its orientation the rotation part of G, a quaternion (x, y, z, w) made
  sign-continuous over time. An End Site is a joint named ``<parent>_End`` (``_End2``... when a
  joint has several) placed at its offset in its parent's frame; it has no orientation of its own.

Units and axes: BVH does not say its unit. Offsets and positions are scaled to metres by
``unit`` (``cm`` by default: Mixamo, MotionBuilder and most dance captures write centimetres;
``m``, ``mm`` and ``in`` too); the axes are kept as written (most files have y up). The joint set
is named ``bvh-`` and 8 hex digits of a hash of the joint names and parents, so every file of one
skeleton (a corpus) shares it.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import JointSet
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import make_continuous
from kinectdata.formats.common import UNITS_TO_M, read_text
from kinectdata.formats.registry import register_reader

MAX_FRAME_TIME_S = 3600.0
"""A frame time above an hour is damage, not a frame rate (and would overflow the clock)."""

CHANNELS = ("xposition", "yposition", "zposition", "xrotation", "yrotation", "zrotation")


@dataclass
class _Joint:
    name: str
    parent: int
    offset: np.ndarray  # [3], file units
    channels: list[str] = field(default_factory=list)  # lower case, in file order
    first: int = 0  # column of its first channel in a frame line
    end_site: bool = False


class _Tokens:
    """The file's tokens with their line numbers, read in order."""

    def __init__(self, path: Path, text: str) -> None:
        self.path = path
        self.items: list[tuple[str, int]] = []
        for number, line in enumerate(text.splitlines(), start=1):
            self.items.extend((token, number) for token in line.split())
        self.k = 0

    @property
    def line(self) -> int:
        return self.items[min(self.k, len(self.items) - 1)][1] if self.items else 1

    def next(self, what: str) -> str:
        if self.k >= len(self.items):
            raise FormatError(self.path, f"the file ends where {what} should be", line=self.line)
        token = self.items[self.k][0]
        self.k += 1
        return token

    def expect(self, word: str) -> None:
        line = self.line
        token = self.next(repr(word))
        if token.upper() != word.upper():
            raise FormatError(self.path, f"expected {word!r}, found {token!r}", line=line)

    def number(self, what: str) -> float:
        line = self.line
        token = self.next(what)
        try:
            value = float(token)
        except ValueError:
            raise FormatError(self.path, f"{what}: {token!r} is not a number", line=line) from None
        if not np.isfinite(value):
            raise FormatError(self.path, f"{what}: {token!r} is not a finite number", line=line)
        return value


def _sniff(path: Path, head: bytes) -> bool:
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").upper().startswith(b"HIERARCHY")


def _hierarchy(tokens: _Tokens) -> tuple[list[_Joint], int]:
    """The joints (End Sites included) in declaration order, parents before children, and the
    number of channel values a frame line holds."""
    tokens.expect("HIERARCHY")
    tokens.expect("ROOT")
    joints: list[_Joint] = []
    columns = _block(tokens, -1, tokens.next("the root's name"), False, joints, 0)
    return joints, columns


def _block(tokens: _Tokens, parent: int, name: str, end_site: bool, joints: list[_Joint], columns: int) -> int:
    """Read one joint block, and its children depth first (the order of the channel columns), into
    ``joints``; returns the next free channel column."""
    if end_site:
        siblings = sum(1 for j in joints if j.end_site and j.parent == parent)
        name = f"{name}_End" + (str(siblings + 1) if siblings else "")
    tokens.expect("{")
    tokens.expect("OFFSET")
    offset = np.array([tokens.number(f"{name}'s OFFSET") for _ in range(3)])
    joint = _Joint(name, parent, offset, first=columns, end_site=end_site)
    index = len(joints)
    joints.append(joint)
    if not end_site:
        tokens.expect("CHANNELS")
        count_line = tokens.line
        count = tokens.number(f"{name}'s channel count")
        if count != int(count) or not 0 <= count <= 6:
            raise FormatError(tokens.path, f"joint {name!r}: {count:g} channels (0 to 6 expected)", line=count_line)
        for _ in range(int(count)):
            channel_line = tokens.line
            channel = tokens.next(f"{name}'s channels").lower()
            if channel not in CHANNELS:
                raise FormatError(
                    tokens.path,
                    f"joint {name!r}: unknown channel {channel!r} (expected Xposition .. Zrotation)",
                    line=channel_line,
                )
            if channel in joint.channels:
                raise FormatError(tokens.path, f"joint {name!r}: channel {channel!r} twice", line=channel_line)
            joint.channels.append(channel)
        columns += len(joint.channels)
    while True:
        word_line = tokens.line
        word = tokens.next(f"the end of {name}'s block")
        upper = word.upper()
        if upper == "}":
            return columns
        if end_site:
            raise FormatError(tokens.path, f"an End Site holds only an OFFSET, found {word!r}", line=word_line)
        if upper == "JOINT":
            columns = _block(tokens, index, tokens.next("a joint's name"), False, joints, columns)
        elif upper == "END":
            tokens.expect("Site")
            columns = _block(tokens, index, name, True, joints, columns)
        else:
            raise FormatError(tokens.path, f"expected JOINT, End Site or '}}', found {word!r}", line=word_line)


def _split(text: str) -> tuple[str, int, str]:
    """``(head, first_line, frames)``: the text up to the frame lines (the hierarchy and the MOTION,
    Frames and Frame Time lines, which are tokenised), the line number of the first frame line, and
    the frame lines (which can be hundreds of megabytes: pandas parses them)."""
    offset, number = 0, 0
    header_lines_left = None  # after MOTION: its "Frames:" and "Frame Time:" lines
    for line in text.splitlines(keepends=True):
        stripped = line.strip()
        if header_lines_left is not None and stripped:
            if header_lines_left == 0:
                break
            header_lines_left -= 1
        elif stripped.upper().startswith("MOTION"):
            header_lines_left = 2
        offset += len(line)
        number += 1
    return text[:offset], number + 1, text[offset:]


def _motion(tokens: _Tokens, columns: int, frames_text: str, first_line: int) -> tuple[np.ndarray, float]:
    """The frame values [T, columns] (file units, degrees) and the frame time (seconds)."""
    tokens.expect("MOTION")
    tokens.expect("Frames:")
    count_line = tokens.line
    count = tokens.number("the frame count")
    if count != int(count) or count < 1:
        raise FormatError(tokens.path, f"Frames: {count:g} (a positive whole number expected)", line=count_line)
    tokens.expect("Frame")
    tokens.expect("Time:")
    time_line = tokens.line
    frame_time = tokens.number("the frame time")
    if not 0 < frame_time < MAX_FRAME_TIME_S:
        message = f"Frame Time: {frame_time:g} s (a positive number of seconds, below {MAX_FRAME_TIME_S:g}, expected)"
        raise FormatError(tokens.path, message, line=time_line)
    n = int(count)
    values = _fast_frames(frames_text, columns)
    if values is None or values.shape != (n, columns) or not np.isfinite(values).all():
        _locate_bad_frames(tokens.path, frames_text, first_line, n, columns)
    return values, frame_time


def _fast_frames(frames_text: str, columns: int) -> np.ndarray | None:
    """The frame lines as a [T, columns] array by pandas' C parser, or None where it cannot."""
    import io

    import pandas as pd

    if columns == 0 or not frames_text.strip():
        return None
    try:
        table = pd.read_csv(io.StringIO(frames_text), sep=r"\s+", header=None, dtype=np.float64, engine="c")
    except (ValueError, pd.errors.ParserError):
        return None
    return table.to_numpy()


def _locate_bad_frames(path: Path, frames_text: str, first_line: int, n: int, columns: int) -> None:
    """Raise the FormatError of the first bad frame line (slow: only for a file pandas refused)."""
    t, last = 0, first_line - 1
    for number, line in enumerate(frames_text.splitlines(), start=first_line):
        cells = line.split()
        if not cells:
            continue
        last = number
        if t >= n:
            raise FormatError(path, f"more values than Frames: {n} frames of {columns} channels", line=number)
        if len(cells) != columns:
            raise FormatError(
                path, f"frame {t}: {len(cells)} values, but a line must hold {columns}, one per channel", line=number
            )
        for cell in cells:
            try:
                value = float(cell)
            except ValueError:
                raise FormatError(path, f"frame {t}: {cell!r} is not a number", line=number) from None
            if not np.isfinite(value):
                raise FormatError(path, f"frame {t}: a value is not finite ({cell!r})", line=number)
        t += 1
    raise FormatError(path, f"Frames: {n}, but the values stop after {t} whole frame(s) of {columns}", line=last)


def _forward_kinematics(joints: list[_Joint], values: np.ndarray, to_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Global positions [T, J, 3] (metres) and orientations [T, J, 4] (x, y, z, w) of every joint."""
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

    T, J = values.shape[0], len(joints)
    positions = np.zeros((T, J, 3))
    rotations: list[Rotation] = []
    for j, joint in enumerate(joints):  # parents come before their children
        local_t = np.repeat(joint.offset[None], T, axis=0)
        order, angles = "", []
        for k, channel in enumerate(joint.channels):
            column = values[:, joint.first + k]
            if channel.endswith("position"):
                local_t[:, "xyz".index(channel[0])] = column
            else:
                order += channel[0].upper()
                angles.append(column)
        local_t = local_t * to_m
        local_r = Rotation.from_euler(order, np.stack(angles, axis=1), degrees=True) if order else Rotation.identity(T)
        if joint.parent < 0:
            positions[:, j] = local_t
            rotations.append(local_r)
        else:
            positions[:, j] = positions[:, joint.parent] + rotations[joint.parent].apply(local_t)
            rotations.append(rotations[joint.parent] * local_r)
    return positions, np.stack([r.as_quat() for r in rotations], axis=1)


def bvh_joint_set(names: list[str], parents: list[int], end_sites: list[bool]) -> JointSet:
    """The joint set of a BVH hierarchy: named by a hash of its joints and parents, End Sites
    without orientations."""
    digest = hashlib.sha256(repr((names, parents)).encode()).hexdigest()[:8]
    return JointSet(
        name=f"bvh-{digest}",
        names=tuple(names),
        parents=tuple(parents),
        has_orientation=tuple(not e for e in end_sites),
        description="a BVH file's hierarchy",
    )


@register_reader("bvh", extensions=(".bvh",), sniff=_sniff, description="Biovision BVH motion capture")
def read_bvh(path: Path, *, unit: str = "cm") -> Motion:
    """Read a BVH file into a Motion (see the module docstring for the maths).

    Args:
        path: the ``.bvh`` file.
        unit: the unit of its offsets and positions: ``cm`` (the default), ``m``, ``mm`` or ``in``.

    Returns:
        A Motion with ``times`` [T] seconds (``k * Frame Time``), ``positions`` [T, J, 3] metres and
        ``orientations`` [T, J, 4] (x, y, z, w), both global in the file's frame; J is the joints and
        End Sites in the order the hierarchy declares them. ``metadata`` holds ``nominal_fps``,
        ``unit`` and ``offsets_m`` [J, 3] (each joint's OFFSET in metres: the rest skeleton).

    Raises:
        FormatError: the file does not follow the format, or ``unit`` is not one of the above;
            the message names the file and line.
    """
    path = Path(path)
    if unit not in UNITS_TO_M:
        raise FormatError(path, f"unit {unit!r} is not one of {', '.join(UNITS_TO_M)}")
    head, first_frame_line, frames_text = _split(read_text(path))
    tokens = _Tokens(path, head)
    joints, columns = _hierarchy(tokens)
    values, frame_time = _motion(tokens, columns, frames_text, first_frame_line)
    positions, quats = _forward_kinematics(joints, values, UNITS_TO_M[unit])
    joint_set = bvh_joint_set([j.name for j in joints], [j.parent for j in joints], [j.end_site for j in joints])
    orientation_mask = np.broadcast_to(joint_set.orientation_mask, quats.shape[:2])
    return Motion(
        times=np.arange(len(values)) * frame_time,
        positions=positions,
        joint_set=joint_set,
        orientations=make_continuous(quats, orientation_mask),
        orientation_mask=orientation_mask,
        metadata={
            "format": "bvh",
            "nominal_fps": 1.0 / frame_time,
            "time_source": "frame index x the header's Frame Time",
            "unit": unit,
            "offsets_m": (np.array([j.offset for j in joints]) * UNITS_TO_M[unit]).tolist(),
        },
    )
