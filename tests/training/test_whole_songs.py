"""The validation energy a run logs (``val_energy``) is the one ``kinectdata evaluate``'s alive
verdict reads: each validation song run free from its first pose to its end, over the real motion."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TINY_TRAINING

from kinectdata.evaluation.evaluate import split_songs
from kinectdata.models.run import load_model
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import train


def _energy(positions: np.ndarray, mask: np.ndarray, fps: float) -> float:
    """Mean squared joint speed by central differences, joint by joint and frame by frame."""
    total, count = 0.0, 0
    for t in range(1, len(positions) - 1):
        for j in range(positions.shape[1]):
            if mask[t - 1, j] and mask[t + 1, j]:
                total += float(np.sum(((positions[t + 1, j] - positions[t - 1, j]) * fps / 2) ** 2))
                count += 1
    return total / count


def test_the_logged_validation_energy_is_the_alive_verdicts_figure_on_the_validation_songs(sample_dataset, tmp_path):
    run = tmp_path / "run"
    history = train(sample_dataset, run, TrainConfig(**{**TINY_TRAINING, "epochs": 1, "keep": "best"}))
    net, config = load_model(run)  # the one epoch, kept
    songs = split_songs(net, config, sample_dataset, "val")
    assert [s.name for s in songs.songs] == ["synth_001"]
    ratios = []
    for song in songs.songs:
        made = songs.generate(song.features, song.first_pose)  # frames 1..T-1, the target's units
        ratios.append(
            _energy(made, np.ones(made.shape[:2], bool), song.fps)
            / _energy(song.real_positions, song.real_mask, song.fps)
        )
    assert history[-1]["kept"] == "best"
    assert history[-1]["val_energy"] == pytest.approx(float(np.mean(ratios)), rel=1e-4)


def test_a_run_that_keeps_its_last_epoch_does_not_measure_it(trained_run):
    assert all(row.get("val_energy") is None for row in trained_run[1])
