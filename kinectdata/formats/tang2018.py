"""The Dance with Melody corpus (Tang, Jia, Mao 2018): ``DANCE_<style>_<n>/skeletons.json`` with the
``config.json`` beside it.

What the reader relies on (github.com/mhy12345/Music-to-Dance-Motion-Synthesis at commit 82ae014,
its Readme.md and utils/draw.py, and measurements on its data, docs/corpora.md):

- ``skeletons.json`` is an object: ``skeletons`` [T][23][3], each point relative to ``center``
  [T][3] (the pelvis: world = skeletons + center), and ``length`` (T). Centimetres, y up.
- ``config.json`` gives ``start_position`` and ``end_position``: where the dance lies in its song,
  in song frames at 25 per second. The T motion frames are spread evenly over that span, so each
  dance has its own rate, 25 T / (end - start) (24.45 to 24.98 fps in the corpus; taking 25 fps
  drifts a 60-s dance by about a beat against its music). Frame k lies at k / rate seconds of
  motion, ``start_position / 25 + k / rate`` seconds of the song: audio_time = motion_time +
  start_position / 25, the offset the ``tang2018`` recipe writes.
- The joint set ``tang2018``: the 23 points in the file's order, then the pelvis (the ``center``
  track) and the neck (the midpoint of the shoulders, where draw.py joins head, arms and spine).

The corpus has no licence: kinectdata ships none of its files or values; the reader reads a local
copy.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from kinectdata.core.errors import FormatError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.formats.registry import register_reader

SONG_FPS = 25.0
"""``config.json``'s positions count song frames at this rate."""
POINTS = 23
CENTIMETRE = 0.01
SHOULDERS = (3, 12)
"""The points whose midpoint is the neck."""
CONFIG = "config.json"


def _sniff(path: Path, head: bytes) -> bool:
    text = b"".join(head.removeprefix(b"\xef\xbb\xbf")[:256].split())  # as the corpus writes it, or indented
    return text.startswith(b'{"length":') and b'"center"' in text


def _show(value: object, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _json(path: Path, what: str):
    """The JSON document of a file (UTF-8 with or without a byte-order mark, UTF-16 or 32), or one
    FormatError line saying why it is none."""
    try:
        return json.loads(path.read_bytes())
    except FileNotFoundError:
        if what == CONFIG:
            raise FormatError(path, "missing: the dance's start and end in its song are in config.json") from None
        raise FormatError(path, "cannot read file: No such file or directory") from None
    except OSError as exc:
        raise FormatError(path, f"cannot read file: {exc.strerror or exc}") from None
    except RecursionError:
        raise FormatError(path, f"nested too deeply to be a {what}") from None
    except ValueError as exc:  # JSON and Unicode errors, an integer longer than Python's digit limit
        raise FormatError(path, f"not JSON ({exc})") from None


def read_config(path: Path) -> tuple[int, int]:
    """(start_position, end_position) from a dance's ``config.json``: song frames at 25 per second."""
    doc = _json(path, "config.json")
    positions = []
    for key in ("start_position", "end_position"):
        value = doc.get(key) if isinstance(doc, dict) else None
        # compared, not converted: an integer beyond float64 is refused, not an OverflowError
        if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value < 2**53:
            raise FormatError(path, f"{key} must be a song frame (a number from 0 to 2**53), not {_show(value)}")
        positions.append(int(value))
    start, end = positions
    if end <= start:
        raise FormatError(path, f"end_position {end} is not after start_position {start}")
    return start, end


def _array(path: Path, doc: dict, key: str, shape: tuple[int, ...]) -> np.ndarray:
    """``doc[key]`` as float64 of ``shape`` (-1: any length), or FormatError naming the first bad frame."""
    if key not in doc:
        raise FormatError(path, f"no {key!r} key (a Dance with Melody skeletons.json has length, center, skeletons)")
    value = doc[key]
    if not isinstance(value, list):
        raise FormatError(path, f"{key!r} must be a list of frames, not {type(value).__name__}")
    if not value:
        return np.empty((0, *shape[1:]))
    try:
        return _frames(value, shape)
    except (TypeError, ValueError, OverflowError):
        pass
    for k, frame in enumerate(value):  # locate the first frame that is not of the shape
        try:
            _frames([frame], shape)
        except (TypeError, ValueError, OverflowError):
            raise FormatError(path, f"{key!r} is not {list(shape[1:])} numbers here", frame=k) from None
    raise FormatError(path, f"{key!r} cannot be read as numbers")


def _frames(value: list, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != len(shape) or arr.shape[1:] != shape[1:]:
        raise ValueError(f"shape {arr.shape}")
    return arr


@register_reader(
    "tang2018",
    extensions=(),  # sniffed: other readers' files end in .json too (OpenPose, Azure Kinect)
    sniff=_sniff,
    description="Dance with Melody skeletons.json (23 points + center, cm), its config.json beside it",
)
def read_tang2018(path: Path) -> Motion:
    """Read a Dance with Melody dance (see the module docstring).

    Args:
        path: the dance's ``skeletons.json``; its ``config.json`` must lie beside it.

    Returns:
        A Motion of joint set ``tang2018``: positions [T, 25, 3] in metres, y up, at the dance's own
        rate (``metadata["nominal_fps"]``); ``metadata["song_start_s"]`` is the song time of frame 0.
        A frame whose value is not finite is invalid for that point (and the pelvis or neck that
        depend on it).
    """
    path = Path(path)
    start, end = read_config(path.with_name(CONFIG))
    doc = _json(path, "skeletons.json")
    if not isinstance(doc, dict):
        raise FormatError(path, f"a {type(doc).__name__}; a Dance with Melody skeletons.json is an object")
    points = _array(path, doc, "skeletons", (-1, POINTS, 3))
    center = _array(path, doc, "center", (-1, 3))
    frames = len(points)
    if len(center) != frames:
        raise FormatError(path, f"{len(center)} center frames for {frames} skeleton frames")
    declared = doc.get("length")
    if declared is not None and declared != frames:
        raise FormatError(path, f"length says {_show(declared)} frames, the file holds {frames}")
    if frames < 2:
        raise FormatError(path, f"{frames} frame(s); a dance has at least 2")
    rate = SONG_FPS * frames / (end - start)
    with np.errstate(invalid="ignore", over="ignore"):
        world = (points + center[:, None, :]) * CENTIMETRE
        pelvis = center * CENTIMETRE
        neck = world[:, SHOULDERS].mean(axis=1)
    positions = np.concatenate([world, pelvis[:, None], neck[:, None]], axis=1)
    valid = np.isfinite(positions).all(axis=2)
    return Motion(
        times=np.arange(frames) / rate,
        positions=np.where(valid[..., None], positions, np.nan),
        joint_set=load_joint_set("tang2018"),
        position_mask=valid,
        metadata={
            "format": "tang2018",
            "nominal_fps": rate,
            "time_source": "frames spread evenly over the song frames of config.json",
            "song_start_s": start / SONG_FPS,
            "song_frames": [start, end],
            "time_origin": {"value": start / SONG_FPS, "unit": "s"},
        },
    )
