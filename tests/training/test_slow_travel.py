"""The root's slow travel taken out of training windows for a run that draws its travel
(kinectdata.training.augment.without_slow_travel): a sway about where the dancer goes stays, the
going does not; checked in metres against a moving average computed by numpy."""

from __future__ import annotations

import numpy as np
import torch

from kinectdata.training.augment import SlowTravel, without_slow_travel

FPS = 30.0


def test_the_sway_stays_and_the_going_goes():
    travel = SlowTravel(columns=(3, 5), scale=(0.2, 0.25), offset=(0.5, -1.0), frames=61)
    frames = 301
    t = np.arange(-1, frames) / FPS  # the pose before the window, then the window's
    place = np.stack([0.4 * t + 0.05 * np.sin(2 * np.pi * 1.5 * t), -0.3 * t], axis=1)  # metres, x and z
    rng = np.random.default_rng(0)
    poses = rng.normal(0, 0.3, (frames + 1, 8))
    for k, (column, scale, offset) in enumerate(zip(travel.columns, travel.scale, travel.offset)):
        poses[:, column] = (place[:, k] - offset) * scale  # normalised
    batch = {
        "pose": torch.tensor(poses[None, 1:], dtype=torch.float32),
        "previous": torch.tensor(poses[None, :-1], dtype=torch.float32),
        "mask": torch.ones(1, frames, 8, dtype=torch.bool),
        "previous_mask": torch.ones(1, frames, 8, dtype=torch.bool),
        "audio": torch.zeros(1, frames, 2),
    }
    out = without_slow_travel(batch, travel)
    assert torch.equal(batch["pose"], torch.tensor(poses[None, 1:], dtype=torch.float32))  # not changed in place
    others = [c for c in range(8) if c not in travel.columns]
    assert torch.equal(out["pose"][..., others], batch["pose"][..., others])
    assert torch.equal(out["previous"][0, 1:], out["pose"][0, :-1])  # previous is the pose a frame later
    for k, (column, scale, offset) in enumerate(zip(travel.columns, travel.scale, travel.offset)):
        metres = out["pose"][0, :, column].numpy() / scale + offset
        width = travel.frames // 2
        average = np.array(
            [place[max(0, i - width) : i + width + 1, k].mean() for i in range(len(place))]  # truncated at the edges
        )
        np.testing.assert_allclose(metres, (place[:, k] - average)[1:], atol=1e-5)
        inside = slice(width, frames - width)  # away from the edges the going is gone, the sway kept
        sway = 0.05 * np.sin(2 * np.pi * 1.5 * t[1:]) if k == 0 else 0.0 * t[1:]
        # a 2-s average keeps 1/30 of a 1.5-Hz sway's swing
        np.testing.assert_allclose(metres[inside], sway[inside], atol=0.003)
