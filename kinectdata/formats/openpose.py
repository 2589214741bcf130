"""OpenPose ``--write_json`` output: 2-D body keypoints per video frame, read as the 15 MPI joints.

Inputs:

- a folder of per-frame files as OpenPose writes them, ``<video>_<frame:012d>_keypoints.json``,
  each ``{"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": [x, y, c, ...],
  "face_keypoints_2d": [], ...}]}``. The frame number is the last digit group before
  ``_keypoints``; files are ordered by it (numerically) and gaps in it are missing frames;
- one file holding such frame documents: a JSON array of them, an object with a ``"frames"``
  array, JSON Lines (one document per line; ``.jsonl``, or a ``.json`` holding several
  documents), or a single document. A document's frame number is its ``frame``,
  ``frame_index`` or ``frame_id`` key when present, else its position in the file (for a single
  document: the number in an OpenPose file name, else 0).

A frame document with no people is a frame where nobody was seen. The format has no timestamps:
``times`` [T] = (frame number - first frame number) / ``video_fps`` seconds; frame numbers are
below 2**53, where float64 still tells consecutive frames apart.

Layouts, detected from the keypoint count (75, 54 or 45 values) or forced with ``layout=``, and
their mapping to the joint set ``openpose_mpi`` (index = keypoint index in ``pose_keypoints_2d``)::

    MPI joint  body25 (BODY_25)         coco18 (COCO-18)                       mpi15 (MPI-15)
    Head       0 Nose                   0 Nose                                 0 Head
    Neck       1 Neck                   1 Neck                                 1 Neck
    RShoulder  2                        2                                      2
    RElbow     3                        3                                      3
    RWrist     4                        4                                      4
    LShoulder  5                        5                                      5
    LElbow     6                        6                                      6
    LWrist     7                        7                                      7
    RHip       9                        8                                      8
    RKnee      10                       9                                      9
    RAnkle     11                       10                                     10
    LHip       12                       11                                     11
    LKnee      13                       12                                     12
    LAnkle     14                       13                                     13
    Chest      (1 Neck + 8 MidHip) / 2  (1 Neck + (8 RHip + 11 LHip) / 2) / 2  14 Chest

BODY_25 and COCO have no head top: Head is the Nose (a few centimetres lower and forward of
MPI's head top). They have no chest: Chest is the midpoint of the Neck and the hip centre, valid
only where every keypoint it uses is, with the smallest of their confidences. The eyes, ears and
feet (BODY_25 15-24, COCO 14-17) are not used.

Values: positions [T, 15, 2] are pixels as written, in image axes (x right, y down), not
flipped; OpenPose's ``c`` (0..1) becomes ``confidence``; ``c == 0`` (OpenPose writes ``0, 0, 0``
for a keypoint it did not find) masks the joint. Real OpenPose output holds confidences a little
above 1 (up to about 1.4): they are clipped to 1 and counted (``metadata["confidences_clipped"]``,
of the person read), so ``info`` shows them; above :data:`MAX_CONFIDENCE` the file is refused.
Nothing is interpolated here: alignment fills
gaps up to its ``max_gap`` later.

Several people: one person per Motion. When OpenPose wrote ids (``person_id`` other than -1)
they are the tracks. Otherwise detections are tracked (:func:`track_people`): each frame's
detections are matched to the live tracks by :func:`scipy.optimize.linear_sum_assignment` on
the mean distance between their joints, in units of the track's body size; matches costing more
than :data:`MAX_MATCH_COST` are refused, a track unseen for more than :data:`TRACK_TIMEOUT_S`
seconds ends, and unmatched detections start new tracks, numbered "0", "1"... in order of first
appearance. The person read is ``person=`` or, by default, the track present in the most frames
(ties: the first). Frames where it is absent stay, fully masked.

Errors name the file (for a folder, the frame's own file), the frame number (``frame``), the
line for JSON syntax errors and JSON Lines, and the person as ``people[i]``.
"""

from __future__ import annotations

import json
import os
import re
import statistics
from array import array
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.formats.common import choose_body, count_bodies, read_text
from kinectdata.formats.registry import register_reader

KEYPOINTS_SUFFIX = "_keypoints.json"
FRAME_KEYS = ("frame", "frame_index", "frame_id")
MAX_MATCH_COST = 0.3
"""Largest mean joint distance, in body sizes (bounding-box diagonal of the valid joints), between
a detection and the track it continues. A dancer's joints move a few hundredths of a body size per
video frame; two people's joints are rarely closer than half a body size on average."""
TRACK_TIMEOUT_S = 1.0
"""A track whose last detection is more than this many seconds before the current frame ends."""
SIZE_HISTORY = 30
"""A track's body size is the median over its last this many detections."""
MAX_FRAME_NUMBER = 2**53
"""Frame numbers are below this: beyond it float64 times would merge consecutive frames."""


@dataclass(frozen=True)
class Layout:
    """An OpenPose body layout and how its keypoints give the 15 MPI joints.

    ``sources`` are the keypoint indices of the MPI joints Head ... LAnkle (joint-set order, all
    but the last); Chest is ``sum(weight * keypoint)`` over ``chest`` (index, weight) pairs.
    """

    name: str
    title: str
    n_keypoints: int
    sources: tuple[int, ...]
    chest: tuple[tuple[int, float], ...]


LAYOUTS = {
    "body25": Layout("body25", "BODY_25", 25, (0, 1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13, 14), ((1, 0.5), (8, 0.5))),
    "coco18": Layout(
        "coco18", "COCO-18", 18, (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13), ((1, 0.5), (8, 0.25), (11, 0.25))
    ),
    "mpi15": Layout("mpi15", "MPI-15", 15, tuple(range(14)), ((14, 1.0),)),
}
_BY_VALUES = {3 * lay.n_keypoints: lay for lay in LAYOUTS.values()}
_KNOWN = "25 (BODY_25), 18 (COCO-18) or 15 (MPI-15)"
_FILE_NUMBER = re.compile(r"(\d+)\D*" + re.escape(KEYPOINTS_SUFFIX) + "$")


@dataclass
class _Frame:
    """One frame document: its frame number, its ``people`` list and where it is (for errors)."""

    number: int
    people: list
    where: dict[str, Any]  # FormatError(**where, ...): path, frame and, in JSON Lines, line


def to_mpi15(keypoints: np.ndarray, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """The 15 MPI joints of OpenPose detections.

    Args:
        keypoints: [n, K, 3] (x, y, c) per keypoint of ``layout``; c == 0 means not detected.
        layout: the keypoints' layout.

    Returns:
        ``positions`` [n, 15, 2] (NaN where not detected) and ``confidence`` [n, 15] float32
        (0 where not detected), in joint-set order (Head, Neck, ..., LAnkle, Chest).
    """
    idx = [i for i, _ in layout.chest]
    weights = np.array([w for _, w in layout.chest])
    positions = np.empty((keypoints.shape[0], 15, 2))
    confidence = np.empty((keypoints.shape[0], 15))
    positions[:, :14] = keypoints[:, layout.sources, :2]
    confidence[:, :14] = keypoints[:, layout.sources, 2]
    positions[:, 14] = np.einsum("nkd,k->nd", keypoints[:, idx, :2], weights)
    confidence[:, 14] = keypoints[:, idx, 2].min(axis=1)
    positions[confidence == 0] = np.nan
    return positions, confidence.astype(np.float32)


def body_sizes(positions: np.ndarray) -> np.ndarray:
    """[n] bounding-box diagonal (pixels) of each detection's valid joints; NaN with fewer than 2.

    ``positions`` [n, J, 2] with NaN for missing joints.
    """
    valid = np.isfinite(positions).all(axis=-1)
    low = np.where(valid[..., None], positions, np.inf).min(axis=1)
    high = np.where(valid[..., None], positions, -np.inf).max(axis=1)
    with np.errstate(invalid="ignore"):
        diagonal = np.hypot(*(high - low).T)
    return np.where(valid.sum(axis=1) >= 2, diagonal, np.nan)


def _match_cost(det: np.ndarray, tracks: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """[D, L] mean distance over joints valid in both, divided by the track's size (inf if none)."""
    with np.errstate(over="ignore"):  # beyond float64 (coordinates near 1e308): inf, left out like NaN
        dist = np.linalg.norm(det[:, None] - tracks[None], axis=-1)  # [D, L, J], NaN where either is missing
    common = np.isfinite(dist)
    n = common.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cost = np.where(common, dist, 0.0).sum(axis=-1) / n / sizes[None]
    return np.where((n > 0) & np.isfinite(cost), cost, np.inf)


def track_people(
    frame_numbers: np.ndarray,
    positions: np.ndarray,
    *,
    max_gap_frames: float,
    max_cost: float = MAX_MATCH_COST,
) -> np.ndarray:
    """Follow people across frames: the track index of each detection.

    Each frame's detections are assigned to live tracks by ``linear_sum_assignment`` on
    :func:`_match_cost` (mean joint distance to the track's last detection over the joints valid
    in both, divided by the median :func:`body_sizes` of its last :data:`SIZE_HISTORY`
    detections). Assignments costing more than ``max_cost`` are refused; a track whose last
    detection is more than ``max_gap_frames`` frame numbers back ends; detections left over start
    new tracks, numbered from 0 in order of first appearance (in a frame, in detection order).

    Args:
        frame_numbers: [n] frame number of each detection, non-decreasing.
        positions: [n, J, 2] pixels, NaN for joints not detected.
        max_gap_frames: frame numbers a track may go unseen.
        max_cost: largest accepted cost, in body sizes.

    Returns:
        [n] int track index per detection.
    """
    from scipy.optimize import linear_sum_assignment  # here: scipy.optimize is slow to import

    n = len(frame_numbers)
    track = np.full(n, -1)
    if n == 0:
        return track
    sizes = body_sizes(positions)
    last: list[int] = []  # per track: its last detection
    history: list[list[float]] = []  # per track: its recent body sizes
    live: list[int] = []
    bounds = np.flatnonzero(np.r_[True, np.diff(frame_numbers) != 0, True])
    for a, b in zip(bounds[:-1], bounds[1:]):
        frame = frame_numbers[a]
        live = [t for t in live if frame - frame_numbers[last[t]] <= max_gap_frames]
        matched: dict[int, int] = {}  # detection -> track
        if live:
            scale = np.array([statistics.median(history[t]) if history[t] else np.nan for t in live])
            cost = _match_cost(positions[a:b], positions[[last[t] for t in live]], scale)
            rows, cols = linear_sum_assignment(np.where(np.isfinite(cost), cost, 1e12))
            matched = {a + r: live[c] for r, c in zip(rows, cols) if cost[r, c] <= max_cost}
        for d in range(a, b):
            t = matched.get(d)
            if t is None:
                t = len(last)
                last.append(d)
                history.append([])
                live.append(t)
            track[d] = t
            last[t] = d
            if np.isfinite(sizes[d]):
                history[t] = (history[t] + [float(sizes[d])])[-SIZE_HISTORY:]
    return track


# -- reading ------------------------------------------------------------------------------------


def _sniff(path: Path, head: bytes) -> bool:
    """True for a folder holding ``*_keypoints.json`` files, or JSON whose head shows OpenPose's keys."""
    if path.is_dir():
        with os.scandir(path) as entries:
            return any(e.name.endswith(KEYPOINTS_SUFFIX) for e in entries)
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff \t\r\n")
    if not text.startswith(("{", "[")) or '"k4abt_sdk_version"' in text or '"joint_positions"' in text:
        return False
    return '"pose_keypoints_2d"' in text or re.search(r'"people"\s*:\s*\[', text) is not None


def _json_error(path: Path, exc: ValueError | RecursionError, line: int | None = None) -> FormatError:
    if isinstance(exc, json.JSONDecodeError):
        return FormatError(path, f"invalid JSON: {exc.msg} (column {exc.colno})", line=line or exc.lineno)
    if isinstance(exc, RecursionError):
        return FormatError(path, "invalid JSON: nested too deeply", line=line)
    return FormatError(path, f"invalid JSON: {exc}", line=line)  # e.g. an integer beyond Python's digit limit


def _loads(path: Path, text: str, line: int | None = None) -> Any:
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise _json_error(path, exc, line) from None


def _is_document(line: str) -> bool:
    try:
        return isinstance(json.loads(line), dict)
    except (ValueError, RecursionError):
        return False


def _number_in_name(path: Path) -> int | None:
    match = _FILE_NUMBER.search(path.name)
    if match is None:
        return None
    digits = match.group(1).lstrip("0") or "0"
    if len(digits) > 16 or int(digits) >= MAX_FRAME_NUMBER:
        raise FormatError(path, f"the frame number in the file name is beyond 2**53: {_show(match.group(1))}")
    return int(digits)


def _show(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _frame(doc: Any, number: int, where: dict[str, Any]) -> _Frame:
    """Check a frame document and return it as a :class:`_Frame`."""
    if not isinstance(doc, dict):
        raise FormatError(**where, message=f"a frame must be a JSON object with 'people', found {type(doc).__name__}")
    people = doc.get("people")
    if not isinstance(people, list):
        found = "no 'people' key" if people is None else f"'people' is {type(people).__name__}"
        raise FormatError(**where, message=f"a frame document needs a 'people' list, {found}")
    return _Frame(number, people, where)


def _explicit_number(doc: Any, where: dict[str, Any]) -> int | None:
    """The document's frame/frame_index/frame_id value (None when it has none)."""
    if not isinstance(doc, dict):
        return None
    for key in FRAME_KEYS:
        if key in doc:
            value = doc[key]
            if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < MAX_FRAME_NUMBER:
                message = f"'{key}' must be a non-negative integer below 2**53, found {_show(value)}"
                raise FormatError(**where, message=message)
            return value
    return None


def _read_folder(folder: Path) -> list[_Frame]:
    with os.scandir(folder) as entries:
        files = [Path(e.path) for e in entries if e.name.endswith(KEYPOINTS_SUFFIX) and e.is_file()]
    if not files:
        raise FormatError(folder, f"no *{KEYPOINTS_SUFFIX} files (OpenPose --write_json output) in this folder")
    numbered = []
    for f in files:
        number = _number_in_name(f)
        if number is None:
            raise FormatError(f, "no frame number in the file name (expected <video>_<frame>_keypoints.json)")
        numbered.append((number, f))
    numbered.sort()
    for (n0, f0), (n1, f1) in zip(numbered, numbered[1:]):
        if n0 == n1:
            raise FormatError(f1, f"frame number {n1} also in {f0.name}: two files for one frame")
    frames = []
    for number, f in numbered:
        text = read_text(f, fallback_encoding=None)
        if not text.strip():
            raise FormatError(f, "the file is empty", line=1)
        frames.append(_frame(_loads(f, text), number, {"path": f, "frame": number}))
    return frames


def _read_file(path: Path) -> list[_Frame]:
    text = read_text(path, fallback_encoding=None)
    if not text.strip():
        raise FormatError(path, "the file is empty", line=1)
    if path.suffix.lower() != ".jsonl":
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            if exc.msg != "Extra data" or not _is_document(text.lstrip().split("\n", 1)[0]):
                raise _json_error(path, exc) from None
            # several documents, the first on its own line: JSON Lines
        except (ValueError, RecursionError) as exc:
            raise _json_error(path, exc) from None
        else:
            return _documents(path, doc)
    lines = [(i, s) for i, s in enumerate(text.splitlines(), 1) if s.strip()]
    docs = [_loads(path, s, line=i) for i, s in lines]
    return _numbered(path, docs, [{"line": i} for i, _ in lines])


def _documents(path: Path, doc: Any) -> list[_Frame]:
    """The frames of a parsed single JSON file: an array, an object with 'frames', or one document."""
    if isinstance(doc, dict) and "frames" in doc:
        doc = doc["frames"]
        if not isinstance(doc, list):
            raise FormatError(path, f"'frames' must be a list of frame documents, found {type(doc).__name__}")
    elif isinstance(doc, dict) and "people" in doc:
        number = _explicit_number(doc, {"path": path})
        if number is None:
            number = _number_in_name(path) or 0
        return [_frame(doc, number, {"path": path, "frame": number})]
    elif not isinstance(doc, list):
        raise FormatError(
            path,
            "not OpenPose output: expected a frame document with 'people', a list of them, or an object with "
            "a 'frames' list",
        )
    return _numbered(path, doc, [{} for _ in doc])


def _numbered(path: Path, docs: list, places: list[dict[str, Any]]) -> list[_Frame]:
    """Frames from documents in file order: number from their key, else their position; sorted."""
    if not docs:
        raise FormatError(path, "the file holds no frames")
    frames = []
    for k, (doc, place) in enumerate(zip(docs, places)):
        number = _explicit_number(doc, {"path": path, "frame": k, **place})
        number = k if number is None else number
        frames.append(_frame(doc, number, {"path": path, "frame": number, **place}))
    frames.sort(key=lambda f: f.number)
    for a, b in zip(frames, frames[1:]):
        if a.number == b.number:
            raise FormatError(**b.where, message=f"frame number {b.number} appears twice in the file")
    return frames


def _person_id(person: dict, where: dict[str, Any], k: int) -> int:
    pid = person.get("person_id", -1)  # OpenPose before 1.3 writes no person_id
    if isinstance(pid, list) and len(pid) == 1:
        pid = pid[0]
    if not isinstance(pid, int) or isinstance(pid, bool) or not -(2**63) <= pid < 2**63:
        message = f"people[{k}].person_id must be [integer] (64-bit) as OpenPose writes it, found {_show(pid)}"
        raise FormatError(**where, message=message)
    return pid


def _first_non_number(values: list) -> Any:
    for v in values:
        try:
            array("d", [v])
        except (TypeError, OverflowError):
            return v
    return None


def _layout_mismatch(k: int, n_values: int, layout: Layout, forced: bool) -> str:
    other = _BY_VALUES.get(n_values)
    found = f"people[{k}].pose_keypoints_2d has {n_values} values" + (f" ({other.title})" if other else "")
    expected = f"{3 * layout.n_keypoints} ({layout.title})"
    if forced:
        return f"{found}; expected {expected} for layout={layout.name!r}"
    return f"{found} but earlier people have {expected}" + (": mixed layouts" if other else "")


MAX_CONFIDENCE = 2.0
"""Confidences above 1 (OpenPose writes up to about 1.4) are clipped to 1 and counted; above this,
the values are not confidences."""


def _detections(frames: list[_Frame], forced: Layout | None):
    """Every person of every frame: frame row [n], person_id [n], keypoints [n, K, 3], layout, places."""
    layout = forced
    rows: list[int] = []
    ids: list[int] = []
    buffers: list[array] = []
    places: list[tuple[dict[str, Any], int]] = []  # (where, index in people) of each detection
    for row, fr in enumerate(frames):
        for k, person in enumerate(fr.people):
            kp = person.get("pose_keypoints_2d") if isinstance(person, dict) else None
            if kp is None and isinstance(person, dict) and "pose_keypoints" in person:
                message = (
                    f"people[{k}] has 'pose_keypoints', the key of OpenPose before 1.2 (2017), which kinectdata "
                    "does not read; OpenPose 1.2 and later write 'pose_keypoints_2d' (rename the key if the layout "
                    "is the same)"
                )
                raise FormatError(**fr.where, message=message)
            if not isinstance(kp, list):
                raise FormatError(**fr.where, message=f"people[{k}] must be an object with a 'pose_keypoints_2d' list")
            try:
                values = array("d", kp)  # converts and type-checks in C
            except (TypeError, OverflowError):
                message = f"people[{k}].pose_keypoints_2d must hold numbers, found {_show(_first_non_number(kp))}"
                raise FormatError(**fr.where, message=message) from None
            if layout is None:
                layout = _BY_VALUES.get(len(values))
                if layout is None:
                    message = (
                        f"people[{k}].pose_keypoints_2d has {len(values)} values, not x, y, c for {_KNOWN} keypoints"
                    )
                    raise FormatError(**fr.where, message=message)
            elif len(values) != 3 * layout.n_keypoints:
                raise FormatError(**fr.where, message=_layout_mismatch(k, len(values), layout, forced is not None))
            rows.append(row)
            ids.append(_person_id(person, fr.where, k))
            buffers.append(values)
            places.append((fr.where, k))
    K = layout.n_keypoints if layout else 0
    keypoints = np.frombuffer(b"".join(buffers), dtype=np.float64).reshape(len(buffers), K, 3)
    return np.array(rows, dtype=int), np.array(ids, dtype=int), keypoints, layout, places


def _check_values(keypoints: np.ndarray, places: list[tuple[dict[str, Any], int]]) -> None:
    finite = np.isfinite(keypoints).all(axis=-1)
    if not finite.all():
        d, j = np.argwhere(~finite)[0]
        where, k = places[d]
        raise FormatError(
            **where, message=f"people[{k}].pose_keypoints_2d keypoint {j} is not finite: {keypoints[d, j]}"
        )
    c = keypoints[..., 2]
    bad = (c < 0) | (c > MAX_CONFIDENCE)
    if bad.any():
        d, j = np.argwhere(bad)[0]
        where, k = places[d]
        message = (
            f"people[{k}].pose_keypoints_2d keypoint {j} has confidence {c[d, j]:g}, outside 0..{MAX_CONFIDENCE:g} "
            "(OpenPose writes 0..1, at times a little above 1): is the file x, y, c triples?"
        )
        raise FormatError(**where, message=message)


def _track_ids(
    pids: np.ndarray, rows: np.ndarray, numbers: np.ndarray, positions: np.ndarray, places: list, fps: float
) -> tuple[list[str], str]:
    """Track id of each detection, and how they were found: OpenPose's person_id when written, else
    :func:`track_people`."""
    written = pids != -1
    if written.all():
        order = np.lexsort((pids, rows))
        twice = (np.diff(rows[order]) == 0) & (np.diff(pids[order]) == 0)
        if twice.any():
            i = int(np.argmax(twice))
            where, k = places[max(order[i], order[i + 1])]
            raise FormatError(**where, message=f"people[{k}].person_id {pids[order[i]]} appears twice in this frame")
        return [str(p) for p in pids], "person_id as written by OpenPose"
    if written.any():
        where, k = places[int(np.argmin(written))]
        message = f"people[{k}].person_id is -1 while other people carry OpenPose ids: ids must be all or none"
        raise FormatError(**where, message=message)
    tracks = track_people(numbers[rows], positions, max_gap_frames=TRACK_TIMEOUT_S * fps)
    return [str(t) for t in tracks], f"tracked (max cost {MAX_MATCH_COST} body sizes, timeout {TRACK_TIMEOUT_S} s)"


@register_reader(
    "openpose",
    extensions=(".jsonl",),
    sniff=_sniff,
    description="OpenPose --write_json keypoints (a folder of *_keypoints.json, or one .json/.jsonl), 2-D",
)
def read_openpose(
    path: Path, *, video_fps: float | None = None, person: str | None = None, layout: str | None = None
) -> Motion:
    """Read one person of OpenPose ``--write_json`` output as the 15 MPI joints.

    Args:
        path: a folder of ``*_keypoints.json`` files, or one ``.json`` / ``.jsonl`` file of frames.
        video_fps: the video's frame rate (frames per second); required, OpenPose writes no times.
        person: track id ("0", "1"... or OpenPose's person_id); default the track in most frames.
        layout: ``"body25"``, ``"coco18"`` or ``"mpi15"``; default detected from the keypoint count.

    Returns:
        A Motion on ``openpose_mpi``: ``times`` [T] seconds from the first frame, ``positions``
        [T, 15, 2] pixels as written (x right, y down), ``confidence`` [T, 15] (OpenPose's c; 0
        where not detected or the person is absent). ``metadata`` holds ``time_origin`` (first
        frame number), ``video_fps``, ``layout``, ``person``, ``people`` (track id -> frames
        present), ``person_ids`` (how tracks were found) and ``source``.
    """
    path = Path(path)
    if video_fps is None:
        raise FormatError(
            path,
            "OpenPose output has no timestamps: pass the video's frame rate (video_fps=, --video-fps on the "
            "command line)",
        )
    try:
        fps = float(video_fps)
    except (TypeError, ValueError):
        fps = float("nan")
    if not np.isfinite(fps) or fps <= 0:
        raise FormatError(path, f"video_fps must be a positive number of frames per second, got {video_fps!r}")
    forced = None
    if layout is not None:
        if layout not in LAYOUTS:
            raise FormatError(path, f"unknown layout {layout!r} (known: {', '.join(LAYOUTS)})")
        forced = LAYOUTS[layout]

    frames = _read_folder(path) if path.is_dir() else _read_file(path)
    numbers = np.array([f.number for f in frames])
    rows, pids, keypoints, found, places = _detections(frames, forced)
    _check_values(keypoints, places)
    T = len(frames)
    if found is None:  # nobody in any frame
        choose_body(path, {}, person, n_frames=T)
    above_one = keypoints[..., 2] > 1
    if above_one.any():
        keypoints = keypoints.copy()
        keypoints[..., 2] = np.minimum(keypoints[..., 2], 1.0)
    det_positions, det_confidence = to_mpi15(keypoints, found)
    ids, how = _track_ids(pids, rows, numbers, det_positions, places, fps)
    people = count_bodies(ids)
    chosen_id = choose_body(path, people, person, n_frames=T)
    chosen = np.array([i == chosen_id for i in ids])

    positions = np.full((T, 15, 2), np.nan)
    confidence = np.zeros((T, 15), np.float32)
    positions[rows[chosen]] = det_positions[chosen]
    confidence[rows[chosen]] = det_confidence[chosen]
    return Motion(
        times=(numbers - numbers[0]) / fps,
        positions=positions,
        joint_set=load_joint_set("openpose_mpi"),
        position_mask=confidence > 0,
        confidence=confidence,
        metadata={
            "format": "openpose",
            "time_origin": {"value": int(numbers[0]), "unit": "frame"},
            "time_source": "frame number / video_fps",
            "video_fps": fps,
            "axes": "image pixels as written: x right, y down",
            "layout": found.name,
            "person": chosen_id,
            "people": people,
            "person_ids": how,
            "confidences_clipped": int(above_one[chosen].sum()),
            "source": str(path),
        },
    )
