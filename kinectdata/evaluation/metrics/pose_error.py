"""Metrics of generated against real poses (numpy or torch arrays of the same shape)."""

from __future__ import annotations

import numpy as np

from kinectdata.core.errors import KinectDataError


def smape(generated: np.ndarray, real: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Symmetric mean absolute percentage error, as Yalta et al. (2016) define it, in percent.

    ``SMAPE = 100 / n * sum |F - A| / (|A| + |F|)`` over the n valid values, F generated and A
    real. A term whose denominator is 0 (both values exactly 0) counts as 0: a perfect match.
    Values range over 0..100.
    """
    f = np.asarray(generated, dtype=np.float64)
    a = np.asarray(real, dtype=np.float64)
    valid = np.ones(f.shape, bool) if mask is None else np.asarray(mask, bool)
    den = np.abs(a) + np.abs(f)
    terms = np.divide(np.abs(f - a), den, out=np.zeros_like(den), where=den > 0)
    n = int(valid.sum())
    return float(100.0 * terms[valid].sum() / n) if n else float("nan")


def motion_energy(poses: np.ndarray) -> np.ndarray:
    """[T] mean squared frame-to-frame change of a [T, D] pose sequence (0 for the first frame)."""
    poses = np.asarray(poses, dtype=np.float64)
    return np.concatenate([[0.0], np.mean(np.diff(poses, axis=0) ** 2, axis=1)])


def motion_energy_per_s(positions: np.ndarray, mask: np.ndarray | None, fps: float) -> float:
    """Mean squared joint speed, (units / s)^2: central-difference velocities of [T, J, C]
    positions, averaged over the joints and frames where the joint and both neighbours are valid."""
    pos = np.asarray(positions, np.float64)
    valid = np.isfinite(pos).all(axis=2) if mask is None else np.asarray(mask, bool) & np.isfinite(pos).all(axis=2)
    if pos.shape[0] < 3:
        raise KinectDataError(f"motion energy needs at least 3 frames, got {pos.shape[0]}")
    velocity = (pos[2:] - pos[:-2]) * fps / 2
    ok = valid[2:] & valid[:-2]
    if not ok.any():
        raise KinectDataError("motion energy: no joint is valid in two frames two apart")
    return float((velocity**2).sum(axis=2)[ok].mean())
