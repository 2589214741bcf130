"""The training dancers' turning about the vertical and travel across the floor, fitted for a run to
draw at generation.

``train`` calls :func:`fit_dataset_turning` and :func:`fit_dataset_travel` before its first epoch and
keeps the processes in the run's ``config.json`` (``turning``, ``travel``): each training recording's
turning speed per frame (:func:`kinectdata.evaluation.metrics.turning.turning_rates`: the
least-squares turn of its joints' offsets from the root, the root's travel left out), fitted by
:func:`kinectdata.targets.turning.fit_turning`; and its root's horizontal travel, fitted by
:func:`kinectdata.targets.travel.fit_travel`.
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

__all__ = ["fit_dataset_travel", "fit_dataset_turning"]


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
