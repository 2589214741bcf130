"""The training figure: loss curves (PNG, headless)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kinectdata.core.figures import pyplot, save_png


def loss_curves(
    history: Sequence[dict],
    path: str | Path,
    title: str = "Training",
    loss_name: str = "mean squared error (normalised targets)",
) -> Path:
    """Training and validation loss per epoch, log scale (the paper's Figure 5), labelled
    ``loss_name`` with its units, and validation SMAPE on a second axis when present."""
    plt = pyplot()
    epochs = [h["epoch"] for h in history]
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(epochs, [h["train_loss"] for h in history], "o-", label="training loss")
    val = [h.get("val_loss") for h in history]
    if any(v is not None and np.isfinite(v) for v in val):
        ax.plot(epochs, [np.nan if v is None else v for v in val], "s-", label="validation loss")
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    ax.set_ylabel(loss_name)
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
    return save_png(fig, path)
