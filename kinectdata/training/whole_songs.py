"""How much a model moves over a split's whole songs, against the real dancers: the figure the kept
epoch is chosen by (``TrainConfig.keep``) and ``log.csv``'s ``val_energy``.

It is the energy ``kinectdata evaluate`` gives its alive verdict
(:func:`kinectdata.evaluation.metrics.pose_error.motion_energy_per_s`: mean squared joint speed of the body's
positions), of each song run free from its first pose to its end, over the real motion's, averaged
over the songs. Measured on windows run free from a true pose instead, the cdhc model on tang2018
moved at 0.36 x in an epoch whose whole songs moved at 0.07 x: a model that settles after some
seconds looks alive in ten-second windows (docs/training.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.evaluate import body_positions, split_recordings
from kinectdata.evaluation.metrics.pose_error import motion_energy_per_s
from kinectdata.models.kind import ModelKind
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec


@dataclass(frozen=True)
class WholeSongs:
    """A split's whole recordings, ready to be run free and measured.

    Attributes:
        features: per song, the model's inputs [T_i, *feature shape].
        first_poses: per song, the previous pose of frame 1 [D] (normalised).
        real_energy: per song, the real motion's mean squared joint speed, (units / s)^2.
        dataset: the run's dataset summary (target, normalisation, skeleton, fps).
    """

    features: list[np.ndarray]
    first_poses: list[np.ndarray]
    real_energy: list[float]
    dataset: dict[str, Any]

    @classmethod
    def of_split(
        cls,
        dataset: Path,
        manifest: dict[str, Any],
        split: str,
        kind: ModelKind,
        summary: dict[str, Any],
        start_pose: list[float] | None,
    ) -> WholeSongs | None:
        """The ``split``'s clean recordings of ``dataset`` (``summary``: the run's dataset summary,
        :func:`kinectdata.models.run.dataset_summary`; ``start_pose`` [D] stands in for a first
        pose's masked values); None when the split has none, or the target gives no joint position
        to measure (then no epoch has a ``val_energy``)."""
        spec = TargetSpec.from_dict(summary["target"])
        norm = Normalizer.from_dict(summary["normalisation"])
        features, first_poses, energy = [], [], []
        for r in split_recordings(dataset, manifest, split):
            positions, mask = body_positions(norm.invert(r["current"], spec, mask=r["mask"]), r["mask"], spec, summary)
            try:
                energy.append(motion_energy_per_s(positions, mask, summary["fps"]))
            except KinectDataError:  # too short, or no joint position: nothing to measure against
                continue
            features.append(r["input"])
            first_poses.append(kind.fill_previous(r["current"][0], r["mask"][0], start_pose))
        if not features or not all(e > 0 for e in energy):
            return None
        return cls(features, first_poses, energy, summary)

    def energy_ratio(self, net: Any, kind: ModelKind) -> float:
        """The model's motion energy over the real motion's, averaged over the songs: each song run
        free (``kind.free_runs``, in evaluation mode) from its first pose over all its frames."""
        spec = TargetSpec.from_dict(self.dataset["target"])
        norm = Normalizer.from_dict(self.dataset["normalisation"])
        runs = kind.free_runs(net, self.features, self.first_poses)
        ratios = []
        for made, real in zip(runs, self.real_energy):
            values = norm.invert(np.asarray(made), spec)
            positions, _ = body_positions(values, np.ones_like(values, bool), spec, self.dataset)
            ratios.append(motion_energy_per_s(positions, None, self.dataset["fps"]) / real)
        return float(np.mean(ratios))
