"""Training on several processes: ``torchrun`` and DistributedDataParallel (DDP).

Under ``torchrun`` (``RANK``, ``WORLD_SIZE`` and ``LOCAL_RANK`` in the environment) each process
trains a replica of the network: :func:`process_group` joins the group (gloo on CPU, nccl on
CUDA, one GPU per process), :func:`replicate` wraps the network in DDP, which averages the
gradients in ``backward``. Every step takes one global batch of ``batch_size`` windows, dealt out
to the ranks by :class:`WindowSampler` (``batch_size / world size`` each), so a step sees the same
windows as one process would. What every rank must agree on is seeded identically on all of them:
the initial weights (DDP also copies rank 0's at the start), the batch order and the gradient
noise, so the replicas take identical optimiser steps; :func:`check_replicas` verifies that after
each epoch.

Batch normalisation is where DDP differs from one process: each rank normalises with the
statistics of its own part of the batch, and DDP copies rank 0's running statistics to the
others before each forward (``broadcast_buffers``), so the running statistics (used in evaluation)
come from rank 0's windows only. Losses therefore match one process closely, not exactly.

With one process (no ``torchrun``, or ``WORLD_SIZE`` 1) nothing here communicates and the windows
come in exactly the order a plain shuffled ``DataLoader`` gives.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import Dataset, DistributedSampler

from kinectdata.core.errors import KinectDataError


@dataclass(frozen=True)
class World:
    """This process's place among the training processes: ``rank`` of ``size``, ``local_rank`` on its machine."""

    rank: int = 0
    size: int = 1
    local_rank: int = 0

    @classmethod
    def from_environment(cls, environ: Mapping[str, str] = os.environ) -> World:
        """The world torchrun describes in ``RANK``, ``WORLD_SIZE`` and ``LOCAL_RANK``; one process without them."""
        if "WORLD_SIZE" not in environ:
            return cls()
        try:
            world = cls(int(environ["RANK"]), int(environ["WORLD_SIZE"]), int(environ.get("LOCAL_RANK", "0")))
        except (KeyError, ValueError) as exc:
            raise KinectDataError(
                f"WORLD_SIZE is set ({environ['WORLD_SIZE']!r}) but RANK / LOCAL_RANK are missing or not integers "
                f"({exc}): start distributed training with torchrun"
            ) from None
        if not 0 <= world.rank < world.size:
            raise KinectDataError(f"RANK {world.rank} is outside 0..{world.size - 1} (WORLD_SIZE {world.size})")
        return world

    @property
    def main(self) -> bool:
        """The process that logs and writes the run's files (rank 0)."""
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.size > 1


@contextmanager
def process_group(world: World, device: torch.device) -> Iterator[torch.device]:
    """Join the process group (gloo on CPU, nccl on CUDA) for the duration; yields this rank's
    device (``cuda:LOCAL_RANK`` on CUDA). A group the caller started already is used and kept."""
    if not world.distributed:
        yield device
        return
    if device.type == "cuda":
        device = torch.device("cuda", world.local_rank)
        torch.cuda.set_device(device)
    if dist.is_initialized():
        yield device
        return
    try:
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    except (ValueError, RuntimeError) as exc:
        raise KinectDataError(
            f"cannot join the {world.size} training processes ({exc}): start them with torchrun"
        ) from exc
    try:
        yield device
    finally:
        dist.destroy_process_group()


def per_rank_batch(batch_size: int, world: World) -> int:
    """Windows per rank and step: ``batch_size / world.size``; KinectDataError when it does not divide."""
    if batch_size % world.size:
        raise KinectDataError(
            f"batch size {batch_size} does not divide among {world.size} processes: give a multiple of {world.size} "
            "(the batch size is global, the same as one process's)"
        )
    return batch_size // world.size


def replicate(net: torch.nn.Module, world: World, device: torch.device) -> torch.nn.Module:
    """``net`` wrapped in DDP (gradients averaged over the ranks in ``backward``), or ``net`` itself alone."""
    if not world.distributed:
        return net
    return DistributedDataParallel(net, device_ids=[device.index] if device.type == "cuda" else None)


class PaddedWindows(Dataset):
    """A window dataset whose indices ``n .. 2n-1`` repeat windows ``0 .. n-1`` with their pose mask
    cleared: the padding :class:`WindowSampler` deals out so every rank has as many windows adds
    nothing to a masked loss or its gradient."""

    def __init__(self, windows: Dataset):
        self.windows = windows

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, i: int) -> dict[str, Any]:
        if i < len(self.windows):
            return self.windows[i]
        item = self.windows[i - len(self.windows)]
        return item | {"mask": torch.zeros_like(item["mask"])}


class WindowSampler(DistributedSampler):
    """This rank's share of each epoch's shuffled windows.

    Each epoch draws one permutation of the n windows from ``generator`` (the same on every rank:
    same seed, and restored from the checkpoint on resume), pads it to a multiple of the world
    size with ``n + i`` for the first windows i (masked copies in :class:`PaddedWindows`) and gives
    rank r the entries r, r + size, r + 2 size, ... With ``weights`` ([n], :attr:`TrainConfig.balance
    <kinectdata.training.config.TrainConfig>`) the n entries are drawn with replacement by them
    instead of permuted. So the ranks' k-th batches of
    ``batch_size / size`` windows together are the one-process run's k-th batch, and with one
    process the order is exactly a shuffled ``DataLoader``'s with the same generator.

    Unlike torch's DistributedSampler, whose order follows ``seed + epoch`` (``set_epoch``), the
    order comes from the run's own generator, which advances each epoch: runs keep the order they
    had before distributed training existed, and ``set_epoch`` is not needed.
    """

    def __init__(
        self, windows: PaddedWindows, world: World, generator: torch.Generator, weights: np.ndarray | None = None
    ):
        super().__init__(windows, num_replicas=world.size, rank=world.rank, shuffle=True, drop_last=False)
        self.generator = generator
        self.weights = None if weights is None else torch.as_tensor(weights, dtype=torch.float64)

    def __iter__(self) -> Iterator[int]:
        n = len(self.dataset)
        if self.weights is not None:  # balanced: n windows drawn with replacement by their weights
            order = torch.multinomial(self.weights, n, replacement=True, generator=self.generator).tolist()
        else:
            # drawn as torch's RandomSampler draws (a shuffled DataLoader's): when iteration starts, after
            # the DataLoader's base seed, and then an empty remainder that still advances the generator
            order = torch.randperm(n, generator=self.generator).tolist()
            torch.randperm(n, generator=self.generator)
        padding = self.total_size - n
        order += [n + i for i in (order * math.ceil(padding / n))[:padding]] if padding else []
        yield from order[self.rank : self.total_size : self.num_replicas]


def _collective(values: list[float]) -> torch.Tensor:
    """``values`` as a float64 tensor where the backend communicates: nccl only moves GPU tensors."""
    device = torch.device("cuda", torch.cuda.current_device()) if dist.get_backend() == "nccl" else None
    return torch.tensor(values, dtype=torch.float64, device=device)


def sum_over_ranks(values: list[float], world: World) -> list[float]:
    """Each value summed over the ranks (float64); the values themselves alone."""
    if not world.distributed:
        return values
    tensor = _collective(values)
    dist.all_reduce(tensor)
    return tensor.tolist()


def share_of_batch(valid: float, world: World) -> float:
    """The factor for this rank's masked-mean loss, ``size * valid / valid over all ranks`` (1 alone):
    DDP averages the ranks' gradients, and so weighted that average is the gradient of the masked
    mean over the whole global batch, as one process computes it, however the valid values fall."""
    if not world.distributed:
        return 1.0
    (everywhere,) = sum_over_ranks([valid], world)
    return world.size * valid / everywhere if everywhere > 0 else 0.0


def from_main(values: list[float], world: World) -> list[float]:
    """Rank 0's values on every rank (float64; NaN passes)."""
    if not world.distributed:
        return values
    tensor = _collective(values)
    dist.broadcast(tensor, src=0)
    return tensor.tolist()


def check_replicas(params: list[torch.nn.Parameter], world: World, epoch: int) -> None:
    """KinectDataError unless every rank's parameters are bit for bit rank 0's: replicas that drift
    apart (a rank seeded differently, a nondeterministic kernel) would train different models."""
    if not world.distributed:
        return
    flat = torch.cat([p.detach().reshape(-1) for p in params])
    low, high = flat.clone(), flat.clone()
    dist.all_reduce(low, op=dist.ReduceOp.MIN)
    dist.all_reduce(high, op=dist.ReduceOp.MAX)
    differ = int(((low != high) & ~(low.isnan() & high.isnan())).sum())  # NaN everywhere is not a difference
    if differ:
        raise KinectDataError(
            f"after epoch {epoch} the {world.size} training processes hold different weights ({differ} of "
            f"{flat.numel()} values differ): their random generators or inputs are not the same"
        )
