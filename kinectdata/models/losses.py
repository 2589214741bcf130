"""Training losses shared by the models (torch tensors; differentiable)."""

from __future__ import annotations


def masked_mse(prediction, target, mask):
    """Mean squared error over the valid entries (torch tensors; differentiable)."""
    mask = mask.to(prediction.dtype)
    return ((prediction - target) ** 2 * mask).sum() / mask.sum().clamp(min=1.0)
