"""The training dancers' turning about the vertical, fitted for a run to draw at generation.

``train`` calls :func:`fit_dataset_turning` before its first epoch and keeps the process in the run's
``config.json`` (``turning``): each training recording's turning speed per frame
(:func:`kinectdata.evaluation.metrics.turning.turning_rates`: the least-squares turn of its joints'
offsets from the root, the root's travel left out), fitted by
:func:`kinectdata.targets.turning.fit_turning`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.evaluation.evaluate import split_recordings
from kinectdata.evaluation.metrics.turning import turning_rates
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.turning import TurningProcess, fit_turning, turnable

__all__ = ["fit_dataset_turning", "body_offsets"]


def body_offsets(values: np.ndarray, mask: np.ndarray, spec: TargetSpec) -> tuple[np.ndarray, np.ndarray]:
    """The offsets from the root [T, P-1, 3] of every positioned joint but the root, and their mask
    [T, P-1], from denormalised root-centred targets [T, D] and their mask [T, D]."""
    joints = [j for j in spec.positions if j != spec.root]
    cols = np.array([np.arange(spec.columns(j).start, spec.columns(j).stop) for j in joints], np.int64)
    return values[:, cols], mask[:, cols].all(axis=2)


def fit_dataset_turning(
    dataset: Path, manifest: dict[str, Any], summary: dict[str, Any]
) -> tuple[TurningProcess | None, str]:
    """(the turning process of the dataset's training recordings, "") or (None, why there is none).

    Args:
        dataset: the dataset folder.
        manifest: its manifest.
        summary: the run's dataset summary (:func:`kinectdata.models.run.dataset_summary`).
    """
    spec = TargetSpec.from_dict(summary["target"])
    why = turnable(spec, bool(summary["root_centre"]))
    if why:
        return None, why
    norm = Normalizer.from_dict(summary["normalisation"])
    fps = float(summary["fps"])
    rates = []
    for r in split_recordings(dataset, manifest, "train"):
        if len(r["current"]) >= 3:
            offsets, mask = body_offsets(norm.invert(r["current"], spec, mask=r["mask"]), r["mask"], spec)
            rates.append(turning_rates(offsets, fps, mask))
    try:
        return fit_turning(rates, fps, spec), ""
    except ConfigError as exc:
        return None, str(exc).removeprefix("turning: ")
