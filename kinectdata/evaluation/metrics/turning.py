"""How much of a motion's speed is the body turning about the vertical.

Ballroom dancers turn all the time: in the root-centred positions of tang2018's dancers, where the
body's travel is gone, a rigid turn about the vertical still moves every joint around the root. A
model whose output never turns can only make up that speed with other motion, or move less
(docs/notebook/2026-11-real-dance.md, "Where the missing energy is: the dancers turn").

The turn between two frames is the 2-D rotation about the up axis that best maps one frame's
horizontal joint positions onto the other's, both centred on their own mean (the least-squares
angle of the orthogonal Procrustes problem in the plane: Kabsch 1976, in two dimensions). Frames
are taken two apart (t-1 and t+1), as :func:`~kinectdata.evaluation.metrics.pose_error.motion_energy_per_s`
takes its central-difference speeds, so that the two figures share their frames and joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.metrics.pose_error import motion_energy_per_s

__all__ = ["Turning", "turning", "turning_rates"]


@dataclass(frozen=True)
class Turning:
    """One motion's turning (see the module docstring).

    Attributes:
        rate: mean absolute turning speed about the up axis, rad/s.
        energy: mean squared joint speed, (units / s)^2 (:func:`motion_energy_per_s`).
        turning_energy: the part of ``energy`` a rigid turn at each frame's rate explains: the mean
            squared speed of each joint carried round the frame's centre by the turn alone.
        spread: how wide the body is about the vertical: the mean squared horizontal distance of
            its joints from each frame's centre, (units)^2. A turn's energy is its speed squared
            times this: a body with its arms in turns with little of it.
    """

    rate: float
    energy: float
    turning_energy: float
    spread: float = float("nan")

    @property
    def share(self) -> float:
        """The turning's share of the motion's mean squared speed (0-1; NaN for a still motion)."""
        return self.turning_energy / self.energy if self.energy > 0 else float("nan")


def _pairs(positions: np.ndarray, mask: np.ndarray | None, up_axis: int):
    pos = np.asarray(positions, np.float64)
    if pos.ndim != 3 or pos.shape[2] != 3 or not 0 <= up_axis < 3:
        raise KinectDataError(f"turning needs positions [T, J, 3] and an up axis in 0..2, got shape {pos.shape}")
    if pos.shape[0] < 3:
        raise KinectDataError(f"turning needs at least 3 frames, got {pos.shape[0]}")
    valid = np.isfinite(pos).all(axis=2)
    if mask is not None:
        valid &= np.asarray(mask, bool)
    both = valid[2:] & valid[:-2]  # [T-2, J]: the joint in frames t-1 and t+1
    flat = [a for a in range(3) if a != up_axis]
    before, after = np.nan_to_num(pos[:-2][..., flat]), np.nan_to_num(pos[2:][..., flat])
    return pos, both, before, after


def _centred(points: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """[T, J, 2] points less their per-frame mean over the joints ``weight`` [T, J] marks."""
    count = np.maximum(weight.sum(axis=1, keepdims=True), 1.0)
    centre = (points * weight[..., None]).sum(axis=1, keepdims=True) / count[..., None]
    return (points - centre) * weight[..., None]


def _angles(both: np.ndarray, before: np.ndarray, after: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame pair, the least-squares turn angle [T-2] (NaN where fewer than two joints are valid
    in both frames) and the first frame's centred horizontal points [T-2, J, 2] it turns."""
    weight = both.astype(np.float64)
    p, q = _centred(before, weight), _centred(after, weight)
    cross = (p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]).sum(axis=1)
    dot = (p[..., 0] * q[..., 0] + p[..., 1] * q[..., 1]).sum(axis=1)
    angle = np.arctan2(cross, dot)
    angle[both.sum(axis=1) < 2] = np.nan
    return angle, p


def turning_rates(positions: np.ndarray, fps: float, mask: np.ndarray | None = None, up_axis: int = 1) -> np.ndarray:
    """Per frame 1..T-2, the body's turning speed about the up axis, rad/s.

    Args:
        positions: [T, J, 3] joint positions (any unit: the angle does not depend on it).
        fps: frames per second.
        mask: [T, J] bool, True where valid, or None (valid where finite).
        up_axis: the vertical axis (1: y up, the Kinect's camera space).

    Returns:
        [T-2] float64: the least-squares rotation angle from frame t-1 to frame t+1 over ``2 / fps``
        seconds, positive from the first horizontal axis towards the second (for y up, from x towards
        z); NaN where fewer than two joints are valid in both frames.
    """
    _, both, before, after = _pairs(positions, mask, up_axis)
    return _angles(both, before, after)[0] * fps / 2


def turning(positions: np.ndarray, fps: float, mask: np.ndarray | None = None, up_axis: int = 1) -> Turning:
    """A motion's turning speed, its mean squared joint speed and the part of it the turning explains.

    Args:
        positions: [T, J, 3] joint positions (metres, or the target's units).
        fps: frames per second.
        mask: [T, J] bool, True where valid, or None (valid where finite).
        up_axis: the vertical axis (1: y up).

    Returns:
        :class:`Turning`; the speeds are central differences, ``(x[t+1] - x[t-1]) * fps / 2``,
        averaged over the frames and joints valid in both neighbours. The turning's part moves each
        joint by the chord the frame's rigid turn carries it along, about the frame's centre.
    """
    pos, both, before, after = _pairs(positions, mask, up_axis)
    if not both.any():
        raise KinectDataError("turning: no joint is valid in two frames two apart")
    angles, p = _angles(both, before, after)
    rates, angle = angles * fps / 2, np.nan_to_num(angles)
    cos, sin = np.cos(angle)[:, None], np.sin(angle)[:, None]
    turned = np.stack([cos * p[..., 0] - sin * p[..., 1], sin * p[..., 0] + cos * p[..., 1]], axis=-1)
    carried = ((turned - p) ** 2).sum(axis=2) * (fps / 2) ** 2
    return Turning(
        rate=float(np.nanmean(np.abs(rates))) if np.isfinite(rates).any() else float("nan"),
        energy=motion_energy_per_s(pos, mask, fps),
        turning_energy=float(carried[both].mean()),
        spread=float((p**2).sum(axis=2)[both].mean()),
    )
