"""The free-running loss's floors per component (``TrainConfig.component_floor``): a component far
smaller than the rest in normalised units, a root swaying along the floor, costs what it does,
against a numpy computation of the same divergence."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.models import losses  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402

FPS, FRAMES, CHUNK = 30.0, 120, 60


def _windows(sway: float) -> tuple[np.ndarray, np.ndarray]:
    """[1, T, 2] a limb's coordinate (1 unit at 1 Hz, as the network's normalised limbs) and a root's
    (1e-3 units at 1.5 Hz, as tang2018's root along the floor, scaled by the floor's width): the
    target, and the made motion whose root sways ``sway`` times as far."""
    t = np.arange(FRAMES) / FPS
    limb = np.sin(2 * np.pi * t)
    root = 1e-3 * np.sin(2 * np.pi * 1.5 * t)
    real = np.stack([limb, root], axis=-1)[None]
    made = np.stack([limb, sway * root], axis=-1)[None]
    return made, real


def _numpy_energy_divergence(made: np.ndarray, real: np.ndarray, per_component: bool) -> float:
    """Twice the Itakura-Saito divergence of the mean squared changes per component and chunk, each
    floored at 1 % of the target's mean (over every component, or over its own chunks)."""

    def energy(x):
        d2 = np.diff(x[0], axis=0) ** 2
        return np.stack([d2[a : a + CHUNK].mean(axis=0) for a in range(0, len(d2), CHUNK)])  # [chunks, D]

    m, r = energy(made), energy(real)
    floor = 1e-2 * (r.mean(axis=0) if per_component else r.mean()) + 1e-12
    ratio = (r + floor) / (m + floor)
    return float(np.mean(2 * (ratio - np.log(ratio) - 1)))


@pytest.mark.parametrize("per_component", [False, True])
def test_a_small_components_sway_costs_only_under_its_own_floor(per_component):
    made, real = _windows(sway=4.0)
    mask = torch.ones(real.shape, dtype=torch.bool)
    got = float(
        losses.masked_energy_loss(
            torch.from_numpy(made), torch.from_numpy(real), mask, CHUNK, component_floor=per_component
        )
    )
    assert got == pytest.approx(_numpy_energy_divergence(made, real, per_component), rel=1e-6)
    if per_component:
        assert got > 0.5  # four times the sway: the root's half of the mean, 2 (1/16 + ln 16 - 1) / 2
    else:
        assert got < 1e-4  # under the shared floor the sway is free


def test_the_free_running_loss_floors_every_speed_and_jitter_term_per_component_when_asked():
    """Every term that divides by the target's speed or acceleration sees the root's sway with
    ``component_floor``; the rhythm spectra (their own floor) and the postures are the same."""
    made, real = (torch.from_numpy(x) for x in _windows(sway=4.0))
    mask = torch.ones(real.shape, dtype=torch.bool)
    weights = losses.RhythmWeights(jitter=2.0, low_energy=2.0)
    shared = float(losses.masked_rhythm_loss(made, real, mask, FPS, None, weights))
    own = float(losses.masked_rhythm_loss(made, real, mask, FPS, None, weights, component_floor=True))
    chunk = round(losses.ENERGY_CHUNK_S * FPS)
    expected = 0.0
    for floor in (False, True):
        sign = 1.0 if floor else -1.0
        expected += sign * float(
            losses.masked_energy_loss(made, real, mask, chunk, component_floor=floor)
            + losses.masked_energy_loss(*losses._changes(made, real, mask), chunk, component_floor=floor)
            + 2.0 * losses.masked_jitter_loss(made, real, mask, chunk, component_floor=floor)
            + 2.0 * losses.masked_low_band_energy_loss(made, real, mask, FPS, chunk, component_floor=floor)
        )
    assert own - shared == pytest.approx(expected, rel=1e-5)
    assert own - shared > 1.0


def test_training_hands_the_setting_to_the_loss(monkeypatch, sample_dataset, tmp_path):
    from conftest import TINY_TRAINING

    from kinectdata.training import train as training

    seen = []
    original = training.masked_rhythm_loss

    def spy(*args, **kwargs):
        seen.append(kwargs.get("component_floor"))
        return original(*args, **kwargs)

    monkeypatch.setattr(training, "masked_rhythm_loss", spy)
    config = TrainConfig(**{**TINY_TRAINING, "epochs": 1, "free_weight": 1.0, "component_floor": True})
    training.train(sample_dataset, tmp_path / "run", config)
    assert seen and set(seen) == {True}  # the training steps' and the validation's
    assert TrainConfig.from_dict({"model": "cdhc"}).component_floor is False  # runs written before it
