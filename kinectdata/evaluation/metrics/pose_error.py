"""Metrics of generated against real poses (numpy or torch arrays of the same shape)."""

from __future__ import annotations

import numpy as np


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
