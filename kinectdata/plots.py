"""Figures (PNG, headless): training curves and generated-against-real trajectories.

Every function writes one PNG with labelled axes and units and returns its path.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # headless: no display needed
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | Path) -> Path:
    from .atomic import atomic_output

    path = Path(path)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")
    _pyplot().close(fig)
    return path


def loss_curves(history: Sequence[dict], path: str | Path, title: str = "Training") -> Path:
    """Training and validation loss (MSE of normalised targets) per epoch, log scale (the
    paper's Figure 5), and validation SMAPE on a second axis when present."""
    plt = _pyplot()
    epochs = [h["epoch"] for h in history]
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(epochs, [h["train_loss"] for h in history], "o-", label="training loss")
    val = [h.get("val_loss") for h in history]
    if any(v is not None and np.isfinite(v) for v in val):
        ax.plot(epochs, [np.nan if v is None else v for v in val], "s-", label="validation loss")
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    ax.set_ylabel("mean squared error (normalised targets)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    smape = [h.get("val_smape") for h in history]
    lines, labels = ax.get_legend_handles_labels()
    if any(v is not None and np.isfinite(v) for v in smape):
        ax2 = ax.twinx()
        ax2.plot(
            epochs,
            [np.nan if v is None else v for v in smape],
            "^--",
            color="tab:green",
            label="validation SMAPE (free-running)",
        )
        ax2.set_ylabel("SMAPE (%)")
        l2, lab2 = ax2.get_legend_handles_labels()
        lines, labels = lines + l2, labels + lab2
    ax.legend(lines, labels, loc="upper right")
    return _save(fig, path)


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
    plt = _pyplot()
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
    return _save(fig, path)


def rhythm_plot(report: dict, path: str | Path, title: str = "Autocorrelation of joint trajectories") -> Path:
    """Each axis's autocorrelation (unitless) against lag (s) from :func:`kinectdata.rhythm.rhythm_report`
    (Lee et al. 2018's evaluation), its peaks marked, a solid line at the beat period and dotted
    ones at half and double it. ``report`` may be read back from JSON (missing values as None)."""
    plt = _pyplot()
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
    return _save(fig, path)
