"""An aligned recording: motion on an exact grid paired with mono audio, and its HDF5 file.

The file (``kinectdata align ... -o OUT.h5``) is self-describing; its layout, version 1:

=====================================  ==============================================================
``/`` attributes                       ``format`` = "kinectdata.aligned", ``format_version`` = 1,
                                       ``fps``, ``sample_rate`` (Hz), ``joint_set``, ``created_by``
``/motion/times``                      [N] float64, seconds; frame k is at exactly k / fps
``/motion/positions``                  [N, J, D] float32, metres (pixels for 2-D joint sets), NaN where masked
``/motion/position_mask``              [N, J] bool, True where valid
``/motion/position_interpolated``      [N, J] bool, True where filled across a gap
``/motion/confidence``                 [N, J] float32, 0..1
``/motion/orientations``               [N, J, 4] float32 unit quaternions (x, y, z, w), if the source has them
``/motion/orientation_mask``           [N, J] bool
``/motion/orientation_interpolated``   [N, J] bool
``/joints/names``, ``/joints/parents`` [J] joint names (UTF-8) and parent indices (-1: root)
``/joints`` attribute ``document``     JSON: a joint set kinectdata does not ship, whole (bones, roles, SMPL-24 mapping)
``/audio/samples``                     [S] float32 mono at ``sample_rate``; sample 0 is at time 0
``/`` attribute ``offset``             JSON: seconds, source ("given", "clap", "xcorr"), confidence
``/`` attribute ``provenance``         JSON: source files with SHA-256, reader, options
``/`` attribute ``summary``            JSON: the figures printed by ``align``
``/`` attribute ``gaps``               JSON: gaps longer than max_gap (masked), on the output clock
=====================================  ==============================================================
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from kinectdata.align.offset import OffsetChoice
from kinectdata.core.atomic import atomic_hdf5
from kinectdata.core.errors import ConfigError, FormatError
from kinectdata.core.jointsets import (
    JointSet,
    is_shipped,
    joint_set_from_text,
    joint_set_text,
    load_joint_set,
    shipped_joint_sets,
)
from kinectdata.core.motion import Motion
from kinectdata.core.version import __version__

FORMAT = "kinectdata.aligned"
FORMAT_VERSION = 1
_MAX_ARRAY_IN_ATTRIBUTE = 1024
_H5_DAMAGE = (OSError, KeyError, ValueError, TypeError, RuntimeError, IndexError)
"""What h5py raises reading a damaged file (bad signatures, truncated heaps, a group where a dataset
should be, attributes of odd types): caught only around the reading itself (:func:`_read_raw`)."""


def _jsonable(value: Any) -> Any:
    """numpy values for JSON attributes. Arrays of up to 1024 items become lists; larger ones
    (per-frame data of the source recording, meaningless on the output grid and too big for an
    HDF5 attribute) are replaced by a note of their shape."""
    if isinstance(value, np.ndarray):
        if value.size <= _MAX_ARRAY_IN_ATTRIBUTE:
            return value.tolist()
        return f"<array {list(value.shape)} {value.dtype} not kept>"
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def _dumps(value: Any) -> str:
    return json.dumps(value, default=_jsonable)


@dataclass
class Provenance:
    """Where an aligned recording came from (the ``provenance`` attribute, JSON).

    Attributes:
        motion: the reader's metadata of the skeleton recording, with ``path`` and ``sha256``.
        audio: the audio's source description (path, original rate, channels) with ``sha256``.
        options: the reading and alignment options given (format, schema, body, ...).
    """

    motion: dict[str, Any] = field(default_factory=dict)
    audio: dict[str, Any] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Provenance:
        parts = [d.get(k) or {} for k in ("motion", "audio", "options")]
        if not all(isinstance(x, dict) for x in parts):
            raise TypeError("motion, audio and options must be JSON objects")
        return cls(*parts)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"motion": self.motion, "audio": self.audio}
        if self.options:
            d["options"] = self.options
        return d


@dataclass(eq=False)
class AlignedRecording:
    """Motion resampled to ``k / fps`` seconds and the audio that goes with it.

    Attributes:
        motion: on the output clock; ``motion.times[k] == k / fps``.
        audio: [S] float32 mono samples at ``sample_rate``; sample 0 is at time 0.
        sample_rate: Hz.
        fps: motion frames per second.
        position_interpolated / orientation_interpolated: [N, J] bool, values filled across gaps.
        offset: :class:`~kinectdata.align.offset.OffsetChoice`; audio_time = motion_time + seconds
            on the *source* clocks.
        provenance: :class:`Provenance`: source files, hashes and options.
        summary: figures about the alignment (frames, duration, jitter, drops, interpolation...).
        gaps: gaps longer than ``max_gap`` (left masked), on the output clock.
    """

    motion: Motion
    audio: np.ndarray
    sample_rate: int
    fps: float
    position_interpolated: np.ndarray
    orientation_interpolated: np.ndarray | None = None
    offset: OffsetChoice | None = None
    provenance: Provenance = field(default_factory=Provenance)
    summary: dict[str, Any] = field(default_factory=dict)
    gaps: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        # the file stores both as JSON objects: a dict given (or read) becomes the typed value
        if isinstance(self.offset, dict):
            self.offset = OffsetChoice.from_dict(self.offset) if self.offset else None
        if isinstance(self.provenance, dict):
            self.provenance = Provenance.from_dict(self.provenance)

    @property
    def n_frames(self) -> int:
        return self.motion.n_frames

    @property
    def duration(self) -> float:
        """Seconds from frame 0 to one frame period past the last frame."""
        return self.n_frames / self.fps

    def frame_starts(self, sample_rate: int, slice_samples: int | None = None) -> np.ndarray:
        """[T] int64: the audio sample at each motion frame, ``round(k * sample_rate / fps)``.

        ``sample_rate`` (Hz) and ``slice_samples`` (audio samples one frame's features take) are
        those of the features to compute; a ConfigError refuses a rate other than the recording's
        or slices that are not one frame period long (a 16 kHz / 30 fps preset on a 22.05 kHz or
        60 fps recording would silently give features of the wrong audio)."""
        if sample_rate != self.sample_rate:
            raise ConfigError(
                f"the features are defined at {sample_rate} Hz, this recording's audio is at {self.sample_rate} Hz: "
                f"align it with --sample-rate {sample_rate} or use a feature configuration for {self.sample_rate} Hz"
            )
        period = self.sample_rate / self.fps
        if slice_samples is not None and abs(slice_samples - period) > 1:
            raise ConfigError(
                f"the features take {slice_samples}-sample slices "
                f"(one frame at {sample_rate / slice_samples:.0f} fps); "
                f"this recording has {self.fps:g} fps, {period:.1f} samples a frame: align it with --fps "
                f"{sample_rate / slice_samples:.0f} or use a feature configuration with slices of one frame"
            )
        return np.round(np.arange(self.n_frames) * self.sample_rate / self.fps).astype(np.int64)

    def __repr__(self) -> str:
        m = self.motion
        off = self.offset
        offset_text = f", offset {off.seconds:+.3f} s ({off.source})" if off is not None else ""
        return (
            f"AlignedRecording({self.n_frames} frames at {self.fps:g} fps ({self.duration:.2f} s), "
            f"{m.joint_set.name} {m.n_joints} joints, audio {self.audio.shape[0]} samples at {self.sample_rate} Hz"
            f"{offset_text}, {len(self.gaps)} long gaps)"
        )

    def save(self, path: str | Path, *, compression: str | None = "gzip") -> None:
        """Write the HDF5 file atomically (a temporary file renamed into place)."""
        m = self.motion
        with atomic_hdf5(path) as f:  # no chunk cache: a full disk is an error, not a crash
            f.attrs.update(
                {
                    "format": FORMAT,
                    "format_version": FORMAT_VERSION,
                    "fps": self.fps,
                    "sample_rate": self.sample_rate,
                    "joint_set": m.joint_set.name,
                    "created_by": f"kinectdata {__version__}",
                    "offset": _dumps(self.offset.to_dict() if self.offset else {}),
                    "provenance": _dumps(self.provenance.to_dict()),
                    "summary": _dumps(self.summary),
                    "gaps": _dumps(self.gaps),
                    "metadata": _dumps(m.metadata),
                }
            )
            g = f.create_group("motion")
            kw = {"compression": compression} if compression else {}
            g.create_dataset("times", data=m.times)
            g.create_dataset("positions", data=m.positions.astype(np.float32), **kw)
            g.create_dataset("position_mask", data=m.position_mask, **kw)
            g.create_dataset("position_interpolated", data=self.position_interpolated, **kw)
            g.create_dataset("confidence", data=m.confidence, **kw)
            if m.has_orientations:
                g.create_dataset("orientations", data=m.orientations.astype(np.float32), **kw)
                g.create_dataset("orientation_mask", data=m.orientation_mask, **kw)
                g.create_dataset("orientation_interpolated", data=self.orientation_interpolated, **kw)
            j = f.create_group("joints")
            j.create_dataset("names", data=np.array(m.joint_set.names, dtype=h5py.string_dtype()))
            j.create_dataset("parents", data=np.array(m.joint_set.parents, dtype=np.int32))
            j.attrs["dimensions"] = m.joint_set.dimensions
            if not is_shipped(m.joint_set):  # bones, roles and SMPL-24 mapping of a user's joint set
                j.attrs["document"] = joint_set_text(m.joint_set)
            f.create_group("audio").create_dataset("samples", data=self.audio.astype(np.float32), **kw)

    @classmethod
    def load(cls, path: str | Path, *, audio: bool = True) -> AlignedRecording:
        """Read a file written by :meth:`save`; FormatError naming the file if it is not one or is
        damaged. With ``audio=False`` the audio is left in the file (``audio`` is empty; see
        :func:`audio_blocks`)."""
        path = Path(path)
        try:
            f = h5py.File(path, "r")
        except _H5_DAMAGE as exc:
            raise FormatError(path, f"not a readable HDF5 file ({exc})") from exc
        with f:
            raw = _read_raw(f, path, audio)
        try:
            motion = Motion(
                times=raw["times"],
                positions=raw["positions"],
                joint_set=raw["joint_set"],
                position_mask=raw["position_mask"],
                confidence=raw["confidence"],
                orientations=raw.get("orientations"),
                orientation_mask=raw.get("orientation_mask"),
                metadata=raw["metadata"],
            )
        except ConfigError as exc:  # the arrays contradict each other: the file's fault, not a bug
            raise FormatError(path, f"damaged aligned recording ({exc})") from exc
        fps = raw["fps"]
        if not np.allclose(motion.times, np.arange(motion.n_frames) / fps, rtol=0, atol=1e-9):
            raise FormatError(path, f"motion/times are not k / fps for the fps attribute {fps:g}")
        for name in ("position_interpolated", "orientation_interpolated"):
            flag = raw.get(name)
            if flag is not None and (flag.shape != motion.position_mask.shape or flag.dtype != bool):
                raise FormatError(path, f"motion/{name} is {flag.dtype} {flag.shape}, expected bool [N, J]")
        samples = raw["samples"]
        if samples.ndim != 1 or samples.dtype.kind != "f":
            raise FormatError(path, f"audio/samples is {samples.dtype} {samples.shape}, expected float [S]")
        return cls(
            motion=motion,
            audio=samples,
            sample_rate=raw["sample_rate"],
            fps=fps,
            position_interpolated=raw["position_interpolated"],
            orientation_interpolated=raw.get("orientation_interpolated"),
            offset=_record(path, "offset", OffsetChoice.from_dict, raw["offset"]),
            provenance=_record(path, "provenance", Provenance.from_dict, raw["provenance"]),
            summary=raw["summary"],
            gaps=raw["gaps"],
        )


def _read_raw(f: h5py.File, path: Path, audio: bool) -> dict[str, Any]:
    """The attributes and arrays of an aligned file, checked for the format and its version.
    Only this reading is guarded against a damaged file's h5py errors (:data:`_H5_DAMAGE`); what is
    built from it afterwards raises our own errors, so a bug in that code surfaces as itself."""
    try:
        fmt = f.attrs.get("format")
        if not (isinstance(fmt, str) and fmt == FORMAT):
            raise FormatError(path, f"not a kinectdata aligned recording (format attribute {_show(fmt)})")
        version = f.attrs.get("format_version", -1)
        if not (isinstance(version, (int, np.integer)) and version == FORMAT_VERSION):
            raise FormatError(
                path, f"aligned-recording format version {_show(version)}; this kinectdata reads {FORMAT_VERSION}"
            )
        raw: dict[str, Any] = {"fps": float(f.attrs["fps"]), "sample_rate": int(f.attrs["sample_rate"])}
        if not (0 < raw["fps"] < np.inf and raw["sample_rate"] > 0):
            raise FormatError(path, f"fps {raw['fps']:g} and sample_rate {raw['sample_rate']} must be positive")
        g = f["motion"]
        names = ["times", "positions", "position_mask", "confidence", "position_interpolated"]
        if "orientations" in g:
            names += ["orientations", "orientation_mask", "orientation_interpolated"]
        raw.update({name: g[name][()] for name in names})
        for name in names:  # numbers where numbers belong, flags where flags: else the file is damaged
            want = "b" if name.endswith(("_mask", "_interpolated")) else "fiu"
            if not isinstance(raw[name], np.ndarray) or raw[name].dtype.kind not in want:
                kind = "bool" if want == "b" else "numbers"
                raise FormatError(
                    path, f"motion/{name} holds {getattr(raw[name], 'dtype', type(raw[name]))}, not {kind}"
                )
        raw["joint_set"] = _joint_set(f)
        raw["samples"] = f["audio/samples"][()] if audio else np.zeros(0, np.float32)
        raw["metadata"] = _json_attribute(f, path, "metadata", dict, "{}")
        for key, kind in (("offset", dict), ("provenance", dict), ("summary", dict), ("gaps", list)):
            raw[key] = _json_attribute(f, path, key, kind)
        return raw
    except _H5_DAMAGE as exc:
        raise FormatError(path, f"damaged aligned recording ({type(exc).__name__}: {exc})") from exc


def _json_attribute(f: h5py.File, path: Path, key: str, kind: type, default: str | None = None) -> Any:
    value = f.attrs[key] if default is None else f.attrs.get(key, default)
    try:
        parsed = json.loads(value)
    except (TypeError, ValueError) as exc:
        raise FormatError(path, f"attribute {key!r} is not JSON text ({exc})") from None
    if not isinstance(parsed, kind):
        raise FormatError(path, f"attribute {key!r} must hold a JSON {'object' if kind is dict else 'array'}")
    return parsed


def _record(path: Path, key: str, build: Any, doc: dict[str, Any]) -> Any:
    """A typed record from a JSON attribute's object (an empty object: None); FormatError naming the
    attribute when its fields are missing or of the wrong type."""
    if not doc and key == "offset":
        return None
    try:
        return build(doc)
    except (KeyError, TypeError, ValueError) as exc:
        raise FormatError(
            path, f"attribute {key!r} is not a valid {key} record ({type(exc).__name__}: {exc})"
        ) from None


def _show(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _joint_set(f: h5py.File) -> JointSet:
    names = tuple(n.decode() if isinstance(n, bytes) else str(n) for n in f["joints/names"][()])
    document = f["joints"].attrs.get("document")
    if document is not None:
        js = joint_set_from_text(str(document), f"{f.filename}: joints/document")
        if js.names != names:
            raise FormatError(f.filename, "joints/document names other joints than joints/names")
        return js
    name = str(f.attrs["joint_set"])
    if name in shipped_joint_sets():
        shipped = load_joint_set(name)
        if shipped.names == names:
            return shipped
    parents = [int(p) for p in f["joints/parents"][()]]
    return JointSet(name=name, names=names, parents=tuple(parents), dimensions=int(f["joints"].attrs["dimensions"]))


def audio_length(path: str | Path) -> int:
    """Samples of audio an aligned file holds (read without loading them)."""
    with h5py.File(path, "r") as f:
        return int(f["audio/samples"].shape[0])


def audio_blocks(path: str | Path, block: int = 160_000) -> Iterator[np.ndarray]:
    """The audio of an aligned file as consecutive [<= block] float32 arrays, read in slices."""
    with h5py.File(path, "r") as f:
        samples = f["audio/samples"]
        for start in range(0, samples.shape[0], block):
            yield samples[start : start + block]
