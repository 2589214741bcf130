"""The free-running loss's bend term: the angle at each two-bone chain's middle joint, against
numpy's arccos of the same frames."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.models.losses import chains_of, masked_bend_loss, masked_span_loss  # noqa: E402

HIP, KNEE, ANKLE = 0, 1, 2
BONES = [(KNEE, HIP), (ANKLE, KNEE)]
THIGH, SHIN = 0.45, 0.4


def _legs(knee_deg: np.ndarray) -> np.ndarray:
    """[B, T, 9] hip, knee and ankle (metres) of legs bent to ``knee_deg`` [B, T] at the knee: the
    thigh hangs down from the hip, the shin turned forward in the x-y plane."""
    bend = np.radians(180.0 - knee_deg)
    hip = np.zeros(knee_deg.shape + (3,))
    knee = hip + [0.0, -THIGH, 0.0]
    ankle = knee + SHIN * np.stack([np.sin(bend), -np.cos(bend), np.zeros_like(bend)], axis=-1)
    return np.concatenate([hip, knee, ankle], axis=-1)


def _loss(made_deg, real_deg, mask=None, fn=masked_bend_loss):
    made = torch.from_numpy(_legs(np.asarray(made_deg, float)) * 0.5)
    real = torch.from_numpy(_legs(np.asarray(real_deg, float)) * 0.5)
    mask = torch.ones(real.shape, dtype=torch.bool) if mask is None else mask
    return float(
        fn(made, real, mask, BONES, torch.full((9,), 0.5, dtype=torch.float64), torch.zeros(9, dtype=torch.float64), 3)
    )


def test_the_chains_are_each_joint_its_parent_and_grandparent():
    assert chains_of(BONES) == [(ANKLE, KNEE, HIP)]
    assert chains_of([(1, 0)]) == []


def test_bend_loss_is_the_gap_in_mean_and_spread_of_the_knee_angle_in_radians():
    rng = np.random.default_rng(3)
    real = rng.uniform(140, 178, (2, 200))
    made = rng.uniform(120, 140, (2, 200))
    want = np.mean(
        [
            abs(np.radians(m).mean() - np.radians(r).mean()) + abs(np.radians(m).std() - np.radians(r).std())
            for m, r in zip(made, real)
        ]
    )
    assert _loss(made, real) == pytest.approx(want, rel=1e-6)
    assert _loss(real, real) == pytest.approx(0.0, abs=1e-9)


def test_a_bend_near_straight_costs_here_where_the_span_barely_sees_it():
    """157 against 133 degrees, the fold 2 run's knee: the span shortens by a few per cent and the
    span term stays small, while the angle is 0.42 rad off."""
    real, made = np.full((1, 100), 157.0), np.full((1, 100), 133.0)
    assert _loss(made, real) == pytest.approx(np.radians(24.0), rel=1e-6)
    assert _loss(made, real, fn=masked_span_loss) < 0.1


def test_windows_with_an_unknown_joint_are_left_out_and_the_gradient_is_finite_when_straight():
    real = np.stack([np.full(50, 150.0), np.full(50, 150.0)])
    made = np.stack([np.full(50, 150.0), np.full(50, 100.0)])
    mask = torch.ones(2, 50, 9, dtype=torch.bool)
    mask[1, 10, 6] = False  # the second window's ankle x unknown once
    assert _loss(made, real, mask) == pytest.approx(0.0, abs=1e-9)
    straight = torch.from_numpy(_legs(np.full((1, 20), 180.0))).requires_grad_(True)
    loss = masked_bend_loss(
        straight,
        torch.from_numpy(_legs(np.full((1, 20), 150.0))),
        torch.ones(1, 20, 9, dtype=torch.bool),
        BONES,
        torch.ones(9, dtype=torch.float64),
        torch.zeros(9, dtype=torch.float64),
        3,
    )
    loss.backward()
    assert torch.isfinite(straight.grad).all()


def test_a_body_without_chains_costs_nothing():
    x = torch.zeros(1, 5, 6)
    assert (
        float(masked_bend_loss(x, x, torch.ones(1, 5, 6, dtype=torch.bool), [(1, 0)], torch.ones(6), torch.zeros(6)))
        == 0.0
    )
