"""Pieces every reader needs: reading a text file, choosing one body among several, checking times."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from kinectdata.core.errors import FormatError

UNITS_TO_M = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
"""Length units a file may state or be declared in (BVH, joint arrays), to metres."""


def read_text(path: Path, *, fallback_encoding: str | None = "cp1252") -> str:
    """The text of a file: UTF-8 (a byte-order mark is dropped), else ``fallback_encoding``.

    Windows tools often write cp1252; for numeric files that is harmless. With
    ``fallback_encoding=None`` a file that is not UTF-8 is a FormatError (a binary file given by
    mistake). Unreadable files are FormatErrors too.
    """
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise FormatError(path, f"cannot read file: {exc.strerror or exc}") from exc
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if fallback_encoding is None:
            raise FormatError(path, f"not a UTF-8 text file (byte {exc.start})") from exc
        return raw.decode(fallback_encoding, errors="replace")


def count_bodies(frame_body_ids: Iterable[str]) -> dict[str, int]:
    """Frames per body id, in order of first appearance, from one id per (frame, body) pair."""
    return dict(Counter(frame_body_ids))


def choose_body(path: Path, frames_per_body: dict[str, int], body: str | None, *, n_frames: int, **where) -> str:
    """The body to read: ``body`` (an id as written in the file) or, by default, the body present
    in the most frames, the first to appear winning ties.

    ``n_frames`` is the file's frame count; ``where`` (line=, column=...) locates the body ids
    for the error message.
    """
    if not frames_per_body:
        raise FormatError(path, f"no body appears in any of the {n_frames} frames", **where)
    if body is None:
        return max(frames_per_body, key=frames_per_body.__getitem__)  # max keeps the first of equals
    body = str(body)
    if body not in frames_per_body:
        listing = ", ".join(f"{b} ({n} frames)" for b, n in frames_per_body.items())
        raise FormatError(path, f"no body with id {body!r}; the file has: {listing}", **where)
    return body


def first_bad_time(times: np.ndarray) -> int | None:
    """Index of the first of ``times`` [T] (seconds from the first frame) that is not finite or
    not after the one before, else None.

    A file's timestamps can each be valid and still not make usable times: counted from a
    damaged first stamp, or over a huge span, float64 overflows or merges neighbouring frames.
    """
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(times)
        bad[1:] |= ~(np.diff(times) > 0)
    return int(np.argmax(bad)) if bad.any() else None


def brief(exc: BaseException, limit: int = 200) -> str:
    """``Type: message`` of a library's exception, cut to ``limit`` characters (a damaged file's
    bytes can fill a message)."""
    text = f"{type(exc).__name__}: {exc}"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def load_numpy(path: Path, what: str = "numpy arrays") -> np.ndarray | dict[str, np.ndarray]:
    """The array of an ``.npy`` file or the arrays of an ``.npz`` (by name), never unpickling.

    A damaged file is a FormatError naming it, whichever way numpy fails on it: a header that does
    not parse (numpy evaluates it as a Python literal), a zip that is not one, data shorter than the
    header declares, or a declared size larger than memory.
    """
    import tokenize
    import zipfile

    try:
        if path.suffix.lower() == ".npz":
            with np.load(path) as archive:
                return {name: archive[name] for name in archive.files}
        return np.load(path)
    except MemoryError:
        raise FormatError(path, f"declares {what} larger than memory can hold (a damaged header?)") from None
    except OSError as exc:  # also a zip member whose offset lies past the file's end
        raise FormatError(path, f"cannot read it as {what} ({exc.strerror or exc})") from None
    except (ValueError, EOFError, SyntaxError, tokenize.TokenError, zipfile.BadZipFile, KeyError) as exc:
        # ValueError: an object array (a pickle), a bad header or too little data; KeyError: a zip
        # member named in the directory but missing
        raise FormatError(path, f"cannot read it as {what} ({brief(exc)})") from None


UP_TO_Y = {  # rows: the new (x, y, z) from the file's (x, y, z), a rotation about x
    "y": np.eye(3),
    "z": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
    "-y": np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]]),
    "-z": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
}
"""The rotation that turns a file's up axis into kinectdata's y (z up: (x, y, z) -> (x, z, -y))."""


def to_kinectdata_axes(
    positions: np.ndarray, orientations: np.ndarray | None = None, *, up: str = "y", handedness: str = "right"
) -> tuple[np.ndarray, np.ndarray | None]:
    """Positions [..., 3] and orientations [..., 4] (unit quaternions x, y, z, w; NaN kept) from a
    file's axes to kinectdata's: right-handed, y up. ``handedness="left"`` (Unity, Unreal) negates x
    first: a mirror, so each rotation's axis is mirrored and its angle reversed, (x, y, z, w) ->
    (x, -y, -z, w); then the up axis is turned onto y by :data:`UP_TO_Y`, which turns each
    orientation too (R -> U R, the joint's frame seen from the new axes)."""
    if handedness == "left":
        positions = positions * np.array([-1.0, 1.0, 1.0])
        if orientations is not None:
            orientations = orientations * np.array([1.0, -1.0, -1.0, 1.0])
    if up != "y":
        turn = UP_TO_Y[up]
        positions = positions @ turn.T
        if orientations is not None:
            from scipy.spatial.transform import Rotation  # here: scipy.spatial costs 0.2 s at start-up

            valid = np.isfinite(orientations).all(axis=-1)
            turned = np.full_like(orientations, np.nan)
            turned[valid] = (Rotation.from_matrix(turn) * Rotation.from_quat(orientations[valid])).as_quat()
            orientations = turned
    return positions, orientations
