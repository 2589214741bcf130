"""The free-running loss's step term: the feet's speed about the root over the window against the
dancer's, checked against the same divergence computed per foot joint and axis in numpy."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.models.losses import Body, masked_step_loss  # noqa: E402

FPS = 30.0
JOINTS = 24
FEET = (7, 10, 8, 11)  # SMPL-24 left ankle, left foot, right ankle, right foot


def _dance(seed: int, step: float, travel: float, frames: int = 300) -> np.ndarray:
    """[T, 24, 3] y-up positions (metres): a body carried along the floor by its root at ``travel``
    m/s, swaying, whose feet step about the root by ``step`` metres at 1-1.6 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / FPS
    body = rng.normal(0.0, 0.3, (JOINTS, 3))
    root = np.stack([travel * t + 0.1 * np.sin(2 * np.pi * 0.5 * t), 0.9 + 0.02 * np.sin(4 * np.pi * t), 0 * t], 1)
    p = body[None] + root[:, None]
    p[:, 0] = root
    for k, j in enumerate(FEET):
        p[:, j, 0] += step * np.sin(2 * np.pi * (1.0 + 0.2 * k) * t + k)
        p[:, j, 1] += 0.3 * step * np.abs(np.sin(2 * np.pi * (1.0 + 0.2 * k) * t))
        p[:, j, 2] += 0.5 * step * np.cos(2 * np.pi * (0.8 + 0.1 * k) * t)
    return p


def _body(centred: bool) -> Body:
    feet = torch.zeros(4, JOINTS)
    for k, j in enumerate(FEET):
        feet[k, j] = 1.0
    scale = torch.full((JOINTS * 3,), 0.5)
    return Body(
        bones=[(j, 0) for j in range(1, JOINTS)],
        scale=scale,
        offset=torch.zeros(JOINTS * 3),
        feet=feet,
        root=0,
        centred=centred,
    )


def _tensor(dances: list[np.ndarray], centred: bool):
    x = np.stack(dances).copy()
    if centred:
        x[:, :, 1:] -= x[:, :, :1]
    return torch.from_numpy((x * 0.5).reshape(len(dances), x.shape[1], -1))


def _reference(made: list[np.ndarray], real: list[np.ndarray]) -> float:
    """Per window, foot joint and axis: the mean squared frame-to-frame change of the position about
    the root, ``2 (r/m - log(r/m) - 1)`` with both floored at 1 % of the dancer's mean; the mean."""

    def energy(dances):
        about = np.stack([d[:, FEET] - d[:, :1] for d in dances])  # [B, T, 4, 3]
        return (np.diff(about, axis=1) ** 2).mean(axis=1)  # [B, 4, 3]

    m, r = energy(made), energy(real)
    floor = 1e-2 * r.mean() + 1e-12
    q = (r + floor) / (m + floor)
    return float((2 * (q - np.log(q) - 1)).mean())


@pytest.mark.parametrize("centred", [False, True])
def test_the_step_term_is_the_divergence_of_the_feets_speed_about_the_root(centred):
    made = [_dance(0, 0.05, 0.4), _dance(1, 0.12, 0.0)]
    real = [_dance(2, 0.10, 0.1), _dance(3, 0.10, 0.2)]
    mask = torch.ones(2, 300, JOINTS * 3, dtype=torch.bool)
    got = float(masked_step_loss(_tensor(made, centred), _tensor(real, centred), mask, _body(centred)))
    assert got == pytest.approx(_reference(made, real), rel=1e-6)
    assert got > 0.3


def test_a_glide_costs_and_travel_alone_does_not():
    """Feet still about a root carried along the floor (a glide) cost as much as feet still about a
    root standing; feet stepping as the dancer's cost nothing however far the root travels. Half the
    dancer's step (a quarter of the energy) costs between nothing and the glide: at most
    ``2 (4 - log 4 - 1)``, each component's divergence at a ratio of 4, the floor taking some off."""
    real = [_dance(0, 0.1, 0.0)]
    mask = torch.ones(1, 300, JOINTS * 3, dtype=torch.bool)

    def cost(made):
        return float(masked_step_loss(_tensor(made, True), _tensor(real, True), mask, _body(True)))

    assert cost([_dance(0, 0.1, 0.8)]) == pytest.approx(0.0, abs=1e-9)
    assert cost([_dance(0, 0.0, 0.8)]) == pytest.approx(cost([_dance(0, 0.0, 0.0)]), rel=1e-9)
    assert cost([_dance(0, 0.0, 0.8)]) > 5.0
    half = cost([_dance(0, 0.05, 0.8)])
    assert half == pytest.approx(_reference([_dance(0, 0.05, 0.8)], real), rel=1e-6)
    assert 1.0 < half <= 2 * (4 - np.log(4) - 1) < cost([_dance(0, 0.0, 0.8)])


def test_frames_without_the_feet_or_the_root_do_not_count_and_a_body_without_feet_costs_nothing():
    real, made = [_dance(0, 0.1, 0.2)], [_dance(1, 0.05, 0.2)]
    mask = torch.ones(1, 300, JOINTS * 3, dtype=torch.bool)
    wild = [m.copy() for m in made]
    wild[0][150:, FEET[2]] += 5.0 * np.random.default_rng(4).normal(size=(150, 3))
    rootless = mask.clone()
    rootless[:, 150:, 0:3] = False
    footless = mask.clone()
    footless[:, 150:, 3 * FEET[2] : 3 * FEET[2] + 3] = False
    for hidden in (rootless, footless):
        half = float(masked_step_loss(_tensor(wild, True), _tensor(real, True), hidden, _body(True)))
        reference = _reference([m[:150] for m in made], [r[:150] for r in real])
        assert half == pytest.approx(reference, rel=1e-6)
    seen = float(masked_step_loss(_tensor(wild, True), _tensor(real, True), mask, _body(True)))
    assert seen > 2 * reference  # the wild half counts where the mask keeps it
    no_feet = Body(bones=[(1, 0)], scale=torch.ones(6), offset=torch.zeros(6), root=0, centred=True)
    assert (
        float(masked_step_loss(torch.zeros(1, 10, 6), torch.ones(1, 10, 6), torch.ones(1, 10, 6, dtype=bool), no_feet))
        == 0.0
    )
