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
The travel's floor (its centre, radius and pull) is fitted where every training recording has its
root anchor (datasets built with ``--root-centre``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.dataset.layout import known_metre
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
    "fit_dataset_drawn",
    "fit_dataset_travel",
    "fit_dataset_turning",
    "recording_beats_per_bar",
]

MIN_METRE_RECORDINGS = 3
"""A metre is fitted on its own only when at least this many training recordings have it."""


def _training_dances(
    dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]
) -> list[tuple[int | None, np.ndarray | None, np.ndarray, np.ndarray | None]] | None:
    """Each training recording's (metre (:func:`recording_beats_per_bar`), turning speed per frame
    (None: under 3 frames), root's horizontal track [T, 2] in metres, NaN where unknown, where it
    stood [2] (its root anchor's x and z, metres; None: built before anchors)), read once; None when
    the target cannot be turned (:func:`kinectdata.targets.turning.turnable`)."""
    spec = TargetSpec.from_dict(summary["target"])
    if turnable(spec, bool(summary["root_centre"])):
        return None
    norm = Normalizer.from_dict(summary["normalisation"])
    fps = float(summary["fps"])
    root = spec.positions.index(spec.root)
    out = []
    for r in split_recordings(dataset, manifest, "train"):
        positions, mask = target_positions(norm.invert(r["current"], spec, mask=r["mask"]), r["mask"], spec)
        rates = None  # the joints about the root, its travel left out, as evaluate's turning figure
        if len(r["current"]) >= 3:
            rates = turning_rates(np.delete(positions, root, axis=1), fps, np.delete(mask, root, axis=1))
        track = np.where(mask[:, root, None], positions[:, root][:, [0, 2]], np.nan)
        anchor = r["info"].get("root_anchor")
        stood = None if anchor is None else np.asarray(anchor, np.float64)[[0, 2]]
        out.append((recording_beats_per_bar(manifest, r), rates, track, stood))
    return out


def _fit_turning(dances, summary: dict[str, Any]) -> TurningProcess | None:
    rates = [d[1] for d in dances if d[1] is not None]
    try:
        return fit_turning(rates, float(summary["fps"]), TargetSpec.from_dict(summary["target"]))
    except ConfigError:  # no frame with a known turn
        return None


def _fit_travel(dances, summary: dict[str, Any]) -> TravelProcess | None:
    try:
        return fit_travel([d[2] for d in dances], float(summary["fps"]), [d[3] for d in dances])
    except ConfigError:  # no stretch long enough
        return None


def _fit_by_metre(dances, summary: dict[str, Any]) -> dict[str, Any]:
    groups: dict[int, list] = {}
    for dance in dances:
        if dance[0] is not None and dance[1] is not None:
            groups.setdefault(dance[0], []).append(dance)
    fitted: dict[str, Any] = {}
    for metre, members in sorted(groups.items()):
        if len(members) < MIN_METRE_RECORDINGS:
            continue
        entry: dict[str, Any] = {"recordings": len(members)}
        for name, process in (("turning", _fit_turning(members, summary)), ("travel", _fit_travel(members, summary))):
            if process is not None:
                entry[name] = process.to_dict()
        fitted[str(metre)] = entry
    return fitted


def fit_dataset_drawn(
    dataset: Path, manifest: dict[str, Any], summary: dict[str, Any], *, turning: bool, travel: bool, by_metre: bool
) -> dict[str, Any]:
    """What ``train`` keeps in the run of the processes it was asked for, the training split read
    once: ``turning``, ``travel`` (:func:`fit_dataset_turning`, :func:`fit_dataset_travel`) and
    ``drawn_by_metre`` (:func:`fit_dataset_by_metre`), each left out where it cannot be fitted."""
    dances = _training_dances(dataset, manifest, summary) if (turning or travel or by_metre) else None
    if dances is None:
        return {}
    kept: dict[str, Any] = {}
    for name, asked, fit in (("turning", turning, _fit_turning), ("travel", travel, _fit_travel)):
        process = fit(dances, summary) if asked else None
        if process is not None:
            kept[name] = process.to_dict()
    if by_metre and (metres := _fit_by_metre(dances, summary)):
        kept["drawn_by_metre"] = metres
    return kept


def fit_dataset_turning(dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]) -> TurningProcess | None:
    """The turning process of the dataset's training recordings, or None: the target cannot be
    turned (:func:`kinectdata.targets.turning.turnable`) or no training frame has a known turn.

    Args:
        dataset: the dataset folder.
        manifest: its manifest.
        summary: the run's dataset summary (:func:`kinectdata.models.run.dataset_summary`).
    """
    dances = _training_dances(dataset, manifest, summary)
    return None if dances is None else _fit_turning(dances, summary)


def fit_dataset_travel(dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]) -> TravelProcess | None:
    """The travel process of the dataset's training recordings, or None: the target cannot travel
    (:func:`kinectdata.targets.turning.turnable`: the root's travel is what is drawn) or no training
    recording has a long enough stretch of known root positions. Arguments as :func:`fit_dataset_turning`'s."""
    dances = _training_dances(dataset, manifest, summary)
    return None if dances is None else _fit_travel(dances, summary)


def recording_beats_per_bar(manifest: dict[str, Any], recording: dict[str, Any]) -> int | None:
    """A dataset recording's metre as the build knew it: its recordings-manifest entry's
    ``beats_per_bar``, else the metre the build found for features that count bars; None: unknown."""
    entry = next((e for e in manifest.get("inputs", []) if e.get("name") == recording["recording"]), {})
    listed, found = known_metre(entry, recording.get("info", {}))
    return listed if listed is not None else found


def fit_dataset_by_metre(dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]) -> dict[str, Any]:
    """The turning and travel processes fitted on the training recordings of each metre that at least
    :data:`MIN_METRE_RECORDINGS` of them have (:func:`recording_beats_per_bar`; recordings of no known
    metre are left out): ``{"3": {"recordings": n, "turning": {...}, "travel": {...}}, ...}``, a process
    left out where it cannot be fitted; empty when no metre is. Arguments as :func:`fit_dataset_turning`'s."""
    dances = _training_dances(dataset, manifest, summary)
    return {} if dances is None else _fit_by_metre(dances, summary)
