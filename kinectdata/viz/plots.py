"""The dataset report's figures (PNG, headless): tracking quality, offset evidence, feature
heatmaps, target distributions.

Every function writes one PNG with labelled axes and units to a path (atomically) or into a binary
stream, and returns it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import BinaryIO

import numpy as np

from kinectdata.core.figures import pyplot, save_png


def block_extremes(values: np.ndarray, max_points: int, reduce: str = "min") -> tuple[np.ndarray, np.ndarray]:
    """A long series cut to at most ``max_points`` samples that keeps its dips or peaks.

    Args:
        values: [N] series.
        max_points: most samples to keep (>= 1).
        reduce: ``"min"`` keeps each block's smallest value (dips stay visible), ``"max"`` its largest.

    Returns:
        ``(index [M] int64, value [M])``: from each block of ``ceil(N / max_points)`` consecutive
        samples, the position in ``values`` and the value of its extreme (the first one on ties);
        the whole series when N <= max_points.
    """
    values = np.asarray(values)
    n = values.shape[0]
    size = max(1, -(-n // max_points))
    if size == 1:
        return np.arange(n), values
    padded = np.concatenate([values, np.full(-n % size, values[-1])]).reshape(-1, size)
    pick = np.argmin(padded, axis=1) if reduce == "min" else np.argmax(padded, axis=1)
    index = np.arange(padded.shape[0]) * size + pick
    return index, values[index]


def tracking_quality(
    valid_share: np.ndarray,
    fps: float,
    out: str | Path | BinaryIO,
    *,
    interpolated_share: np.ndarray | None = None,
    spans: Sequence[tuple[float, float]] = (),
    title: str = "Tracking quality",
    max_points: int = 2000,
) -> str | Path | BinaryIO:
    """Share of valid target components per frame against time (s), with the share filled by
    interpolation when known and ``spans`` (start, end in seconds, e.g. masked longer than max_gap)
    shaded.

    ``valid_share`` and ``interpolated_share`` are [N] fractions (0..1) at ``fps`` frames per
    second, drawn in percent; longer series are cut to ``max_points`` by :func:`block_extremes`
    (the valid share's minima, the interpolated share's maxima), so a short loss stays visible.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 2.6))
    k, v = block_extremes(np.asarray(valid_share, np.float64), max_points, "min")
    ax.plot(k / fps, 100 * v, color="tab:blue", lw=1.0, label="valid")
    if interpolated_share is not None:
        k, v = block_extremes(np.asarray(interpolated_share, np.float64), max_points, "max")
        ax.plot(k / fps, 100 * v, color="tab:orange", lw=1.0, label="interpolated")
    for i, (start, end) in enumerate(spans):
        label = "masked, longer than max_gap" if i == 0 else None
        ax.axvspan(start, end, color="tab:red", alpha=0.2, lw=0, label=label)
    ax.set_xlim(0, len(valid_share) / fps)
    ax.set_ylim(-3, 103)
    ax.set_xlabel("time (s, dataset clock: frame k at k / fps)")
    ax.set_ylabel("target components (%)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    return save_png(fig, out)


def offset_curve(
    lags: np.ndarray,
    scores: np.ndarray,
    out: str | Path | BinaryIO,
    *,
    markers: Sequence[tuple[float, str]] = (),
    title: str = "Offset evidence",
    max_points: int = 4000,
) -> str | Path | BinaryIO:
    """Cross-correlation score (unitless) against the offset (s, ``audio_time = motion_time +
    offset``), as :attr:`kinectdata.align.offset.OffsetEstimate.curve` holds it, with a vertical line at
    each of ``markers`` (offset in seconds, label), the first one solid. The curve is cut to
    ``max_points`` by :func:`block_extremes` (its maxima)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 2.8))
    lags = np.asarray(lags, np.float64)
    k, v = block_extremes(np.asarray(scores, np.float64), max_points, "max")
    ax.plot(lags[k], v, color="0.3", lw=0.9, label="cross-correlation")
    colours = ["black", "tab:red", "tab:green", "tab:purple", "tab:brown"]
    for i, (offset, label) in enumerate(markers):
        ax.axvline(offset, color=colours[i % len(colours)], lw=1.3, ls="-" if i == 0 else "--", label=label)
    ax.set_xlabel("offset (s): audio_time = motion_time + offset")
    ax.set_ylabel("normalised correlation")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=7)
    return save_png(fig, out)


def feature_heatmap(
    values: np.ndarray,
    start_s: float,
    end_s: float,
    out: str | Path | BinaryIO,
    *,
    y_extent: tuple[float, float],
    ylabel: str,
    colorbar_label: str = "feature value",
    title: str = "Audio features",
) -> str | Path | BinaryIO:
    """Audio features [B, C] as a heat map: B bins or bands from ``y_extent[0]`` (bottom) to
    ``y_extent[1]`` (in the unit ``ylabel`` names), C columns evenly over ``start_s``..``end_s``
    seconds."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 3.0))
    image = ax.imshow(
        values, origin="lower", aspect="auto", cmap="magma", extent=(start_s, end_s, *y_extent), interpolation="nearest"
    )
    fig.colorbar(image, ax=ax, label=colorbar_label, pad=0.01)
    ax.set_xlabel("time (s, dataset clock)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    return save_png(fig, out)


def target_distributions(
    values: Sequence[np.ndarray],
    names: Sequence[str],
    bounds: tuple[float, float],
    out: str | Path | BinaryIO,
    *,
    title: str = "Target distributions",
    unit: str = "normalised value",
) -> str | Path | BinaryIO:
    """One box per component of its values (a [n_c] array each): quartiles as the box, the median
    as a black bar and a whisker from the minimum to the maximum, so anything beyond ``bounds``
    shows; red where some value lies outside ``bounds``, which are drawn as dashed lines. A
    component without values gets no box."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(max(6.0, 0.13 * len(names) + 1.5), 3.6))
    x = np.arange(len(names))
    stats = np.array([np.percentile(v, [0, 25, 50, 75, 100]) if len(v) else np.full(5, np.nan) for v in values])
    lo, hi = bounds
    colour = np.where((stats[:, 0] < lo) | (stats[:, 4] > hi), "tab:red", "tab:blue")
    ax.vlines(x, stats[:, 0], stats[:, 4], colors=colour, lw=0.8, label="minimum to maximum")
    ax.bar(x, stats[:, 3] - stats[:, 1], bottom=stats[:, 1], width=0.6, color=colour, alpha=0.6, label="quartiles")
    ax.hlines(stats[:, 2], x - 0.3, x + 0.3, colors="black", lw=1.0, label="median")
    for i, b in enumerate(bounds):
        ax.axhline(b, color="black", ls="--", lw=1.0, label=f"normalisation bounds {lo:g}..{hi:g}" if i == 0 else None)
    ax.set_xticks(x, names, rotation=90, fontsize=6)
    ax.set_xlim(-0.7, len(names) - 0.3)
    ax.set_xlabel("target component")
    ax.set_ylabel(unit)
    ax.set_title(title)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    return save_png(fig, out)
