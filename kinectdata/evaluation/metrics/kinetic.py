"""Kinetic motion features: the 72 numbers per sequence behind FID_k and Div_k.

Defined by the AIST++ API (``aist_plusplus/features/kinetic.py``, after fairmotion) and used
unchanged by mint (AI Choreographer) and Bailando. For each of the 24 SMPL joints, over frames
i = 1..T-1:

- the mean squared **horizontal** speed of the joint, its velocity averaged over a window of
  +-2 frame differences (truncated at the ends);
- the mean squared **vertical** speed, same window;
- the mean "energy expenditure": the norm of the acceleration averaged over a window of +-2
  second differences.

No 1/2 m factor. The peers' acceleration has an operator-precedence slip: the earlier of its two
velocities is ``p[k] - p[k - 1] / dt`` instead of ``(p[k] - p[k - 1]) / dt``, so the third
feature grows with the distance of the joint from the origin and is not translation invariant.
``peer_acceleration=True`` (the default) reproduces it, which every published FID_k contains;
``False`` gives the physical quantity. Equality with the peers' code: tests/evaluation/
test_field_metrics.py on ``shared/fixtures/metrics``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinectdata.core.errors import KinectDataError

WINDOW_FRAMES = 2
"""Half-width of the averaging window in frame differences (the peers' ``sliding_window``)."""

KINETIC_PARTS = ("mean squared horizontal speed", "mean squared vertical speed", "mean acceleration")
"""What each joint's three kinetic features are, in their order (:func:`kinetic_features`)."""


def describe_kinetic_feature(index: int, joints: Sequence[str]) -> str:
    """What kinetic feature ``index`` (0-based: ``3 j + part``, :func:`kinetic_features`' order) is, in
    words: ``joints`` names the J joints (SMPL-24's for the field's FID_k)."""
    joint, part = divmod(int(index), 3)
    if not 0 <= joint < len(joints):
        raise KinectDataError(f"kinetic feature {index} does not exist for {len(joints)} joints ({3 * len(joints)})")
    return f"{joints[joint]}'s {KINETIC_PARTS[part]}"


def kinetic_features(positions: np.ndarray, fps: float, up_axis: int = 1, peer_acceleration: bool = True) -> np.ndarray:
    """The 72 kinetic features of one sequence of 24 joints.

    Args:
        positions: [T, J, 3] joint positions in metres, T >= 3 (J = 24 SMPL joints for the field's
            FID_k; any J works and gives 3 J features).
        fps: frames per second of ``positions`` (the field uses 60).
        up_axis: index of the vertical axis (1: y up, as AIST++).
        peer_acceleration: reproduce the peers' acceleration slip (see the module docstring).

    Returns:
        [3 J] float32: per joint j, ``3j`` the mean squared horizontal speed (m/s)^2, ``3j + 1`` the
        mean squared vertical speed (m/s)^2, ``3j + 2`` the mean windowed acceleration norm
        (m/s^2; with the slip, not a physical unit).
    """
    p = _checked(positions, fps)
    dt = 1.0 / fps
    frames = p.shape[0]
    horizontal = [a for a in range(3) if a != up_axis]

    step = np.zeros_like(p)  # step[k] = p[k] - p[k - 1] for k >= 1
    step[1:] = p[1:] - p[:-1]
    velocity = _window_mean(step, first=1, last=frames - 1) / dt  # [T - 1, J, 3] at i = 1..T-1
    energy_h = np.mean(np.sum(velocity[..., horizontal] ** 2, axis=-1), axis=0)
    energy_v = np.mean(velocity[..., up_axis] ** 2, axis=0)

    acceleration = np.zeros_like(p)  # acceleration[k] for k = 1..T-2
    later = (p[2:] - p[1:-1]) / dt
    earlier = (p[1:-1] - p[:-2] / dt) if peer_acceleration else (p[1:-1] - p[:-2]) / dt
    acceleration[1:-1] = (later - earlier) / dt
    expenditure = np.mean(np.linalg.norm(_window_mean(acceleration, first=1, last=frames - 2), axis=-1), axis=0)

    return np.stack([energy_h, energy_v, expenditure], axis=1).reshape(-1).astype(np.float32)


def _window_mean(values: np.ndarray, first: int, last: int) -> np.ndarray:
    """[T - 1, ...] for i = 1..T-1: the mean of ``values[k]`` over k in [i - 2, i + 2] and [first, last]."""
    frames = values.shape[0]
    total = np.zeros((frames - 1, *values.shape[1:]))
    count = np.zeros(frames - 1)
    centre = np.arange(1, frames)
    for offset in range(-WINDOW_FRAMES, WINDOW_FRAMES + 1):
        k = centre + offset
        inside = (k >= first) & (k <= last)
        total[inside] += values[k[inside]]
        count += inside
    return total / count.reshape(-1, *([1] * (values.ndim - 1)))


def _checked(positions: np.ndarray, fps: float) -> np.ndarray:
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3:
        raise KinectDataError(f"kinetic features need [T, J, 3] positions, got shape {p.shape}")
    if p.shape[0] < 3:
        raise KinectDataError(f"kinetic features need at least 3 frames, got {p.shape[0]}")
    if not np.all(np.isfinite(p)):
        frame = int(np.argmin(np.isfinite(p).all(axis=(1, 2))))
        raise KinectDataError(f"kinetic features need finite positions; frame {frame} has a missing joint")
    if not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    return p
