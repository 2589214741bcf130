"""The joints' bends in the free-running loss (``masked_span_loss``): known answers from the law of
cosines, computed apart from the code, on a hip-knee-ankle leg."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.models.losses import (  # noqa: E402
    Body,
    RhythmWeights,
    masked_rhythm_loss,
    masked_span_loss,
    spans_of,
)

THIGH, SHIN = 0.45, 0.31
BONES = [(1, 0), (2, 1)]  # knee -> hip, ankle -> knee
SCALE = torch.full((9,), 0.5)
OFFSET = torch.zeros(9)


def leg(knee_deg: np.ndarray, heading: np.ndarray) -> torch.Tensor:
    """[1, T, 9] normalised: hip at the origin, the thigh straight down, the knee bent by the angle
    between thigh and shin ``knee_deg`` [T] (180: straight), the leg turned by ``heading`` [T]
    radians about the vertical."""
    bend = np.radians(180.0 - knee_deg)
    hip = np.zeros((len(knee_deg), 3))
    knee = np.stack([np.zeros_like(bend), -THIGH * np.ones_like(bend), np.zeros_like(bend)], axis=1)
    ankle = knee + SHIN * np.stack([np.sin(bend), -np.cos(bend), np.zeros_like(bend)], axis=1)
    turn = np.stack([[[np.cos(h), 0, np.sin(h)], [0, 1, 0], [-np.sin(h), 0, np.cos(h)]] for h in heading])
    points = np.einsum("tij,tkj->tki", turn, np.stack([hip, knee, ankle], axis=1))
    return torch.from_numpy((points.reshape(1, -1, 9) - OFFSET.numpy()) * SCALE.numpy()).float()


def span_of(knee_deg: np.ndarray) -> np.ndarray:
    """Hip to ankle, metres, by the law of cosines."""
    return np.sqrt(THIGH**2 + SHIN**2 - 2 * THIGH * SHIN * np.cos(np.radians(knee_deg)))


def test_spans_join_each_joint_to_its_grandparent():
    assert spans_of(BONES) == [(2, 0)]
    assert spans_of([(1, 0), (2, 1), (3, 2), (4, 1)]) == [(2, 0), (3, 1), (4, 0)]
    assert spans_of([(1, 0)]) == []


def test_a_bent_knee_costs_its_span_gap_and_a_turned_leg_nothing():
    frames = 120
    rng = np.random.default_rng(0)
    real_deg = 150 + 10 * np.sin(np.linspace(0, 8 * np.pi, frames))
    real = leg(real_deg, rng.uniform(-np.pi, np.pi, frames))
    mask = torch.ones(1, frames, 9, dtype=torch.bool)

    made_deg = np.full(frames, 110.0)
    made = leg(made_deg, np.zeros(frames))
    real_span, made_span = span_of(real_deg), span_of(made_deg)
    expected = (abs(made_span.mean() - real_span.mean()) + abs(made_span.std() - real_span.std())) / real_span.mean()
    got = float(masked_span_loss(made, real, mask, BONES, SCALE, OFFSET))
    assert got == pytest.approx(expected, rel=1e-4)
    assert got > 0.1

    # the same bends at other headings and other moments: the spans' moments are the same
    turned = leg(np.roll(real_deg, 37), rng.uniform(-np.pi, np.pi, frames))
    assert float(masked_span_loss(turned, real, mask, BONES, SCALE, OFFSET)) == pytest.approx(0.0, abs=1e-5)


def test_masked_frames_do_not_count_and_the_weight_scales_the_term():
    frames = 90
    real_deg = np.full(frames, 150.0)
    made_deg = np.where(np.arange(frames) < 60, 150.0, 60.0)
    real, made = leg(real_deg, np.zeros(frames)), leg(made_deg, np.zeros(frames))
    mask = torch.ones(1, frames, 9, dtype=torch.bool)
    assert float(masked_span_loss(made, real, mask, BONES, SCALE, OFFSET)) > 0.1
    # a joint missing in the target anywhere in the window: the span is not counted at all
    gap = mask.clone()
    gap[0, 70, 6:9] = False
    assert float(masked_span_loss(made, real, gap, BONES, SCALE, OFFSET)) == 0.0

    made, real = made.double(), real.double()  # the whole loss is large: its sum in float64
    body = Body(bones=BONES, scale=SCALE.double(), offset=OFFSET.double())
    term = float(masked_span_loss(made, real, mask, BONES, body.scale, body.offset))
    with_term = float(masked_rhythm_loss(made, real, mask, 30.0, body, RhythmWeights(span=4.0)))
    without = float(masked_rhythm_loss(made, real, mask, 30.0, body))
    assert with_term - without == pytest.approx(4.0 * term, rel=1e-4)
