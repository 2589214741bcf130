"""Read a set of dance files as SMPL-24 sequences for the field's metrics.

A set is a folder (every motion file in it, sorted by name) or one file. What is read:

- **joint arrays** as the field's repositories save them: ``.npy`` or ``.npz`` of shape
  [T, 24, 3] or [T, 72], SMPL-24 order, metres, at ``array_fps`` with ``array_up`` up (AIST++ and
  Bailando: 60 fps, y up; EDGE: 30 fps, z up). An ``.npz`` holds one array, or one of the keys in
  :data:`ARRAY_KEYS`. Pickles (``.pkl``, and ``.npy`` files holding a dict, as Bailando writes
  ``{'pred_position': ...}``) are read only with ``allow_pickle``, and then by an unpickler that
  builds numpy arrays and plain containers and refuses every other class or function (the way a
  pickle runs code).
- **any recording kinectdata reads** (Kinect CSV dialects, NTU, Azure JSON, HTR...) and aligned
  ``.h5`` files: mapped to SMPL-24 by the joint set's mapping (``schemas/jointsets/to_smpl24``, or
  ``mapping``), so that a Kinect recording can be scored with the field's features.

Every sequence is resampled onto the protocol's frame rate with the aligner's resampler (linear
in position; frame 0 at the first frame), and joints missing for a few frames are filled by
linear interpolation (the share filled is recorded); a joint missing in more than
:data:`MAX_FILLED_FRACTION` of the frames is an error naming the file.

Music beats, for the Beat Align Score: an aligned ``.h5`` brings its music (ground-truth beats from
the ``<audio>.truth.json`` that ``kinectdata synth`` writes beside the audio it was aligned from,
else librosa's tracker). Other files take their music from ``music``, a folder with an audio file of
the same stem (a ``<stem>.truth.json`` beside it is used first), whose first sample is the
motion's frame 0, as ``kinectdata generate`` writes them.
"""

from __future__ import annotations

import dataclasses
import json
import pickle
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinectdata.align.aligned import AlignedRecording
from kinectdata.align.audio import load_audio
from kinectdata.align.timeline import resample_motion
from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import FormatError, KinectDataError, KinectDataWarning, SchemaError
from kinectdata.core.joint_mapping import load_smpl24_mapping
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.core.safe_pickle import PICKLE_SUFFIXES, load_arrays_pickle
from kinectdata.evaluation.field_scores import DanceSequence
from kinectdata.evaluation.protocols import Protocol, get_protocol
from kinectdata.features.beats import music_beats
from kinectdata.formats.registry import read_motion, readers
from kinectdata.formats.writers import register_writer

ARRAY_SUFFIXES = (".npy", ".npz")
ALIGNED_SUFFIXES = (".h5", ".hdf5")
AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".mp3")
ARRAY_KEYS = ("joints", "positions", "pred_position", "full_pose", "smpl_joints", "joints3d")
"""Keys under which the field's files keep SMPL-24 joints (Bailando: pred_position; EDGE: full_pose)."""
MAX_FILLED_FRACTION = 0.2
MAX_GAP_S = 0.5
"""Gaps up to this long are filled by the resampler; longer ones by the fill step, counted."""


class MusicOffsetWarning(KinectDataWarning):
    """A raw recording was given music by stem: nothing says where in the music its first frame is."""


def motion_files(path: str | Path) -> list[Path]:
    """The motion files of a set: ``path`` itself, or the files of folder ``path`` that kinectdata
    reads (sorted by name; audio, ``.json`` sidecars of other files and hidden files skipped)."""
    path = Path(path)
    if not path.exists():
        raise FormatError(path, "no such file or folder")
    if path.is_file():
        return [path]
    suffixes = set(ARRAY_SUFFIXES + PICKLE_SUFFIXES + ALIGNED_SUFFIXES)
    for reader in readers().values():
        suffixes.update(reader.extensions)
    found = []
    for f in sorted(path.iterdir()):
        if f.name.startswith(".") or f.suffix.lower() in AUDIO_SUFFIXES or f.name.endswith(".truth.json"):
            continue
        if f.is_file() and f.suffix.lower() in suffixes:
            found.append(f)
    if not found:
        raise FormatError(path, "no motion files in this folder (arrays .npy/.npz, recordings, aligned .h5)")
    return found


@dataclass(frozen=True)
class DanceReading:
    """How to read a set's files.

    Attributes:
        array_fps: frames per second of joint arrays (.npy/.npz/.pkl).
        array_up: ``"y"`` or ``"z"``, the vertical axis of joint arrays.
        mapping: a joint-mapping file for recordings whose joint set has no shipped mapping.
        music: a folder with the music of each file, by stem.
        allow_pickle: read pickles.
    """

    array_fps: float = 60.0
    array_up: str = "y"
    mapping: str | Path | None = None
    music: str | Path | None = None
    allow_pickle: bool = False


def load_dance_set(
    path: str | Path,
    protocol: Protocol,
    reading: DanceReading = DanceReading(),
    *,
    beats: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[DanceSequence]:
    """Every motion file of a set (:func:`motion_files`) as a :class:`DanceSequence` at ``protocol.fps``.

    ``beats``: a JSON file ``{"<stem>": [beat times in seconds from frame 0], ...}``, used before
    ``reading.music`` for the files it names.
    """
    given = read_beats_file(Path(beats)) if beats is not None else {}
    files = motion_files(path)
    out = []
    for i, f in enumerate(files):
        out.append(load_dance_sequence(f, protocol, reading, beats=given.get(f.stem)))
        if progress is not None:
            progress(i + 1, len(files))
    return out


def load_dance_sequence(
    path: str | Path, protocol: Protocol, reading: DanceReading = DanceReading(), *, beats: np.ndarray | None = None
) -> DanceSequence:
    """One file as SMPL-24 joints (metres, y up) at ``protocol.fps``; see the module docstring.

    Args:
        path: the file.
        protocol: gives the frame rate.
        reading: the conventions of joint arrays, the mapping, the music folder, pickles.
        beats: [B] music beat times in seconds from frame 0, if known (then ``reading.music`` is not used).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in ARRAY_SUFFIXES + PICKLE_SUFFIXES:
        joints = _joint_array(path, reading.allow_pickle)
        motion = _array_motion(joints, reading.array_fps, reading.array_up, path)
    elif suffix in ALIGNED_SUFFIXES:
        aligned = AlignedRecording.load(path)
        motion = aligned.motion
        if beats is None:
            beats = _aligned_beats(aligned, path)
    else:
        motion = read_motion(path)
    if reading.music is not None and beats is None:
        beats = _music_beats(Path(reading.music), path.stem)
        generated = motion.metadata.get("file_metadata", {}).get("generated_by") == "kinectdata generate"
        if suffix not in ARRAY_SUFFIXES + PICKLE_SUFFIXES and not generated:
            warnings.warn(
                f"{path}: its music is taken to start at its first frame; a recording whose music started at "
                "another time needs `kinectdata align` first (score the .h5), or its Beat Align Score is off",
                MusicOffsetWarning,
                stacklevel=2,
            )
    return motion_as_dance(motion, protocol, name=path.stem, source=path, mapping=reading.mapping, beats=beats)


def motion_as_dance(
    motion: Motion,
    protocol: Protocol,
    *,
    name: str,
    source: str | Path,
    mapping: str | Path | None = None,
    beats: np.ndarray | None = None,
) -> DanceSequence:
    """A :class:`~kinectdata.core.motion.Motion` of any 3-D joint set as SMPL-24 joints (metres,
    y up) at ``protocol.fps``, mapped by its joint set's shipped mapping or the ``mapping`` file,
    resampled from its first frame and with short gaps filled.

    Args:
        motion: positions in metres; its ``metadata["gravity_axis"]`` names the up axis (default y).
        protocol: gives the frame rate.
        name: what to call the sequence.
        source: the file (or run) it came from, named in errors.
        mapping: a joint-mapping file, else the joint set's shipped one.
        beats: [B] music beat times in seconds from the motion's first frame, if known.
    """
    source = Path(source)
    mapping_record = None
    motion, stand_ins = with_stand_ins(motion)
    if motion.joint_set.name != "smpl24" or len(motion.joint_set) != 24:
        if motion.joint_set.dimensions != 3:
            raise FormatError(
                source,
                f"joint set {motion.joint_set.name} is {motion.joint_set.dimensions}-D (pixels); the field's metrics "
                "need 3-D joints in metres",
            )
        try:
            if mapping is None:
                joint_map = load_smpl24_mapping(motion.joint_set)
            else:
                joint_map = load_smpl24_mapping(mapping, skeleton=motion.joint_set)
        except SchemaError as exc:
            raise FormatError(
                source, f"its {motion.joint_set.name} joints cannot be mapped to SMPL-24: {exc}"
            ) from None
        mapping_record = joint_map.describe()
        if stand_ins:
            mapping_record["stand_ins"] = {
                joint: f"never placed: {parent}, its nearest placed ancestor, stands in"
                for joint, parent in stand_ins.items()
            }
        up = motion.metadata.get("gravity_axis") or "y"
        positions, mask = joint_map.apply(motion.positions, motion.position_mask)
        motion = Motion(
            times=motion.times,
            positions=_y_up(positions, str(up).lower(), source),
            joint_set=load_joint_set("smpl24"),
            position_mask=mask,
        )
    positions, filled = _on_grid(motion, protocol.fps, source)
    steps = np.diff(motion.times)
    native = float(1.0 / np.median(steps)) if steps.size and np.median(steps) > 0 else None
    return DanceSequence(
        name=name,
        positions=positions,
        fps=protocol.fps,
        music_beats_s=beats,
        source=str(source),
        mapping=mapping_record,
        filled_fraction=filled,
        native_fps=native,
    )


def with_stand_ins(motion: Motion) -> tuple[Motion, dict[str, str]]:
    """The motion with every joint that is never placed (a generated target that does not reach it:
    yalta65 has no ankle orientations, so no feet) given its nearest placed ancestor's positions, and
    ``{joint: ancestor}`` for each such stand-in (empty: the motion as it is)."""
    js = motion.joint_set
    placed = motion.position_mask.any(axis=0)
    found = {}
    for j in np.flatnonzero(~placed):
        a = js.parents[j]
        while a >= 0 and not placed[a]:
            a = js.parents[a]
        if a >= 0:
            found[j] = a
    if not found:
        return motion, {}
    positions, mask = motion.positions.copy(), motion.position_mask.copy()
    for j, a in found.items():
        positions[:, j], mask[:, j] = positions[:, a], mask[:, a]
    moved = dataclasses.replace(motion, positions=positions, position_mask=mask)
    return moved, {js.names[j]: js.names[a] for j, a in found.items()}


def smpl24_joints(
    motion: Motion, fps: float = 60.0, *, source: str | Path = "the recording", mapping: str | Path | None = None
) -> DanceSequence:
    """The recording as the field's joint array (``positions``: [T, 24, 3] SMPL-24 joints in metres, y up,
    at ``fps``; AIST++ and Bailando keep 60) with its mapping's record (``mapping``: joints approximated,
    stand-ins), exactly as :func:`motion_as_dance` gives them to the metrics (mapped by the joint
    set's mapping or ``mapping``, never-placed joints stood in for, resampled from frame 0, short
    gaps filled), so that ``score`` reading the array back with ``--fps`` and ``--up y`` scores what
    it would score reading the recording. FormatError names ``source`` when it cannot be mapped."""
    if not (np.isfinite(fps) and fps > 0):
        raise KinectDataError(f"{source}: the frame rate must be a positive number of frames per second, not {fps!r}")
    rate = dataclasses.replace(get_protocol("aist"), fps=float(fps))  # of a protocol, only its rate is used here
    return motion_as_dance(motion, rate, name=Path(str(source)).stem, source=source, mapping=mapping)


def smpl24_loses(motion: Motion) -> list[str]:
    """What of ``motion`` the field's SMPL-24 joint array cannot carry, each a short phrase."""
    lost = [] if motion.joint_set.name == "smpl24" else [f"the {motion.joint_set.name} joints (mapped to SMPL-24)"]
    lost.append("the frame times (resampled from the first frame to --fps)")
    if np.any(motion.confidence[motion.position_mask] != 1.0):
        lost.append("the confidences")
    if motion.has_orientations:
        lost.append("the orientations")
    if not motion.position_mask.all():
        lost.append("which joints were missing (short gaps filled, never-placed joints stood in for)")
    return lost


@register_writer(
    "smpl24", extensions=(".npy",), loses=smpl24_loses, description="The field's SMPL-24 joint array (.npy)"
)
def write_smpl24(motion: Motion, path: str | Path, *, fps: float = 60.0, mapping: str | Path | None = None) -> Path:
    """Write ``motion`` as the field's joint array (:func:`smpl24_joints`: [T, 24, 3] float32
    SMPL-24 joints in metres, y up, at ``fps``), atomically; read back with the shipped array
    schema ``smpl24`` (``--schema smpl24 --array-fps FPS``) or by ``score``. Returns the path."""
    path = Path(path)
    return save_smpl24(smpl24_joints(motion, fps, source=motion.metadata.get("source", path), mapping=mapping), path)


def save_smpl24(sequence: DanceSequence, path: str | Path) -> Path:
    """Save a sequence's [T, 24, 3] joints as a float32 ``.npy`` at ``path``, atomically."""
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:
            np.save(f, sequence.positions.astype(np.float32))
    return Path(path)


def read_beats_file(path: Path) -> dict[str, np.ndarray]:
    """``{stem: [B] beat times in seconds}`` from a JSON object of lists of numbers."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise FormatError(path, f"cannot read ({exc.strerror or exc})") from exc
    except (ValueError, UnicodeDecodeError) as exc:
        raise FormatError(path, f"not JSON ({exc})") from exc
    if not isinstance(doc, dict):
        raise FormatError(path, 'expected a JSON object {"<file stem>": [beat times in seconds], ...}')
    out = {}
    for stem, times in doc.items():
        try:
            values = np.asarray(times, dtype=np.float64)
        except (TypeError, ValueError):
            values = None
        if values is None or values.ndim != 1 or not np.all(np.isfinite(values)):
            raise FormatError(path, f"{stem!r}: expected a list of beat times in seconds")
        out[stem] = values
    return out


def _joint_array(path: Path, allow_pickle: bool) -> np.ndarray:
    """The [T, 24, 3] array a .npy/.npz/.pkl file holds."""
    suffix = path.suffix.lower()
    if suffix in PICKLE_SUFFIXES and not allow_pickle:
        raise FormatError(path, "a pickle: loading one runs code from the file; pass --allow-pickle if you trust it")
    try:
        if suffix in PICKLE_SUFFIXES:
            with open(path, "rb") as f:
                data = load_arrays_pickle(f)
        elif suffix == ".npy":
            data = _read_npy(path, allow_pickle)
        else:
            data = np.load(path)
    except ValueError as exc:
        raise FormatError(path, f"not a readable numpy file ({exc})") from exc
    except (OSError, EOFError, pickle.UnpicklingError) as exc:
        raise FormatError(path, f"not readable ({exc})") from exc
    if isinstance(data, np.lib.npyio.NpzFile):
        with data:
            keys = list(data.keys())
            key = keys[0] if len(keys) == 1 else next((k for k in ARRAY_KEYS if k in keys), None)
            if key is None:
                raise FormatError(path, f"holds arrays {keys}; name the joints one of {', '.join(ARRAY_KEYS)}")
            data = data[key]
    if isinstance(data, np.ndarray) and data.dtype == object and data.shape == ():
        data = data.item()
    if isinstance(data, dict):
        key = next((k for k in ARRAY_KEYS if k in data), None)
        if key is None:
            raise FormatError(path, f"a dict with keys {sorted(map(str, data))}; none of {', '.join(ARRAY_KEYS)}")
        data = data[key]
    joints = np.asarray(data)
    if joints.dtype.kind not in "fiu":
        raise FormatError(path, f"joint array of type {joints.dtype}, expected numbers")
    if joints.ndim == 2 and joints.shape[1] == 72:
        joints = joints.reshape(-1, 24, 3)
    if joints.ndim != 3 or joints.shape[1:] != (24, 3):
        raise FormatError(path, f"joint array of shape {joints.shape}; expected [T, 24, 3] or [T, 72] SMPL-24 joints")
    return joints.astype(np.float64)


def _read_npy(path: Path, allow_pickle: bool):
    """A .npy file's array; one holding Python objects (Bailando's dicts) only with ``allow_pickle``,
    through :func:`~kinectdata.core.safe_pickle.load_arrays_pickle`."""
    with open(path, "rb") as f:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
        else:
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
        if dtype.hasobject:
            if not allow_pickle:
                raise FormatError(
                    path, "holds Python objects (a pickled dict?): pass --allow-pickle to read them (numpy arrays only)"
                )
            return load_arrays_pickle(f)
    return np.load(path)


def _array_motion(joints: np.ndarray, fps: float, up: str, path: Path) -> Motion:
    if not fps > 0:
        raise KinectDataError(f"--fps must be positive, got {fps}")
    return Motion(
        times=np.arange(joints.shape[0]) / fps,
        positions=_y_up(joints, up, path),
        joint_set=load_joint_set("smpl24"),
    )


def _y_up(positions: np.ndarray, up: str, path: Path) -> np.ndarray:
    """Positions turned so that y is up: z up (EDGE) turns by -90 degrees about x, (x, y, z) -> (x, z, -y)."""
    if up == "y":
        return positions
    if up == "z":
        return np.stack([positions[..., 0], positions[..., 2], -positions[..., 1]], axis=-1)
    raise FormatError(path, f"up axis {up!r}: the metrics take y or z up")


def _on_grid(motion: Motion, fps: float, path: Path) -> tuple[np.ndarray, float]:
    """[N, 24, 3] positions at ``fps`` from the motion's first frame, gaps filled; the share filled."""
    if motion.n_frames < 2:
        raise FormatError(path, f"{motion.n_frames} frame(s); the metrics need a sequence")
    times = motion.times
    # a grid time within a thousandth of a frame of the last frame is kept: files round their times
    # (kinectdata's CSV to the microsecond), and a frame lost to that would change every metric
    grid = times[0] + np.arange(int(np.floor((times[-1] - times[0]) * fps + 1e-3)) + 1) / fps
    grid = np.minimum(grid, times[-1])
    resampled = resample_motion(motion, grid, max_gap=MAX_GAP_S).motion
    positions, valid = resampled.positions, resampled.position_mask
    share = 1.0 - valid.mean(axis=0)
    worst = int(np.argmax(share))
    if share[worst] > MAX_FILLED_FRACTION:
        raise FormatError(
            path,
            f"joint {resampled.joint_set.names[worst]} (SMPL-24) is missing in {share[worst]:.0%} of the frames "
            f"(at most {MAX_FILLED_FRACTION:.0%} can be filled)",
        )
    frames = np.arange(grid.size)
    for j in np.flatnonzero(~valid.all(axis=0)):
        ok = valid[:, j]
        for c in range(3):
            positions[~ok, j, c] = np.interp(frames[~ok], frames[ok], positions[ok, j, c])
    return positions, float(1.0 - valid.mean())


def _aligned_beats(aligned: AlignedRecording, path: Path) -> np.ndarray | None:
    """Beats of an aligned recording's music on its motion clock: ground truth if the audio it was
    aligned from (as given, or beside the ``.h5``) has a ``.truth.json``, else librosa on its
    audio; None when neither is available."""
    given = aligned.provenance.audio.get("path")
    if isinstance(given, str):
        for candidate in (Path(given), path.parent / given):
            truth = _truth_beside(candidate)
            if truth is not None:
                return truth - float(aligned.summary.get("audio_trimmed_start_s", 0.0))
    try:
        beats, _ = music_beats(aligned.audio, aligned.sample_rate)
    except KinectDataError:
        return None
    return beats


def _music_beats(folder: Path, stem: str) -> np.ndarray:
    """Beats of the music ``folder/<stem>.<audio>``: its truth file, else librosa's tracker."""
    audio = next((folder / f"{stem}{s}" for s in AUDIO_SUFFIXES if (folder / f"{stem}{s}").is_file()), None)
    truth = _truth_beside(folder / f"{stem}.wav")
    if truth is not None:
        return truth
    if audio is None:
        raise FormatError(folder, f"no music for {stem!r} here ({stem}.wav, .flac, .ogg or .mp3)")
    loaded = load_audio(audio)
    beats, _ = music_beats(loaded.samples, loaded.sample_rate)
    return beats


def _truth_beside(audio: Path) -> np.ndarray | None:
    truth = audio.with_name(audio.name.rsplit(".", 1)[0] + ".truth.json")
    if not truth.is_file():
        return None
    try:
        return np.asarray(json.loads(truth.read_text())["beat_times_s"], dtype=np.float64)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise FormatError(truth, f"no readable beat_times_s ({exc})") from exc
