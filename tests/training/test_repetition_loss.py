"""How a motion repeats in the free-running loss (``masked_repetition_loss``): its curve equals the
listening figures' own autocorrelation (numpy, computed lag by lag, apart from the loss's FFT), it
does not care about phase, it parts a motion repeating every bar from one repeating every two bars,
and its gradient moves a motion towards the target's repetition."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.evaluation.rhythm import DRIFT_WINDOW_S, trajectory_autocorrelation  # noqa: E402
from kinectdata.models.losses import (  # noqa: E402
    REPETITION_DRIFT_S,
    REPETITION_LAGS_S,
    Body,
    RhythmWeights,
    masked_repetition_loss,
    masked_rhythm_loss,
    vertical_repetition,
)

FPS = 30.0
BAR = 2.07  # a waltz's bar at 87 BPM, seconds
JOINTS = 4
BODY = Body(bones=[(1, 0), (2, 1), (3, 0)], scale=torch.full((3 * JOINTS,), 0.5), offset=torch.zeros(3 * JOINTS))


def dancer(frames: int, one_bar: float, two_bars: float, shift_s: float = 0.0, seed: int = 0) -> np.ndarray:
    """[frames, JOINTS, 3] metres: heights that bob every bar (amplitude ``one_bar``) and sway every
    two bars (``two_bars``), each joint at its own phase, started ``shift_s`` later, a little noise
    and a slow rise; x and z noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / FPS + shift_s
    pos = 0.05 * rng.standard_normal((frames, JOINTS, 3))
    for j in range(JOINTS):
        pos[:, j, 1] = (
            1.0
            + 0.3 * j
            + one_bar * np.sin(2 * np.pi * t / BAR + j)
            + two_bars * np.sin(np.pi * t / BAR + 0.5 * j)
            + 0.02 * rng.standard_normal(frames)
            + 0.01 * t
        )
    return pos


def windows(*motions: np.ndarray) -> torch.Tensor:
    """[B, L, 3 * JOINTS] normalised as BODY normalises."""
    return torch.from_numpy(np.stack([m.reshape(len(m), -1) * 0.5 for m in motions])).double()


def test_the_curve_is_the_listening_figures_autocorrelation():
    assert REPETITION_DRIFT_S == DRIFT_WINDOW_S
    pos = dancer(300, 0.1, 0.06)
    first, last = int(np.ceil(REPETITION_LAGS_S[0] * FPS)), int(REPETITION_LAGS_S[1] * FPS)
    reference = trajectory_autocorrelation(pos, None, last, round(DRIFT_WINDOW_S * FPS))[first:, 1]
    curve, counted = vertical_repetition(torch.from_numpy(pos[None, :, :, 1]), torch.ones(1, JOINTS), FPS)
    assert counted.tolist() == [1.0]
    # the reference takes each lag's own means out of its pairs; the loss does not: a few thousandths
    assert np.abs(curve[0].numpy() - reference).max() < 0.01
    assert curve[0, round(2 * BAR * FPS) - first] > 0.8  # it repeats after two bars


def test_phase_does_not_count_and_the_level_does():
    mask = torch.ones(1, 300, 3 * JOINTS, dtype=torch.bool)
    two_bar_dancer = windows(dancer(300, 0.05, 0.1))
    later = windows(dancer(300, 0.05, 0.1, shift_s=1.3, seed=1))
    one_bar_dancer = windows(dancer(300, 0.1, 0.0, seed=2))
    same = float(masked_repetition_loss(later, two_bar_dancer, mask, BODY, FPS))
    other = float(masked_repetition_loss(one_bar_dancer, two_bar_dancer, mask, BODY, FPS))
    assert same < 0.005
    assert other > 20 * same


def test_a_joint_missing_in_the_window_is_left_out_and_a_body_without_bones_costs_nothing():
    made, real = windows(dancer(300, 0.1, 0.0)), windows(dancer(300, 0.05, 0.1))
    mask = torch.ones(1, 300, 3 * JOINTS, dtype=torch.bool)
    whole = float(masked_repetition_loss(made, real, mask, BODY, FPS))
    gap = mask.clone()
    gap[0, 150, 3:6] = False  # joint 1 missing once
    kept = [0, 2, 3]
    alone = Body(bones=[(1, 0), (2, 0)], scale=torch.full((9,), 0.5), offset=torch.zeros(9))
    pick = [c for j in kept for c in range(3 * j, 3 * j + 3)]
    three = float(masked_repetition_loss(made[..., pick], real[..., pick], mask[..., pick], alone, FPS))
    assert float(masked_repetition_loss(made, real, gap, BODY, FPS)) == pytest.approx(three, rel=1e-9)
    assert three != pytest.approx(whole)
    boneless = Body(bones=[], scale=BODY.scale, offset=BODY.offset)
    assert float(masked_repetition_loss(made, real, mask, boneless, FPS)) == 0


def test_its_gradient_brings_the_two_bar_sway_the_target_has():
    real = windows(dancer(300, 0.05, 0.1))
    mask = torch.ones(1, 300, 3 * JOINTS, dtype=torch.bool)
    t = torch.arange(300, dtype=torch.float64) / FPS
    sway = torch.zeros((), dtype=torch.float64, requires_grad=True)
    optimiser = torch.optim.Adam([sway], lr=0.01)
    base = windows(dancer(300, 0.05, 0.0, seed=3))
    for _ in range(150):
        made = base.clone()
        made[0, :, 1::3] = made[0, :, 1::3] + 0.5 * sway * torch.sin(np.pi * t / BAR)[:, None]
        loss = masked_repetition_loss(made, real, mask, BODY, FPS)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    assert float(sway.detach().abs()) > 0.05  # it grew from 0 towards the target's 0.1


def test_the_weight_adds_the_term_to_the_free_running_loss():
    made, real = windows(dancer(300, 0.1, 0.0)), windows(dancer(300, 0.05, 0.1))
    mask = torch.ones(1, 300, 3 * JOINTS, dtype=torch.bool)
    without = float(masked_rhythm_loss(made, real, mask, FPS, BODY))
    with_term = float(masked_rhythm_loss(made, real, mask, FPS, BODY, RhythmWeights(repetition=4.0)))
    term = float(masked_repetition_loss(made, real, mask, BODY, FPS))
    assert with_term - without == pytest.approx(4.0 * term, rel=1e-6)
