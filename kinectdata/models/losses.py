"""Training losses shared by the models (torch tensors; differentiable)."""

from __future__ import annotations


def masked_mse(prediction, target, mask):
    """Mean squared error over the valid entries (torch tensors; differentiable)."""
    mask = mask.to(prediction.dtype)
    return ((prediction - target) ** 2 * mask).sum() / mask.sum().clamp(min=1.0)


def masked_velocity_mse(prediction, target, mask):
    """Mean squared error of the frame-to-frame changes [B, L-1, D] of [B, L, D] sequences, over
    the entries valid in both frames (torch tensors; differentiable). Weighs the motion itself,
    which a pose loss lets a model trade for staying near the mean pose."""
    both = mask[:, 1:] & mask[:, :-1]
    return masked_mse(prediction[:, 1:] - prediction[:, :-1], target[:, 1:] - target[:, :-1], both)


def masked_velocity_l1(prediction, target, mask):
    """Mean absolute error of the frame-to-frame changes [B, L-1, D] of [B, L, D] sequences, over
    the entries valid in both frames (torch tensors; differentiable): the L1 form of
    :func:`masked_velocity_mse`, for models trained with L1."""
    both = (mask[:, 1:] & mask[:, :-1]).to(prediction.dtype)
    change = (prediction[:, 1:] - prediction[:, :-1]) - (target[:, 1:] - target[:, :-1])
    return (change.abs() * both).sum() / both.sum().clamp(min=1.0)
