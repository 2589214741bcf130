"""``build_dataset``: recordings in, a dataset folder out (shards + ``manifest.json``).

The recipe, top to bottom:

1. read the recordings (a manifest or a folder) and give each a split (explicit, or drawn with
   the seed; by recording, never by frame);
2. prepare every recording (:func:`.prepare.prepare_recording`: alignment, targets, streamed
   features, noisy copies for training), in parallel over recordings, into ``DATASET/.work/``;
   work files already there with the same key are reused, which is how an interrupted build
   resumes;
3. fit the target normalisation on the training split only (merged per-recording statistics);
4. write the shards, split by split, starting a new one before one would exceed the size limit;
   each shard is written to a temporary name and renamed, and an existing shard with the same
   build key is kept;
5. write ``manifest.json`` (atomically; its presence marks a complete dataset) and remove the
   work folder.

Everything is deterministic: the same inputs and configuration give byte-identical files.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from .. import __version__
from ..align import file_sha256
from ..atomic import atomic_output
from ..normalization import Normalizer, NormStats, count_out_of_range
from .inputs import SPLITS, RecordingEntry, assign_splits, read_recordings
from .prepare import BuildConfig, Unit, prepare_recording, source_hashes
from .shards import ShardRecording, row_bytes, write_shard

MANIFEST = "manifest.json"
DATASET_FORMAT = "kinectdata.dataset"
DATASET_FORMAT_VERSION = 1
WORK = ".work"


def _prepare(args: tuple[RecordingEntry, BuildConfig, str, tuple[float, ...], dict[str, str]]) -> list[dict[str, Any]]:
    entry, config, work, snrs, hashes = args
    return [u.to_dict() for u in prepare_recording(entry, config, work, snrs, hashes)]


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
        shard["file"] = f"{shard['split']}-{i:05d}.h5"
    return plan


def _shard_attributes(config: BuildConfig, normalizer: Normalizer, split: str, key: str) -> dict[str, Any]:
    return {
        "split": split,
        "fps": config.fps,
        "sample_rate": config.sample_rate,
        "features": {"extractor": "stft", **config.features},
        "target_spec": config.target,
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


def _complete(out: Path, build_key: str) -> dict[str, Any] | None:
    """The manifest of a finished build with this key whose shards are intact, else None."""
    try:
        manifest = json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    if manifest.get("build_key") != build_key:
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
    progress: Callable[[int, int], None] | None = None,
    keep_work: bool = False,
) -> dict[str, Any]:
    """Build a dataset folder from a recordings manifest or folder; returns the manifest.

    Args:
        source: a recordings manifest (JSON, YAML, CSV) or a folder (aligned ``.h5`` files or
            sessions).
        out_dir: the dataset folder (created; an earlier build's files there are resumed or
            replaced).
        config: what to build (:class:`BuildConfig`).
        jobs: recordings prepared in parallel (processes).
        progress: called as ``progress(done, total)`` after each recording.
        keep_work: keep ``.work/`` (the per-recording files) after success.
    """
    out = Path(out_dir)
    entries = read_recordings(source)
    splits = assign_splits(entries, config.split_ratios, config.seed)
    hashes = {e.name: source_hashes(e) for e in entries}
    build_key = _digest(
        {
            "config": config.to_dict(),
            "inputs": [e.to_dict() | {"split": splits[e.name]} for e in entries],
            "sources": hashes,
        }
    )
    done = _complete(out, build_key)
    if done is not None:
        return done
    (out / MANIFEST).unlink(missing_ok=True)  # until the new one is written, the folder is incomplete
    work = out / WORK
    work.mkdir(parents=True, exist_ok=True)
    tasks = [
        (e, config, str(work), config.augment_snr if splits[e.name] == "train" else (), hashes[e.name]) for e in entries
    ]

    units: list[Unit] = []
    if jobs > 1 and len(tasks) > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for i, result in enumerate(pool.map(_prepare, tasks)):
                units += [Unit(**u) for u in result]
                if progress:
                    progress(i + 1, len(tasks))
    else:
        for i, task in enumerate(tasks):
            units += [Unit(**u) for u in _prepare(task)]
            if progress:
                progress(i + 1, len(tasks))

    train_stats = [NormStats.from_dict(u.stats) for u in units if splits[u.recording] == "train" and u.snr_db is None]
    if not train_stats:
        raise ValueError("no training recordings")  # assign_splits always puts one in train
    normalizer = Normalizer.fit(NormStats.merge_all(train_stats), config.normalisation)

    with h5py.File(work / units[0].file, "r") as f:
        feature_shape, dim = tuple(f["input"].shape[1:]), f["targets"].shape[1]
    plan = _plan_shards(units, splits, config, feature_shape, dim)
    shards, records = [], []
    for shard in plan:
        key = _digest(
            {
                "config": config.to_dict(),
                "normalisation": normalizer.to_dict(),
                "units": [u.key for u in shard["units"]],
                "file": shard["file"],
            }
        )
        path = out / shard["file"]
        out_of_range = np.zeros(dim, np.int64)
        with_files = [
            h5py.File(work / u.file, "r") if (not path.is_file() or _existing_key(path) != key) else None
            for u in shard["units"]
        ]
        try:
            if any(f is not None for f in with_files):
                members = []
                for u, f in zip(shard["units"], with_files):
                    current = normalizer.apply(f["targets"][()], f["mask"][()])
                    out_of_range += count_out_of_range(current, f["mask"][()])
                    members.append(
                        ShardRecording(
                            u.name,
                            f["input"],
                            current,
                            f["mask"][()],
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
            else:
                with h5py.File(path, "r") as f:
                    out_of_range += count_out_of_range(f["current"][()], f["mask"][()])
        finally:
            for f in with_files:
                if f is not None:
                    f.close()
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
                    "sources": u.info["sources"],
                    "offset": u.info["offset"],
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
                "targets_beyond_0.9": int(out_of_range.sum()),
            }
        )

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
        "normalisation_stats": NormStats.merge_all(train_stats).to_dict(),
        "feature_shape": list(feature_shape),
        "target_dim": dim,
        "shards": shards,
        "recordings": records,
        "totals": {"rows": sum(x["frames"] for x in shards), "recordings": len(records), "shards": len(shards)},
    }
    text = json.dumps(manifest, indent=2, default=str) + "\n"
    with atomic_output(out / MANIFEST) as tmp:
        tmp.write_text(text)
    planned = {x["file"] for x in shards}
    for stale in out.glob("*-[0-9][0-9][0-9][0-9][0-9].h5"):
        if stale.name not in planned:  # shards of an earlier, different build
            stale.unlink()
    if not keep_work:
        shutil.rmtree(work, ignore_errors=True)
    return json.loads(text)
