"""The evaluation figures (PNG, headless): generated-against-real trajectories and the
autocorrelation of joint trajectories against the beat period."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kinectdata.core.figures import pyplot, save_png


def trajectories(
    real: np.ndarray,
    generated: np.ndarray,
    names: Sequence[str],
    fps: float,
    path: str | Path,
    title: str = "Generated against real",
    unit: str = "normalised value",
    shade: tuple[float, float] | None = None,
) -> Path:
    """One panel per component: the real (if given) and generated values [T, K] over time (the
    paper's Figures 6 and 7); ``shade`` marks a span in seconds (e.g. inserted silence)."""
    plt = pyplot()
    k = len(names)
    t = np.arange(generated.shape[0]) / fps
    fig, axes = plt.subplots(k, 1, figsize=(7.5, 1.9 * k), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        if real is not None:
            ax.plot(t, real[:, i], color="0.3", lw=1.2, label="real")
        ax.plot(t, generated[:, i], color="tab:red", lw=1.0, label="generated")
        if shade is not None:
            ax.axvspan(*shade, color="tab:blue", alpha=0.12, label="silence")
        ax.set_ylabel(f"{names[i]}\n({unit})", fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[0, 0].set_title(title)
    axes[-1, 0].set_xlabel("time (s)")
    return save_png(fig, path)


def rhythm_plot(report: dict, path: str | Path, title: str = "Autocorrelation of joint trajectories") -> Path:
    """Each axis's autocorrelation (unitless) against lag (s) from :func:`kinectdata.evaluation.rhythm.rhythm_report`
    (Lee et al. 2018's evaluation), its peaks marked, a solid line at the beat period and dotted
    ones at half and double it. ``report`` may be read back from JSON (missing values as None)."""
    plt = pyplot()
    lags = np.asarray(report["lags_s"], dtype=np.float64)
    period = report["beat_period_s"]
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for name, axis in report["axes"].items():
        values = np.array([np.nan if v is None else v for v in axis["autocorrelation"]], dtype=np.float64)
        (line,) = ax.plot(lags, values, lw=1.3, label=name)
        peaks = axis["peaks"]
        ax.plot([p["lag_s"] for p in peaks], [p["height"] for p in peaks], "v", color=line.get_color(), ms=6)
    ax.axvline(period, color="0.15", lw=1.2, label=f"beat period {period:.3f} s ({report['beat_period_source']})")
    multiples = [m * period for m in (0.5, 2.0) if m * period <= lags[-1]]
    for i, lag in enumerate(multiples):
        ax.axvline(lag, color="0.45", lw=1.0, ls=":", label="half / double period" if i == 0 else None)
    ax.axhline(0.0, color="0.7", lw=0.8)
    ax.set_xlim(0.0, lags[-1])
    ax.set_xlabel("lag (s)")
    ax.set_ylabel("autocorrelation (mean over joints)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return save_png(fig, path)
