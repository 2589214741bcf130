"""``build_dataset``: recordings in, a dataset folder out (shards + ``manifest.json``).

The recipe, top to bottom:

1. read the recordings (a manifest or a folder) and give each a split (explicit, or drawn with
   the seed; by recording, never by frame);
2. prepare every recording (:func:`.prepare.prepare_recording`: alignment, targets, streamed
   features, noisy copies for training), in parallel over recordings, into ``DATASET/.work/``;
   work files already there with the same key are reused, which is how an interrupted build
   resumes;
3. pick one quaternion sign per joint for all recordings (:mod:`.hemispheres`) and fit the
   target normalisation, both on the training split only (merged per-recording statistics);
4. write the shards, split by split, starting a new one before one would exceed the size limit;
   each shard is written to a temporary name and renamed, and an existing shard with the same
   build key is kept;
5. write ``manifest.json`` (atomically; its presence marks a complete dataset) and remove the
   work folder.

Everything is deterministic: the same inputs and configuration give byte-identical files.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
import warnings
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from kinectdata.core.atomic import atomic_output, remove
from kinectdata.core.errors import KinectDataError, KinectDataWarning
from kinectdata.core.hashing import file_sha256
from kinectdata.core.version import __version__
from kinectdata.dataset.executors import Executor, LocalExecutor
from kinectdata.dataset.inputs import (
    MUSIC_FACTS,
    LabelledSong,
    RecordingEntry,
    assign_splits,
    read_recordings,
    read_songs,
    split_counts,
)
from kinectdata.dataset.layout import LOCK, LOCK_OWNER, MANIFEST, SHARD_FORMAT, SHARD_NAME, SPLITS, WORK, shard_name
from kinectdata.dataset.lock import FolderBusyError, build_lock
from kinectdata.dataset.prepare import BuildConfig, Unit, prepare_recording, source_hashes
from kinectdata.dataset.shards import ShardRecording, row_bytes, write_shard
from kinectdata.dataset.song_styles import fit_style_inputs
from kinectdata.features import needs_style
from kinectdata.features.music_style import HEARING_VERSION
from kinectdata.targets.hemispheres import apply_flips, flipped_columns, reference_orientations, track_flips
from kinectdata.targets.normalization import Normalizer, NormStats, count_out_of_range
from kinectdata.targets.skeleton import merge_bone_offsets
from kinectdata.targets.specs import GenericTarget, TargetSpec

DATASET_FORMAT = "kinectdata.dataset"
DATASET_FORMAT_VERSION = 2  # 2: one quaternion hemisphere per joint across recordings


def _prepare(task: tuple) -> list[dict[str, Any]]:
    """Prepare one recording (perhaps in a worker process or on a Dask worker); errors name the recording."""
    entry, config, work, snrs, hashes, tempos, style, source = task
    try:
        return [u.to_dict() for u in prepare_recording(entry, config, work, snrs, hashes, tempos, style)]
    except KinectDataError as exc:
        raise KinectDataError(f"recording {entry.name!r} of {source}: {exc}") from exc


def _digest(doc: Any) -> str:
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:32]


def _plan_shards(units: list[Unit], splits: dict[str, str], config: BuildConfig, feature_shape, dim) -> list[dict]:
    """Shards per split, in order; a new shard starts before one would exceed the size limit."""
    limit = config.shard_size_mb * 1e6
    per_row = row_bytes(feature_shape, dim)
    plan = []
    for split in SPLITS:
        members = [u for u in units if splits[u.recording] == split]
        current: list[Unit] = []
        for u in members:
            if current and (sum(x.frames for x in current) + u.frames) * per_row > limit:
                plan.append({"split": split, "units": current})
                current = []
            current.append(u)
        if current:
            plan.append({"split": split, "units": current})
    counters: dict[str, int] = {}
    for shard in plan:
        i = counters.get(shard["split"], 0)
        counters[shard["split"]] = i + 1
        shard["file"] = shard_name(shard["split"], i)
    return plan


def _shard_attributes(config: BuildConfig, normalizer: Normalizer, split: str, key: str) -> dict[str, Any]:
    return {
        "split": split,
        "fps": config.fps,
        "sample_rate": config.sample_rate,
        "features": {"extractor": config.features.extractor, **config.features.to_dict()},
        "target_spec": config.target.to_dict(),
        "normalisation": normalizer.to_dict(),
        "root_centre": config.root_centre,
        "build_key": key,
    }


def _existing_key(path: Path) -> str | None:
    try:
        with h5py.File(path, "r") as f:
            return str(f.attrs.get("build_key"))
    except OSError:
        return None


def _is_shard_of_ours(path: Path) -> bool:
    """A file this builder wrote: a shard name and the shard format attribute."""
    if not SHARD_NAME.fullmatch(path.name):
        return False
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == SHARD_FORMAT
    except OSError:
        return False


def _clean(out: Path, keep: set[str], keep_work: bool) -> None:
    """Remove what earlier builds left: other shards of ours, our temporary files, the work folder."""
    for path in out.iterdir():
        if path.is_file() and path.name not in keep and _is_shard_of_ours(path):
            path.unlink()
    for partial in [*out.glob(".*.partial"), *(out / WORK).glob(".*.partial")]:
        partial.unlink(missing_ok=True)  # left by a killed build: never renamed into place
    if not keep_work:
        shutil.rmtree(out / WORK, ignore_errors=True)


def _complete(out: Path, build_key: str) -> dict[str, Any] | None:
    """The manifest of a finished build with this key whose shards are intact, else None."""
    try:
        manifest = json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(manifest, dict) or manifest.get("build_key") != build_key:
        return None
    if "skeleton" not in manifest:  # built before rest skeletons: redo
        return None
    for shard in manifest["shards"]:
        path = out / shard["file"]
        if not path.is_file() or file_sha256(path) != shard["sha256"]:
            return None
    return manifest


def build_dataset(
    source: str | Path,
    out_dir: str | Path,
    config: BuildConfig,
    *,
    jobs: int = 1,
    executor: Executor | None = None,
    progress: Callable[[int, int], None] | None = None,
    keep_work: bool = False,
    video_fps: float | None = None,
    allow_outside_paths: bool = False,
) -> dict[str, Any]:
    """Build a dataset folder from a recordings manifest or folder; returns the manifest.

    Args:
        source: a recordings manifest (JSON, YAML, CSV) or a folder (aligned ``.h5`` files or
            sessions).
        out_dir: the dataset folder (created; an earlier build's files there are resumed or
            replaced).
        config: what to build (:class:`BuildConfig`).
        jobs: recordings prepared in parallel (processes on this machine).
        executor: where to prepare the recordings (:mod:`.executors`; default: this machine with
            ``jobs`` processes); a Dask cluster's workers must see ``out_dir`` and the recordings
            at the same paths.
        progress: called as ``progress(done, total)`` after each recording.
        keep_work: keep ``.work/`` (the per-recording files) after success.
        video_fps: the frame rate of OpenPose recordings that do not give their own.
        allow_outside_paths: let a recordings manifest name files outside its folder (absolute
            paths, ``..``, symbolic links leading out); refused by default.

    One build writes a folder at a time (:mod:`.lock`): a second one fails at once with
    :class:`~kinectdata.dataset.lock.FolderBusyError` naming the first. A failed build removes an
    empty ``.work`` and the folders it created if it left nothing in them; prepared recordings in
    ``.work`` stay for the rerun. An empty val or test split is warned about
    (:class:`EmptySplitWarning`, :func:`empty_split_message`).
    """
    out = Path(out_dir)
    if executor is not None and jobs != 1:
        raise KinectDataError(f"give either jobs ({jobs}) or an executor ({executor}), not both")
    entries = read_recordings(source, video_fps=video_fps, allow_outside_paths=allow_outside_paths)
    splits = assign_splits(entries, config.split_ratios, config.seed)
    if "train" not in splits.values():
        raise KinectDataError(f"{source}: no recording is in the train split (the normalisation is fitted on it)")
    hashes = {e.name: source_hashes(e) for e in entries}
    _refuse_duplicates(entries, hashes, splits, source)
    # labelled songs without a recording teach a style input's classifier, and nothing else
    songs = read_songs(source, allow_outside_paths=allow_outside_paths)  # checked even when nothing hears them
    hears_style = needs_style(config.feature_config)
    if not hears_style:
        songs = []
    song_hashes = {s.name: file_sha256(s.audio) for s in songs}
    songs = _songs_of_their_own(songs, song_hashes, entries, hashes)
    build_key = _digest(
        {
            "format_version": DATASET_FORMAT_VERSION,
            "config": config.to_dict(),
            "inputs": [_key_entry(e, splits) for e in entries],
            "sources": hashes,
            **({"songs": [s.to_dict() | {"audio": song_hashes[s.name]} for s in songs]} if songs else {}),
            **({"hearing": HEARING_VERSION} if hears_style else {}),
        }
    )
    said = empty_split_message(source, entries, splits, config.split_ratios)
    if said:
        warnings.warn(said, EmptySplitWarning, stacklevel=2)
    created = _first_missing(out)
    locked = False
    try:
        with build_lock(out):
            locked = True
            try:
                return _build_locked(
                    out, entries, splits, hashes, build_key, config, executor, jobs, progress, keep_work, source, songs
                )
            except BaseException:
                _tidy_after_failure(out, created)  # still under the lock: no other build can be starting here
                raise
    except FolderBusyError:
        raise  # the folder is the other build's: touch nothing
    except BaseException:
        if not locked:  # the lock could not be taken (an unwritable folder...): what mkdir made goes
            _tidy_after_failure(out, created)
        raise


class EmptySplitWarning(KinectDataWarning):
    """A build leaves a split with no recording."""


LOST = {"val": "training has no validation loss", "test": "evaluate has no recordings to score"}
"""What an empty split costs, for :func:`empty_split_message`."""


def empty_split_message(
    source: str | Path, entries: list[RecordingEntry], splits: dict[str, str], ratios: tuple[float, float, float]
) -> str | None:
    """What to say when the val or test split is left empty, or None. A split the user emptied on
    purpose (ratio 0 while recordings are drawn) is not mentioned."""
    drawn = sum(e.split is None for e in entries)
    explicit = len(entries) - drawn
    empty = [
        s for i, s in enumerate(SPLITS) if s != "train" and s not in splits.values() and (ratios[i] > 0 or not drawn)
    ]
    if not empty:
        return None
    names = " and ".join(empty)
    if drawn:
        need = _recordings_filling(ratios, explicit_splits={splits[e.name] for e in entries if e.split is not None})
        how = (
            f"{drawn} recording{'s' * (drawn != 1)} drawn at split ratios {tuple(ratios)}"
            + (f" (and {explicit} with a split of their own)" if explicit else "")
            + f" leave{'s' * (drawn == 1 and not explicit)} the {names} split{'s' * (len(empty) > 1)} empty"
        )
        fix = "add recordings" + (f" ({need} or more drawn at these ratios fill every split)" if need else "")
        fix += f", change --split-ratios or give recordings a split ({'/'.join(empty)}) in a recordings manifest"
    else:
        how = f"the recordings manifest puts no recording in the {names} split{'s' * (len(empty) > 1)}"
        fix = f"give some recordings split: {empty[0]}"
    return f"{source}: {how} ({'; '.join(LOST[s] for s in empty)}): {fix}"


def _recordings_filling(ratios: tuple[float, float, float], explicit_splits: set[str], most: int = 1000) -> int | None:
    """The number of drawn recordings from which on (up to ``most``) no split with a non-zero ratio is
    left empty (the splits explicitly assigned recordings fill anyway), as
    :func:`~.inputs.assign_splits` draws them; None when even ``most`` leave one empty."""
    wanted = [s for i, s in enumerate(SPLITS) if ratios[i] > 0 and s not in explicit_splits]
    fills = None
    for n in range(most, 0, -1):
        counts = dict(zip(SPLITS, split_counts(n, ratios)))
        if not all(counts[s] > 0 for s in wanted):
            break
        fills = n
    return fills


def _first_missing(path: Path) -> Path | None:
    """The outermost folder of ``path`` (itself included) that does not exist yet: what a build
    creates there, and may remove again if it fails. None when ``path`` exists."""
    path = path.absolute()
    if path.exists():
        return None
    while not path.parent.exists():
        path = path.parent
    return path


def _tidy_after_failure(out: Path, created: Path | None) -> None:
    """After a failed build: an empty ``.work`` goes (one with prepared recordings stays, for the
    rerun to resume from), and so do the dataset folder and its parents up to ``created`` (the
    outermost folder the build made) if it left them empty but for its lock. A folder that was there
    before the build stays."""
    work = out / WORK
    if work.is_dir() and not any(work.iterdir()):
        work.rmdir()
    if created is None or not out.is_dir() or any(p.name not in (LOCK, LOCK_OWNER) for p in out.iterdir()):
        return
    shutil.rmtree(out, ignore_errors=True)
    folder = out.absolute().parent
    stop = created.parent
    while folder != stop and folder.is_dir() and not any(folder.iterdir()):
        folder.rmdir()
        folder = folder.parent


def _build_locked(
    out: Path,
    entries: list[RecordingEntry],
    splits: dict[str, str],
    hashes: dict[str, dict[str, str]],
    build_key: str,
    config: BuildConfig,
    executor: Executor | None,
    jobs: int,
    progress: Callable[[int, int], None] | None,
    keep_work: bool,
    source: str | Path,
    songs: list[LabelledSong],
) -> dict[str, Any]:
    """The build, under the folder's lock."""
    done = _complete(out, build_key)
    if done is not None:
        _clean(out, {s["file"] for s in done["shards"]}, keep_work)
        return done
    work = out / WORK
    work.mkdir(parents=True, exist_ok=True)
    for partial in work.glob(".*.partial"):
        partial.unlink()
    copies = {e.name: splits[e.name] == "train" for e in entries}  # augmented copies of training dances only
    # a style input hears every other song as it would hear any song; a training song is told its style
    config = fit_style_inputs(config, [e for e in entries if copies[e.name]], source, songs)
    tasks = [
        (
            e,
            config,
            str(work.resolve()),
            config.augment_snr if copies[e.name] else (),
            hashes[e.name],
            config.augment_tempo if copies[e.name] else (),
            e.style if copies[e.name] else None,
            str(source),
        )
        for e in entries
    ]
    units = _prepare_all(tasks, work, executor or LocalExecutor(jobs), progress)
    if isinstance(config.target, GenericTarget):
        config = dataclasses.replace(config, target=_one_target(units, config.target, source))

    spec = config.target
    train_units = [u for u in units if splits[u.recording] == "train" and u.snr_db is None and u.tempo is None]
    reference = reference_orientations((u.orientations for u in train_units), spec)
    flips = {u.name: track_flips(u.orientations, reference) for u in units}
    train_stats = NormStats.merge_all(
        NormStats.from_dict(u.stats).negated(flipped_columns(spec, flips[u.name])) for u in train_units
    )
    normalizer = Normalizer.fit(train_stats, config.normalisation)
    remove(out / MANIFEST)  # shards change from here: the folder is incomplete until the end
    shards, records = _write_shards(out, units, splits, config, normalizer, flips)
    manifest = {
        "format": DATASET_FORMAT,
        "format_version": DATASET_FORMAT_VERSION,
        "created_by": f"kinectdata {__version__}",
        "build_key": build_key,
        "config": config.to_dict(),
        "inputs": [e.to_dict() | {"split": splits[e.name]} for e in entries],
        "splits": {
            s: {
                "recordings": sorted({r["recording"] for r in records if r["split"] == s}),
                "rows": sum(r["frames"] for r in records if r["split"] == s),
                "shards": [x["file"] for x in shards if x["split"] == s],
            }
            for s in SPLITS
        },
        "normalisation": normalizer.to_dict(),
        "normalisation_stats": train_stats.to_dict(),
        "orientation_reference": {j: [float(v) for v in q] for j, q in zip(spec.orientations, reference)},
        "skeleton": merge_bone_offsets([u.skeleton for u in train_units]),
        "feature_shape": list(config.feature_shape),
        "target_dim": normalizer.dim,
        "shards": shards,
        "recordings": records,
        "totals": {"rows": sum(x["frames"] for x in shards), "recordings": len(records), "shards": len(shards)},
    }
    text = json.dumps(manifest, indent=2, default=str) + "\n"
    with atomic_output(out / MANIFEST) as tmp:
        tmp.write_text(text)
    _clean(out, {x["file"] for x in shards}, keep_work)
    return json.loads(text)


def _one_target(units: list[Unit], generic: GenericTarget, source: str | Path) -> TargetSpec:
    """The spec a generic target became for the recordings: one joint set for all of them."""
    specs: dict[str, list[str]] = {}
    for u in units:
        specs.setdefault(json.dumps(u.target, sort_keys=True), []).append(u.recording)
    if len(specs) > 1:
        sets = "; ".join(
            f"{TargetSpec.from_dict(json.loads(t)).joint_set} ({', '.join(sorted(set(r))[:3])})"
            for t, r in specs.items()
        )
        raise KinectDataError(
            f"{source}: the recordings use different joint sets, so the generic {generic.kind!r} target is not one "
            f"vector for all of them: {sets}; build them apart, or map them onto one set"
        )
    return TargetSpec.from_dict(json.loads(next(iter(specs))))


def _key_entry(entry: RecordingEntry, splits: dict[str, str]) -> dict[str, Any]:
    """An input as it counts for the build key: its name, options and split, and what is said about
    its music (a style or metre the features hear, and the manifest's record that evaluate reads),
    not where it lies."""
    facts = {k: getattr(entry, k) for k in MUSIC_FACTS if getattr(entry, k) is not None}
    return entry.options() | facts | {"split": splits[entry.name]}


def _songs_of_their_own(
    songs: list[LabelledSong],
    song_hashes: dict[str, str],
    entries: list[RecordingEntry],
    hashes: dict[str, dict[str, str]],
) -> list[LabelledSong]:
    """The labelled songs whose music (by content) is no recording's song and not an earlier labelled
    song's: a recording's song is heard as that recording's (told, for a training recording; kept
    out of the fit, for a held-out one, whose music must not teach the classifier), and a song
    listed twice counts once."""
    seen = {hashes[e.name][Path(e.audio).name] for e in entries if e.audio is not None}
    kept = []
    for song in songs:
        if song_hashes[song.name] not in seen:
            kept.append(song)
            seen.add(song_hashes[song.name])
    return kept


def _refuse_duplicates(entries: list[RecordingEntry], hashes: dict[str, dict[str, str]], splits, source) -> None:
    """The same recording twice (by content) would leak between splits or weigh double."""
    seen: dict[tuple, str] = {}
    for e in entries:
        content = tuple(sorted(hashes[e.name].values()))
        if content in seen:
            other = seen[content]
            raise KinectDataError(
                f"{source}: recordings {other!r} ({splits[other]}) and {e.name!r} ({splits[e.name]}) are the same "
                "files: a recording must appear once"
            )
        seen[content] = e.name


def _prepare_all(
    tasks: list[tuple], work: Path, executor: Executor, progress: Callable[[int, int], None] | None
) -> list[Unit]:
    """The units of every recording, in task order, prepared by ``executor`` into ``work``."""
    names = [f"recording {entry.name!r} of {source}" for entry, *_, source in tasks]
    units = [Unit(**u) for result in executor.map(_prepare, tasks, names, progress) for u in result]
    missing = [u.file for u in units if not (work / u.file).is_file()]
    if missing:  # workers on other machines wrote them where this one cannot see
        raise KinectDataError(
            f"{work}: the workers wrote {', '.join(missing[:3])}{' ...' if len(missing) > 3 else ''} but they are not "
            "here: the dataset folder must be on a filesystem the workers share, at the same path"
        )
    return units


def _write_shards(
    out: Path,
    units: list[Unit],
    splits: dict[str, str],
    config: BuildConfig,
    normalizer: Normalizer,
    flips: dict[str, np.ndarray],
) -> tuple[list[dict], list[dict]]:
    """Write (or keep, when already there with the same key) every planned shard; ``flips``
    [K] bool per unit name: the quaternion tracks to negate."""
    spec = config.target
    work = out / WORK
    shards, records = [], []
    for shard in _plan_shards(units, splits, config, config.feature_shape, normalizer.dim):
        key = _digest(
            {
                "config": config.to_dict(),
                "normalisation": normalizer.to_dict(),
                "units": [u.key for u in shard["units"]],
                "flips": [flips[u.name].tolist() for u in shard["units"]],
                "file": shard["file"],
            }
        )
        path = out / shard["file"]
        out_of_range = np.zeros(normalizer.dim, np.int64)
        if path.is_file() and _existing_key(path) == key:
            with h5py.File(path, "r") as f:
                out_of_range += count_out_of_range(f["current"][()], f["mask"][()], normalizer.bounds)
        else:
            with ExitStack() as stack:
                members = []
                for u in shard["units"]:
                    f = stack.enter_context(h5py.File(work / u.file, "r"))
                    mask = f["mask"][()]
                    targets = apply_flips(f["targets"][()], flipped_columns(spec, flips[u.name]))
                    current = normalizer.apply(targets, mask)
                    out_of_range += count_out_of_range(current, mask, normalizer.bounds)
                    members.append(
                        ShardRecording(
                            u.name,
                            f["input"],
                            current,
                            mask,
                            f["audio_padded"][()],
                            {"recording": u.recording, **u.info},
                        )
                    )
                write_shard(
                    path,
                    members,
                    _shard_attributes(config, normalizer, shard["split"], key),
                    compression=config.compression,
                )
        start = 0
        for u in shard["units"]:
            records.append(
                {
                    "name": u.name,
                    "recording": u.recording,
                    "split": shard["split"],
                    "shard": shard["file"],
                    "start": start,
                    "frames": u.frames,
                    "snr_db": u.snr_db,
                    **({"tempo": u.tempo} if u.tempo is not None else {}),
                    "sources": u.info["sources"],
                    "offset": u.info["offset"],
                    "flipped_orientations": [j for j, f in zip(spec.orientations, flips[u.name]) if f],
                    **({"metre": u.info["metre"]} if "metre" in u.info else {}),
                    **({"style": u.info["style"]} if "style" in u.info else {}),
                }
            )
            start += u.frames
        shards.append(
            {
                "file": shard["file"],
                "split": shard["split"],
                "frames": start,
                "recordings": len(shard["units"]),
                "bytes": path.stat().st_size,
                "sha256": file_sha256(path),
                "targets_out_of_range": int(out_of_range.sum()),
            }
        )
    return shards, records
