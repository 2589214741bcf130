"""The training dancers' turning about the vertical and travel across the floor, fitted for a run to
draw at generation.

``train`` calls :func:`fit_dataset_turning` and :func:`fit_dataset_travel` before its first epoch and
keeps the processes in the run's ``config.json`` (``turning``, ``travel``): each training recording's
turning speed per frame (:func:`kinectdata.evaluation.metrics.turning.turning_rates`: the
least-squares turn of its joints' offsets from the root, the root's travel left out), fitted by
:func:`kinectdata.targets.turning.fit_turning`; and its root's horizontal travel, fitted by
:func:`kinectdata.targets.travel.fit_travel`. With ``TrainConfig.by_metre``, :func:`fit_dataset_by_metre`
fits both again on the training recordings of each metre (``drawn_by_metre``): on tang2018 the Latin
dancers (4 beats a bar) turn faster and in shorter turns than the waltzers (3), and travel less.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.evaluation.evaluate import split_recordings
from kinectdata.evaluation.metrics.turning import turning_rates
from kinectdata.evaluation.rhythm_eval import target_positions
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.travel import TravelProcess, fit_travel
from kinectdata.targets.turning import TurningProcess, fit_turning, turnable

__all__ = [
    "MIN_METRE_RECORDINGS",
    "fit_dataset_by_metre",
    "fit_dataset_travel",
    "fit_dataset_turning",
    "recording_beats_per_bar",
]

MIN_METRE_RECORDINGS = 3
"""A metre is fitted on its own only when at least this many training recordings have it."""


def fit_dataset_turning(dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]) -> TurningProcess | None:
    """The turning process of the dataset's training recordings, or None: the target cannot be
    turned (:func:`kinectdata.targets.turning.turnable`) or no training frame has a known turn.

    Args:
        dataset: the dataset folder.
        manifest: its manifest.
        summary: the run's dataset summary (:func:`kinectdata.models.run.dataset_summary`).
    """
    spec = TargetSpec.from_dict(summary["target"])
    if turnable(spec, bool(summary["root_centre"])):
        return None
    norm = Normalizer.from_dict(summary["normalisation"])
    fps = float(summary["fps"])
    root = spec.positions.index(spec.root)
    rates = []
    for r in split_recordings(dataset, manifest, "train"):
        if len(r["current"]) >= 3:  # the joints about the root, its travel left out, as evaluate's turning figure
            positions, mask = target_positions(norm.invert(r["current"], spec, mask=r["mask"]), r["mask"], spec)
            rates.append(turning_rates(np.delete(positions, root, axis=1), fps, np.delete(mask, root, axis=1)))
    try:
        return fit_turning(rates, fps, spec)
    except ConfigError:  # no frame with a known turn
        return None


def fit_dataset_travel(dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]) -> TravelProcess | None:
    """The travel process of the dataset's training recordings, or None: the target cannot travel
    (:func:`kinectdata.targets.turning.turnable`: the root's travel is what is drawn) or no training
    recording has a long enough stretch of known root positions. Arguments as :func:`fit_dataset_turning`'s."""
    spec = TargetSpec.from_dict(summary["target"])
    if turnable(spec, bool(summary["root_centre"])):
        return None
    norm = Normalizer.from_dict(summary["normalisation"])
    root = spec.positions.index(spec.root)
    tracks = []
    for r in split_recordings(dataset, manifest, "train"):
        positions, mask = target_positions(norm.invert(r["current"], spec, mask=r["mask"]), r["mask"], spec)
        tracks.append(np.where(mask[:, root, None], positions[:, root][:, [0, 2]], np.nan))
    try:
        return fit_travel(tracks, float(summary["fps"]))
    except ConfigError:  # no stretch long enough
        return None


def recording_beats_per_bar(manifest: dict[str, Any], recording: dict[str, Any]) -> int | None:
    """A dataset recording's metre as the build knew it: its recordings-manifest entry's
    ``beats_per_bar``, else the metre the build found for features that count bars; None: unknown."""
    entry = next((e for e in manifest.get("inputs", []) if e.get("name") == recording["recording"]), {})
    listed = entry.get("beats_per_bar")
    found = (recording.get("info", {}).get("metre") or {}).get("beats_per_bar")
    value = listed if listed is not None else found
    return None if value is None else int(value)


def fit_dataset_by_metre(dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]) -> dict[str, Any]:
    """The turning and travel processes fitted on the training recordings of each metre that at least
    :data:`MIN_METRE_RECORDINGS` of them have (:func:`recording_beats_per_bar`; recordings of no known
    metre are left out): ``{"3": {"recordings": n, "turning": {...}, "travel": {...}}, ...}``, a process
    left out where it cannot be fitted; empty when no metre is. Arguments as :func:`fit_dataset_turning`'s."""
    spec = TargetSpec.from_dict(summary["target"])
    if turnable(spec, bool(summary["root_centre"])):
        return {}
    norm = Normalizer.from_dict(summary["normalisation"])
    fps = float(summary["fps"])
    root = spec.positions.index(spec.root)
    groups: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for r in split_recordings(dataset, manifest, "train"):
        metre = recording_beats_per_bar(manifest, r)
        if metre is None or len(r["current"]) < 3:
            continue
        positions, mask = target_positions(norm.invert(r["current"], spec, mask=r["mask"]), r["mask"], spec)
        rates = turning_rates(np.delete(positions, root, axis=1), fps, np.delete(mask, root, axis=1))
        track = np.where(mask[:, root, None], positions[:, root][:, [0, 2]], np.nan)
        groups.setdefault(metre, []).append((rates, track))
    fitted: dict[str, Any] = {}
    for metre, members in sorted(groups.items()):
        if len(members) < MIN_METRE_RECORDINGS:
            continue
        entry: dict[str, Any] = {"recordings": len(members)}
        try:
            entry["turning"] = fit_turning([m[0] for m in members], fps, spec).to_dict()
        except ConfigError:
            pass
        try:
            entry["travel"] = fit_travel([m[1] for m in members], fps).to_dict()
        except ConfigError:
            pass
        fitted[str(metre)] = entry
    return fitted
