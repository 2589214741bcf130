"""NTU RGB+D ``.skeleton`` files: Kinect v2 skeletons as whitespace-separated text.

Layout, one group of values per line::

    <frame count>
    per frame:  <body count>                        (0 when nobody is seen)
      per body: bodyID clippedEdges handLeftConfidence handLeftState handRightConfidence
                handRightState isRestricted leanX leanY trackingState
                <joint count>                       (25)
                per joint: x y z depthX depthY colorX colorY orientW orientX orientY orientZ state

Mapping to :class:`~kinectdata.core.motion.Motion` (joint set ``kinect_v2``):

- one body per Motion: ``body`` (the bodyID as written) or, by default, the body present in the
  most frames (ties: the first to appear). Frames without that body stay, fully masked.
- The format has no timestamps: ``times`` are frame index / 30 (Kinect v2's nominal rate).
- Positions are camera-space metres as stored; the depth/colour pixel coordinates are not kept.
- Quaternions are stored (w, x, y, z) and returned (x, y, z, w); ``0 0 0 0`` (leaf joints) means
  "no orientation" and is masked.
- Joint tracking state 2 / 1 / 0 gives confidence 1.0 / 0.5 / 0.0; a position, and likewise an
  orientation, is valid only when the state is above 0 (the sensor writes junk for untracked joints).

Every line must parse (count, token count, numbers, finite); tracking states and quaternion norms
are checked for the body read. Errors name the 1-based line.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import split_missing_and_normalise, wxyz_to_xyzw
from kinectdata.formats.common import choose_body, count_bodies, read_text
from kinectdata.formats.registry import register_reader

NOMINAL_FPS = 30.0
N_JOINTS = 25
MAX_BODIES = 6  # Kinect v2 tracks at most six bodies
BODY_FIELDS = 10
JOINT_FIELDS = 12
_FILE_NAME = re.compile(r"S(\d{3})C(\d{3})P(\d{3})R(\d{3})A(\d{3})")
_NAME_FIELDS = ("setup", "camera", "performer", "replication", "action")
_CONFIDENCE = np.array([0.0, 0.5, 1.0], dtype=np.float32)


def _sniff(path: Path, head: bytes) -> bool:
    """True when the first lines read: frame count, body count, then a body line and 25 (or EOF)."""
    lines = head.decode("utf-8", errors="replace").lstrip("\ufeff").splitlines()
    if len(head) >= 4096:
        lines = lines[:-1]  # the last line may be cut
    rows = [s.split() for s in lines if s.strip()]
    if len(rows) < 2 or not all(len(t) == 1 and t[0].isdecimal() for t in rows[:2]):
        return False
    if int(rows[1][0]) == 0 or len(rows) < 4:
        return int(rows[1][0]) <= MAX_BODIES
    return len(rows[2]) == BODY_FIELDS and rows[2][0].isdecimal() and rows[3] == [str(N_JOINTS)]


class _Lines:
    """The non-blank lines of a text file, consumed in order, with their 1-based line numbers."""

    def __init__(self, path: Path) -> None:
        all_lines = read_text(path, fallback_encoding=None).splitlines()
        self.path = path
        self.n_total = len(all_lines)
        self.numbers = [i for i, s in enumerate(all_lines, 1) if s.strip()]
        self.texts = [all_lines[i - 1] for i in self.numbers]
        self.k = 0  # index of the next unread non-blank line

    def error(self, message: str, k: int | None = None, frame: int | None = None) -> FormatError:
        k = self.k if k is None else k
        line = self.numbers[k] if k < len(self.numbers) else self.n_total + 1
        return FormatError(self.path, message, line=line, frame=frame)

    def remaining(self) -> int:
        return len(self.texts) - self.k

    def need(self, n: int, what: str, frame: int | None) -> None:
        if self.remaining() < n:
            raise self.error(f"unexpected end of file: expected {what} (truncated file?)", len(self.texts), frame)

    def count(self, what: str, frame: int | None = None) -> int:
        """Read a line holding one non-negative integer."""
        self.need(1, f"the {what}", frame)
        tokens = self.texts[self.k].split()
        if len(tokens) != 1 or not tokens[0].isdecimal():
            shown = self.texts[self.k].strip()[:60]
            raise self.error(f"expected the {what} (one non-negative integer), found {shown!r}", frame=frame)
        self.k += 1
        return int(tokens[0])


def _looks_like_body_line(lines: _Lines) -> bool:
    """Whether the next line has a body line's shape (its count of values, an integer bodyID)."""
    if not lines.remaining():
        return False
    tokens = lines.texts[lines.k].split()
    return len(tokens) == BODY_FIELDS and tokens[0].isdecimal()


def _holds_a_count(lines: _Lines) -> bool:
    """Whether the next line holds a single integer (a frame's body count), not a body line. At the
    end of the file, False: a truncated file is the likelier cause, and reading on says so."""
    return bool(lines.remaining()) and lines.texts[lines.k].strip().isdecimal()


def _miscounted(lines: _Lines, count_k: int, n_bodies: int, frame: int, why: str) -> FormatError:
    """The error for a frame whose body count (at line index ``count_k``) disagrees with the bodies
    written after it; ``why`` may name ``{line}``, the first line that does not fit."""
    line = lines.numbers[lines.k]
    return lines.error(f"body count {n_bodies} is {why.format(line=line)}", count_k, frame)


def _body_line(lines: _Lines, frame: int) -> str:
    """Check a body line and return its bodyID."""
    lines.need(1, "a body line", frame)
    tokens = lines.texts[lines.k].split()
    if len(tokens) != BODY_FIELDS:
        raise lines.error(
            f"a body line has {BODY_FIELDS} values (bodyID clippedEdges handLeftConfidence handLeftState "
            f"handRightConfidence handRightState isRestricted leanX leanY trackingState), found {len(tokens)}",
            frame=frame,
        )
    if not tokens[0].isdecimal():
        raise lines.error(f"bodyID {tokens[0]!r} is not a non-negative integer", frame=frame)
    for t in tokens[1:]:
        try:
            float(t)
        except ValueError:
            raise lines.error(f"{t!r} is not a number", frame=frame) from None
    lines.k += 1
    return tokens[0]


def _parse_joints(lines: _Lines, starts: list[int], block_frames: list[int]) -> np.ndarray:
    """Parse every joint block (25 lines from each index in ``starts``) into [B, 25, 12] floats."""
    rows = [lines.texts[k + j].split() for k in starts for j in range(N_JOINTS)]

    def where(i: int) -> tuple[int, int]:
        return starts[i // N_JOINTS] + i % N_JOINTS, block_frames[i // N_JOINTS]

    for i, row in enumerate(rows):
        if len(row) != JOINT_FIELDS:
            k, f = where(i)
            raise lines.error(
                f"a joint line has {JOINT_FIELDS} values (x y z depthX depthY colorX colorY "
                f"orientationW orientationX orientationY orientationZ trackingState), found {len(row)}",
                k,
                f,
            )
    try:
        values = np.array(rows, dtype=np.float64).reshape(len(starts), N_JOINTS, JOINT_FIELDS)
    except ValueError:
        for i, row in enumerate(rows):
            for t in row:
                try:
                    float(t)
                except ValueError:
                    raise lines.error(f"{t!r} is not a number", *where(i)) from None
        raise FormatError(lines.path, "joint values cannot be read as numbers") from None
    finite = np.isfinite(values).all(axis=-1).reshape(-1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise lines.error("a value is not finite (NaN or infinity)", *where(i))
    return values


@register_reader(
    "ntu",
    extensions=(".skeleton",),
    sniff=_sniff,
    description="NTU RGB+D .skeleton text (Kinect v2, 25 joints, several bodies)",
)
def read_ntu(path: Path, *, body: str | None = None) -> Motion:
    """Read one body of an NTU RGB+D ``.skeleton`` file.

    Args:
        path: the ``.skeleton`` file.
        body: bodyID as written in the file; default the body present in the most frames.

    Returns:
        A Motion on the ``kinect_v2`` joint set: ``times`` [T] seconds = frame index / 30 (the
        format has no timestamps), ``positions`` [T, 25, 3] metres, ``orientations`` [T, 25, 4]
        (x, y, z, w), ``confidence`` [T, 25] (1.0 tracked, 0.5 inferred, 0.0 not tracked or body
        absent). ``metadata`` holds ``body``, ``bodies`` (id and frame count of each), and the
        setup/camera/performer/replication/action numbers when the file name has the NTU form.
    """
    path = Path(path)
    lines = _Lines(path)
    if not lines.texts:
        raise FormatError(path, "the file is empty", line=1)
    n_frames = lines.count("frame count")
    if n_frames == 0:
        raise lines.error("the frame count is 0: the file holds no frames", 0)
    if n_frames > lines.remaining():
        raise lines.error(
            f"the frame count {n_frames} is more than the {lines.remaining()} lines that follow could hold "
            "(truncated or corrupt file?)",
            0,
        )

    starts: list[int] = []  # first joint line of each body occurrence
    block_frames: list[int] = []
    block_ids: list[str] = []
    count_k, n_bodies = -1, 0  # the line index and value of the latest body count
    for f in range(n_frames):
        if f and _looks_like_body_line(lines):
            raise _miscounted(
                lines,
                count_k,
                n_bodies,
                f - 1,
                "fewer than the bodies that follow: line {line} holds "
                "a body line where the next frame's body count should be",
            )
        count_k = lines.k
        n_bodies = lines.count("body count", f)
        if n_bodies > MAX_BODIES:
            raise lines.error(f"body count {n_bodies} is more than Kinect v2's {MAX_BODIES}", lines.k - 1, f)
        seen: set[str] = set()
        for i in range(n_bodies):
            if _holds_a_count(lines):  # where body line i should be, the next frame begins
                got = "1 body that follows" if i == 1 else f"{i} bodies that follow"
                raise _miscounted(lines, count_k, n_bodies, f, f"more than the {got}: line {{line}} holds no body line")
            body_k = lines.k
            body_id = _body_line(lines, f)
            if body_id in seen:
                raise lines.error(f"bodyID {body_id} appears twice in this frame", body_k, f)
            seen.add(body_id)
            n_joints = lines.count("joint count", f)
            if n_joints != N_JOINTS:
                raise lines.error(f"joint count {n_joints}, expected {N_JOINTS} (Kinect v2)", lines.k - 1, f)
            lines.need(N_JOINTS, f"{N_JOINTS} joint lines", f)
            starts.append(lines.k)
            block_frames.append(f)
            block_ids.append(body_id)
            lines.k += N_JOINTS
    if n_frames and _looks_like_body_line(lines):
        raise _miscounted(
            lines, count_k, n_bodies, n_frames - 1, "fewer than the bodies that follow: line {line} holds a body line"
        )
    if lines.remaining():
        raise lines.error(f"unexpected content after the last of the {n_frames} frames the first line announces")

    values = _parse_joints(lines, starts, block_frames)

    bodies = count_bodies(block_ids)
    body = choose_body(path, bodies, body, n_frames=n_frames)

    chosen = np.array([i for i, b in enumerate(block_ids) if b == body])
    frames = np.array(block_frames)[chosen]
    block = values[chosen]  # [n, 25, 12]

    state = block[..., 11]
    bad = ~np.isin(state, (0.0, 1.0, 2.0))
    if bad.any():
        b, j = np.argwhere(bad)[0]
        raise lines.error(f"tracking state {state[b, j]:g} is not 0, 1 or 2", starts[chosen[b]] + j, int(frames[b]))
    with np.errstate(over="ignore"):  # the norm of huge values overflows to inf: not a unit quaternion
        unit, present, bad = split_missing_and_normalise(wxyz_to_xyzw(block[..., 7:11]))
    if bad.any():
        b, j = np.argwhere(bad)[0]
        norm = math.hypot(*block[b, j, 7:11])  # inf, not an overflow warning, for huge values
        raise lines.error(f"orientation quaternion has norm {norm:.4g}, not 1", starts[chosen[b]] + j, int(frames[b]))

    T = n_frames
    positions = np.full((T, N_JOINTS, 3), np.nan)
    positions[frames] = block[..., :3]
    position_mask = np.zeros((T, N_JOINTS), bool)
    position_mask[frames] = state > 0
    confidence = np.zeros((T, N_JOINTS), np.float32)
    confidence[frames] = _CONFIDENCE[state.astype(int)]
    orientations = np.full((T, N_JOINTS, 4), np.nan)
    orientations[frames] = unit
    orientation_mask = np.zeros((T, N_JOINTS), bool)
    orientation_mask[frames] = present & (state > 0)  # untracked joints' orientations are junk

    metadata: dict = {
        "format": "ntu",
        "time_origin": None,
        "time_source": "frame index at nominal 30 fps",
        "nominal_fps": NOMINAL_FPS,
        "body": body,
        "bodies": bodies,
    }
    match = _FILE_NAME.fullmatch(path.name.split(".")[0])
    if match:
        metadata.update({k: int(v) for k, v in zip(_NAME_FIELDS, match.groups(), strict=True)})
    return Motion(
        times=np.arange(T) / NOMINAL_FPS,
        positions=positions,
        joint_set=load_joint_set("kinect_v2"),
        position_mask=position_mask,
        confidence=confidence,
        orientations=orientations,
        orientation_mask=orientation_mask,
        metadata=metadata,
    )
