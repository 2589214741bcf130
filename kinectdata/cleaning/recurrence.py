"""The first-order recurrence ``y[t] = a[t] x[t] + (1 - a[t]) y[t-1]`` solved without a Python loop
per frame: the exponential smoothing under every causal low-pass here (the 1-euro filter's two).

Frames are taken in blocks of :data:`BLOCK`: inside a block, with ``g = 1 - a`` and ``C[t]`` the
product of ``g`` from the block's start to ``t``, ``y[t] = C[t] (y_start + sum_{k <= t} a[k] x[k] /
C[k])``, a cumulative product and a cumulative sum over all blocks at once; then each block's start
is carried from the block before (a loop over blocks, not frames). Blocks are short so that ``C``
stays far from underflow (``g`` is clipped at :data:`G_FLOOR`).
"""

from __future__ import annotations

import numpy as np

BLOCK = 32
"""Frames per block: 32 frames of the smallest ``g`` kept (1e-6) is 1e-192, inside float64's range."""
G_FLOOR = 1e-6
"""``1 - a`` below this is taken as this: the output then follows the input to within a millionth."""


def smooth(a: np.ndarray, x: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """``y[t] = a[t] x[t] + (1 - a[t]) y[t-1]`` from ``y[-1] = y0``, for every channel at once.

    Args:
        a: [T, ...] smoothing factors in 0..1 (1: take the sample; 0: hold the last output), shaped
            like ``x`` or broadcasting to it.
        x: [T, ...] samples (finite where ``a > 0``; where ``a == 0`` any finite value).
        y0: [...] the output before frame 0.

    Returns:
        [T, ...] float64 outputs.
    """
    x = np.asarray(x, dtype=np.float64)
    a = np.broadcast_to(np.asarray(a, dtype=np.float64), x.shape)
    T = x.shape[0]
    if T == 0:
        return x.copy()
    blocks = -(-T // BLOCK)
    pad = blocks * BLOCK - T
    g = np.clip(1.0 - a, G_FLOOR, 1.0)
    ax = a * x
    if pad:
        g = np.concatenate([g, np.ones((pad, *x.shape[1:]))])
        ax = np.concatenate([ax, np.zeros((pad, *x.shape[1:]))])
    g = g.reshape(blocks, BLOCK, *x.shape[1:])
    ax = ax.reshape(blocks, BLOCK, *x.shape[1:])
    carried = np.cumprod(g, axis=1)  # C[t] within each block
    own = carried * np.cumsum(ax / carried, axis=1)  # each block's output from a zero start
    out = np.empty_like(own)
    start = np.broadcast_to(np.asarray(y0, dtype=np.float64), x.shape[1:]).copy()
    for b in range(blocks):  # one step per block: its start is the block before's end
        out[b] = own[b] + carried[b] * start
        start = out[b, -1]
    return out.reshape(blocks * BLOCK, *x.shape[1:])[:T]
