"""EDGE's Physical Foot Contact score (PFC; Tseng et al. 2023, ``eval/eval_pfc.py``).

When the body's centre accelerates, a foot must be on the ground to push: the score multiplies,
per frame, the root's acceleration (normalised by its largest value in the sequence) by the
horizontal speed of the slower foot joint of each foot, and averages. Lower is more physical.

As EDGE computes it, on SMPL-24 joints at 30 fps with z up:

- root acceleration: the second difference of joint 0 divided by dt^2; its vertical component
  clamped at >= 0 (falling is free, pushing up needs a foot); the norm, divided by its maximum;
- foot speed: the horizontal displacement **per frame** of the ankle and foot joints (7, 10 left;
  8, 11 right), frames 2..T-1 (so the value depends on the frame rate, one reason the protocol
  fixes 30 fps); per side the smaller of the two;
- the sequence's score: the mean over frames of left x right x root acceleration; the set's PFC:
  the mean over sequences times 10 000.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinectdata.core.errors import KinectDataError

PFC_FPS = 30.0
"""The frame rate EDGE's PFC is defined at."""
LEFT_FOOT = (7, 10)
"""SMPL-24 left ankle and left foot."""
RIGHT_FOOT = (8, 11)
"""SMPL-24 right ankle and right foot."""
SCALE = 10_000
"""EDGE reports the mean score times 10 000."""


def foot_contact_score(positions: np.ndarray, fps: float = PFC_FPS, up_axis: int = 2) -> float:
    """One sequence's physical foot contact score (unscaled).

    Args:
        positions: [T, 24, 3] SMPL-24 joint positions in metres, T >= 4, ``fps`` frames per second.
        fps: frames per second (EDGE: 30).
        up_axis: index of the vertical axis (EDGE: 2, z up).

    Returns:
        The mean of left x right foot displacement (m per frame) x normalised root acceleration;
        0 when the root never accelerates.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (24, 3):
        raise KinectDataError(f"foot contact needs [T, 24, 3] SMPL-24 positions, got shape {p.shape}")
    if p.shape[0] < 4:
        raise KinectDataError(f"foot contact needs at least 4 frames, got {p.shape[0]}")
    if not np.all(np.isfinite(p)):
        raise KinectDataError("foot contact needs finite positions (fill or drop missing frames first)")
    if not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    dt = 1.0 / fps
    root = p[:, 0]
    acceleration = np.diff(root, n=2, axis=0) / dt**2  # [T - 2, 3]
    acceleration[:, up_axis] = np.maximum(acceleration[:, up_axis], 0.0)
    magnitude = np.linalg.norm(acceleration, axis=1)
    peak = magnitude.max()
    if peak == 0:
        return 0.0
    magnitude /= peak
    flat = [a for a in range(3) if a != up_axis]
    feet = p[:, list(LEFT_FOOT + RIGHT_FOOT)][:, :, flat]
    step = np.linalg.norm(feet[2:] - feet[1:-1], axis=-1)  # [T - 2, 4]
    left = np.minimum(step[:, 0], step[:, 1])
    right = np.minimum(step[:, 2], step[:, 3])
    return float(np.mean(left * right * magnitude))


def physical_foot_contact(sequences: Sequence[np.ndarray], fps: float = PFC_FPS, up_axis: int = 2) -> float:
    """EDGE's PFC of a set: the mean :func:`foot_contact_score` over sequences, times 10 000."""
    if len(sequences) == 0:
        raise KinectDataError("PFC needs at least one sequence")
    return float(np.mean([foot_contact_score(s, fps, up_axis) for s in sequences]) * SCALE)
