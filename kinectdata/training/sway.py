"""A trained run's sway gain: its network's root along the floor against the training dancers'
(:mod:`kinectdata.targets.sway`), fitted once the run's weights are final (``TrainConfig.sway``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.dataset.layout import is_copy
from kinectdata.evaluation.evaluate import split_recordings
from kinectdata.inference.turning import faced_first_pose
from kinectdata.models.kind import ModelKind
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.sway import SwayGain, fit_sway
from kinectdata.targets.travel import floor_columns
from kinectdata.targets.turning import turnable

__all__ = ["fit_run_sway"]


def fit_run_sway(
    net: Any, kind: ModelKind, dataset: Path, manifest: dict[str, Any], run_config: dict[str, Any]
) -> SwayGain | None:
    """The sway gain of a trained network (``net``, in evaluation mode, of ``kind``): each training
    recording of ``dataset`` (not its augmented copies) run free and whole from its first pose, as
    ``evaluate`` runs a song (faced, where the run learnt its poses facing one way), its root's x and
    z against the dancer's (:func:`kinectdata.targets.sway.fit_sway`). None when the run draws no
    travel (its targets keep the dancers' whole travel, not their sway about it) or the target
    cannot travel."""
    summary = run_config["dataset"]
    spec = TargetSpec.from_dict(summary["target"])
    if run_config.get("travel") is None or turnable(spec, bool(summary["root_centre"])):
        return None
    norm = Normalizer.from_dict(summary["normalisation"])
    columns = floor_columns(spec, "sway")
    songs, firsts, dancers = [], [], []
    for r in split_recordings(dataset, manifest, "train"):
        if is_copy(r) or len(r["current"]) < 2:
            continue
        first = kind.fill_previous(r["current"][0], r["mask"][0], summary["start_pose"])
        firsts.append(faced_first_pose(run_config, first)[0])
        songs.append(r["input"])
        place = norm.invert(r["current"], spec, mask=r["mask"])[:, columns]
        dancers.append(np.where(r["mask"][:, columns].all(axis=1, keepdims=True), place, np.nan))
    if not songs:
        return None
    runs = kind.free_runs(net, songs, firsts)
    network = [norm.invert(np.asarray(made), spec)[:, columns] for made in runs]
    return fit_sway(network, dancers, float(summary["fps"]))
