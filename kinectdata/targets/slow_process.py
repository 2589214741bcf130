"""The slow random process behind what a run draws at generation (the turning, the travel): white
Gaussian noise through two equal first-order low-pass stages.

``u_t = b u_{t-1} + (1 - b) e_t``, ``v_t = b v_{t-1} + (1 - b) u_t``, ``b = exp(-1 / (fps * tau))``,
scaled so that its stationary root mean square is 1; its autocorrelation at k frames is
``b^k (1 + k (1 - b^2) / (1 + b^2))`` (``(1 + t / tau) exp(-t / tau)`` in time). Two stages, not one:
one renews the acceleration every frame and adds jerk. Where ``live`` is False (the music is
silent) the output is held at 0 and the second stage starts again from 0 after it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from kinectdata.core.motion import true_runs

__all__ = ["fit_time_constant", "pole_and_gain", "pooled_autocorrelation", "two_stage", "two_stage_autocorrelation"]


def pole_and_gain(time_constant: float, fps: float) -> tuple[float, float]:
    """The stages' pole b and the gain that gives unit white noise a unit stationary output:
    ``1 / sqrt((1 - b)^4 (1 + b^2) / (1 - b^2)^3)``."""
    b = math.exp(-1 / (fps * time_constant))
    return b, math.sqrt((1 - b * b) ** 3 / ((1 - b) ** 4 * (1 + b * b)))


def two_stage_autocorrelation(lags: np.ndarray, b: float) -> np.ndarray:
    """The autocorrelation of the process of pole ``b`` at ``lags`` frames."""
    return b**lags * (1 + lags * (1 - b * b) / (1 + b * b))


def pooled_autocorrelation(series: Sequence[np.ndarray], lags: int) -> np.ndarray:
    """[lags + 1] sum of x_t x_{t+k} over the pairs finite in both, over the sum of x_t^2, pooled over
    the ``series`` (each [T_i], NaN where unknown)."""
    num, den = np.zeros(lags + 1), 0.0
    for r in series:
        r = np.asarray(r, np.float64)
        x = np.where(np.isfinite(r), r, 0.0)
        den += float((x * x).sum())
        for k in range(lags + 1):
            if k < len(x):
                num[k] += float((x[: len(x) - k] * x[k:]).sum())
    return num / den if den > 0 else np.full(lags + 1, np.nan)


def fit_time_constant(series: Sequence[np.ndarray], fps: float, max_lag_s: float) -> float:
    """The time constant (seconds, 0.5 frame to 10 s) whose process's autocorrelation over lags of 1
    frame to ``max_lag_s`` is nearest (least squares) the pooled autocorrelation of ``series``."""
    lags = max(1, int(round(max_lag_s * fps)))
    seen = pooled_autocorrelation(series, lags)
    k = np.arange(1, lags + 1, dtype=np.float64)

    def misfit(tau: float) -> float:
        return float(np.nansum((two_stage_autocorrelation(k, math.exp(-1 / (fps * tau))) - seen[1:]) ** 2))

    return float(minimize_scalar(misfit, bounds=(0.5 / fps, 10.0), method="bounded").x)


def two_stage(noise: np.ndarray, live: np.ndarray, time_constant: float, fps: float) -> np.ndarray:
    """The process (unit stationary root mean square) from standard normal draws ``noise`` [T, ...]
    (one per frame and component, frames first), 0 where ``live`` [T] is False."""
    live = np.asarray(live, bool)
    b, gain = pole_and_gain(time_constant, fps)
    u = lfilter([1 - b], [1, -b], np.asarray(noise, np.float64), axis=0)
    v = np.zeros_like(u)
    for first, last in true_runs(live):  # v is 0 in silence: each stretch of music starts from 0
        v[first : last + 1] = lfilter([1 - b], [1, -b], u[first : last + 1], axis=0)
    return gain * v
