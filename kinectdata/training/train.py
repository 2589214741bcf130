"""``train``: a registered model on a kinectdata dataset, deterministic and resumable.

The model (a :class:`~kinectdata.models.kind.ModelKind` of :mod:`kinectdata.models.registry`)
decides whether the dataset fits, the network, how a batch is fed (e.g. the yalta model's
configured feedback, the cdhc model's teacher forcing), the loss, and what is written at the end
besides ``model.pt`` (e.g. the yalta model's ``stream.ts``). Its output layer starts at the mean
training pose (maxabs-normalised positions are far from centred: a camera-space depth of 2.5 m
becomes about 0.88), the rest of the network at PyTorch's default initialisation. Each epoch goes over the
training split's windows (:class:`~kinectdata.dataset.windows.WindowDataset`) in a seeded random
order, in batches; after ``backward`` the gradient is clipped (if asked) and annealed Gaussian
noise is added (if asked); Adam steps. Then the validation split is scored (loss as in training,
and SMAPE free-running from each window's first true pose), one row is added to ``log.csv``, and
the checkpoint is rewritten atomically with everything needed to continue exactly: model,
optimiser, step, the batch-order and noise generators, history. ``resume=True`` continues a run
from its checkpoint and ends with the same weights as an uninterrupted run.

Under ``torchrun`` the same loop runs in every process on its share of each global batch, with
the network in DistributedDataParallel (:mod:`.distributed`); only rank 0 validates, logs and
writes files.
"""

from __future__ import annotations

import csv
import inspect
import io
import json
import math
import sys
import time
import warnings
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import torch
from torch.utils.data import DataLoader

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import ConfigError, KinectDataError, KinectDataWarning
from kinectdata.dataset.layout import is_copy
from kinectdata.dataset.windows import WindowDataset
from kinectdata.evaluation.listening import ALIVE_RANGE
from kinectdata.evaluation.metrics import smape
from kinectdata.features import feature_config, style_input_of
from kinectdata.inference.export import export_network, stream_metadata
from kinectdata.inference.smoothing import check_cutoff
from kinectdata.inference.turning import with_turning
from kinectdata.models.losses import Body, masked_rhythm_loss
from kinectdata.models.registry import check_fits, model_for_dataset, model_kind
from kinectdata.models.run import (
    CHECKPOINT,
    CONFIG,
    LOG,
    MODEL,
    dataset_summary,
    load_checkpoint,
    read_manifest,
    save_checkpoint,
    write_json,
)
from kinectdata.targets.facing import faced
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.sway import BAND_HZ as SWAY_BAND_HZ
from kinectdata.targets.sway import band_problem
from kinectdata.training.augment import (
    Facing,
    Mirror,
    SlowTravel,
    facing_windows,
    mirror_windows,
    silence_windows,
    silent_frame,
    without_slow_travel,
)
from kinectdata.training.config import TrainConfig
from kinectdata.training.distributed import (
    PaddedWindows,
    WindowSampler,
    World,
    check_replicas,
    from_main,
    per_rank_batch,
    process_group,
    replicate,
    share_of_batch,
    sum_over_ranks,
)
from kinectdata.training.figures import loss_curves
from kinectdata.training.sway import fit_run_sway
from kinectdata.training.turning import fit_dataset_drawn
from kinectdata.training.whole_songs import WholeSongs

LOG_FIELDS = [
    "epoch",
    "step",
    "train_loss",
    "val_loss",
    "val_smape",
    "val_rhythm",
    "val_energy",
    "seconds",
    "frames_per_second",
    "stopped",
    "kept",
]
"""``log.csv``'s columns; ``val_energy`` is the validation songs' energy run free over the real
motion's (:class:`~kinectdata.training.whole_songs.WholeSongs`; with ``keep="best"``); ``stopped`` is ``time budget`` on
the epoch that the time budget cut short; ``kept`` marks the epoch ``model.pt`` holds when the run
keeps its best (``TrainConfig.keep``)."""


MIN_STEPS = 300
"""Fewer optimiser steps than this in a whole run draw a :class:`TrainingWarning`: the learning
benchmark's models need about a thousand to follow the beat (docs/training.md)."""


class TrainingWarning(KinectDataWarning):
    """A run that will finish but is unlikely to learn (e.g. far too few optimiser steps)."""


def _style_tempo_kept(config: TrainConfig, manifest: dict[str, Any], dataset: Path, world: World) -> TrainConfig:
    """``config`` as the run keeps it: its ``style_tempo`` where the dataset's features hear the style
    and tell each style's tempo; else None, with a :class:`TrainingWarning` saying why (a model's
    default band on a corpus without styles, or a dataset built before the tempi were kept)."""
    part = style_input_of(feature_config(manifest["config"]["features"]))
    why = None
    if part is None or part.classifier is None:
        why = "its features hear no dance style (a *_style preset, from a corpus that gives its recordings' styles)"
    elif not part.classifier.tempi:
        why = "its build kept no tempo per style (built before they were kept: build it again)"
    if why is None:
        return config
    if world.main:
        warnings.warn(
            f"{dataset}: every song will be danced at its own tempo (no --style-tempo): {why}", TrainingWarning, 2
        )
    return config.replace(style_tempo=None)


def _warn_if_too_few_steps(windows: int, config: TrainConfig, world: World) -> None:
    per_epoch = math.ceil(windows / config.batch_size)
    total = per_epoch * config.epochs
    if total < MIN_STEPS and world.main:
        warnings.warn(
            f"this run takes {per_epoch} optimiser step{'s' if per_epoch != 1 else ''} per epoch, {total} in all "
            f"({windows} training windows of {config.sequence} frames, batches of {config.batch_size}, "
            f"{config.epochs} epochs): too few to learn to follow the music (a model needs about a thousand). "
            f"Give more data, --stride below --sequence (overlapping windows), a smaller --batch-size or more "
            f"--epochs (with --max-minutes as the limit)",
            TrainingWarning,
            stacklevel=3,
        )


RISING_EPOCHS = 3
"""A training or validation loss that rises this many epochs in a row draws a :class:`TrainingWarning`."""


def _losses(history: list[dict], key: str) -> list[float]:
    """A loss of each epoch (log rows), NaN where the row has none (no validation split, non-finite)."""
    return [float("nan") if r.get(key) is None else float(r[key]) for r in history]


def _ran_free(history: list[dict]) -> bool:
    """Whether the run measured its free runs (a free-running validation rhythm loss in some epoch)."""
    return any(math.isfinite(v) for v in _losses(history, "val_rhythm"))


def _rose(losses: list[float], n: int) -> bool:
    """Whether the last value ends the first run of ``n`` rises in a row (so a streak is said once)."""
    rising = [b > a for a, b in zip(losses[:-1], losses[1:])]  # False where either is NaN
    return len(rising) >= n and all(rising[-n:]) and (len(rising) == n or not rising[-n - 1])


def loss_warning(history: list[dict], lr: float) -> str | None:
    """What to say when, at the newest of the epochs so far (log rows), the training loss has just
    become non-finite or has just risen :data:`RISING_EPOCHS` epochs in a row, or the validation loss
    has just risen that many epochs in a row; else None. Said once per streak: on the epoch it starts.
    A run with the free-running loss is judged on its free-running figures (:func:`validation_warning`):
    its teacher-forced validation loss may rise while it learns to dance on its own."""
    losses = _losses(history, "train_loss")
    epoch, last = history[-1]["epoch"], losses[-1]
    lower = f"try --lr {lr / 10:g}"
    if not math.isfinite(last):
        if len(losses) > 1 and not math.isfinite(losses[-2]):
            return None
        return (
            f"the training loss is {last} at epoch {epoch}: the learning rate ({lr:g}) is probably too high, or the "
            f"data holds huge values (kinectdata verify, kinectdata inspect); {lower} or --clip-norm 1"
        )
    n = RISING_EPOCHS
    if _rose(losses, n):
        return (
            f"the training loss rose {n} epochs in a row ({losses[-n - 1]:.4g} at epoch {epoch - n} -> {last:.4g} at "
            f"epoch {epoch}): the learning rate ({lr:g}) may be too high; {lower} or --clip-norm 1"
        )
    val = _losses(history, "val_loss")
    if not _ran_free(history) and _rose(val, n):
        best = min(range(len(val)), key=lambda i: val[i] if math.isfinite(val[i]) else math.inf)
        return (
            f"the validation loss rose {n} epochs in a row ({val[-n - 1]:.4g} at epoch {epoch - n} -> {val[-1]:.4g} "
            f"at epoch {epoch}; lowest {val[best]:.4g} at epoch {history[best]['epoch']}): the model is fitting the "
            f"training recordings rather than the music; stop earlier (--epochs {history[best]['epoch']}), "
            f"{lower}, or add recordings (--augment-snr at build-dataset adds noisy copies)"
        )
    return None


WORSE_SMAPE_POINTS = 1.0
"""A free-running validation SMAPE this many percentage points above its best, reached while the
training loss at least halved since that best epoch, draws a :class:`TrainingWarning`."""


def validation_warning(history: list[dict]) -> str | None:
    """What to say when a free-running validation figure gets worse while the training loss falls:
    at the newest epoch, the free-running rhythm loss has just risen :data:`RISING_EPOCHS` epochs in
    a row while the training loss fell, or the free-running SMAPE has just become
    :data:`WORSE_SMAPE_POINTS` worse than its best epoch's while the training loss fell to half of
    that epoch's or less (the model fits the training dances frame by frame and runs worse on its
    own); else None. Said once per streak. A run that measures its free runs' rhythm
    (``val_rhythm``) is judged by that figure alone: its free-running loss matches how the real
    motion moves, not its poses, so its SMAPE may rise while it learns, and ``--keep best`` keeps the
    epoch by the rhythm figure (the SMAPE's advice to stop earlier would be wrong for it)."""

    smape, train = _losses(history, "val_smape"), _losses(history, "train_loss")

    def worse(i: int) -> int | None:
        seen = [k for k in range(i) if math.isfinite(smape[k])]
        if i < 1 or not seen or not math.isfinite(smape[i]) or not math.isfinite(train[i]):
            return None
        best = min(seen, key=lambda k: smape[k])
        return best if smape[i] - smape[best] >= WORSE_SMAPE_POINTS and train[i] <= train[best] / 2 else None

    last = len(history) - 1
    rhythm = _losses(history, "val_rhythm")
    if _rose(rhythm, RISING_EPOCHS) and train[-1] < train[-RISING_EPOCHS - 1]:
        low = min((k for k in range(last + 1) if math.isfinite(rhythm[k])), key=lambda k: rhythm[k])
        n, first = RISING_EPOCHS, history[-RISING_EPOCHS - 1]["epoch"]
        return (
            f"the free-running validation rhythm loss rose {n} epochs in a row ({rhythm[-n - 1]:.4g} at epoch "
            f"{first} -> {rhythm[-1]:.4g} at epoch {history[-1]['epoch']}) while the training loss fell: on its own "
            f"the model dances less like the real dancers; its best epoch is {history[low]['epoch']} "
            f"({rhythm[low]:.4g}), which --keep best keeps"
        )
    if _ran_free(history):
        return None
    best = worse(last)
    if best is None or (last > 0 and worse(last - 1) is not None):
        return None
    return (
        f"the free-running validation SMAPE is {smape[last]:.2f} % at epoch {history[last]['epoch']}, worse than its "
        f"{smape[best]:.2f} % at epoch {history[best]['epoch']}, while the training loss fell from {train[best]:.4g} "
        f"to {train[last]:.4g}: the model fits the training dances frame by frame but runs worse on its own; "
        f"stop earlier (--epochs {history[best]['epoch']}) or give it its own motion to learn from (docs/training.md, "
        '"Learning real dance")'
    )


def ending_warning(history: list[dict], lr: float) -> str | None:
    """What to say when a finished run's training or validation loss ended above where it started
    (its first epoch's); else None. A run with the free-running loss is judged on its free-running
    validation rhythm loss: its teacher-forced validation loss can sit where it started while it
    learns to dance on its own (a model predicting the change from the previous pose copies that
    pose from its first epoch)."""
    if len(history) < 2:
        return None
    said = []
    free = _ran_free(history)
    validation = ("val_rhythm", "free-running validation rhythm") if free else ("val_loss", "validation")
    for key, name in (("train_loss", "training"), validation):
        losses = _losses(history, key)
        first, last = losses[0], losses[-1]
        if math.isfinite(first) and (last > first or math.isinf(last)):
            said.append(
                f"the {name} loss ended above where it started ({first:.4g} at epoch {history[0]['epoch']} -> "
                f"{last:.4g} at epoch {history[-1]['epoch']})"
            )
    if not said:
        return None
    return (
        f"{' and '.join(said)}: this run did not learn; the learning rate ({lr:g}) is probably too high: "
        f"try --lr {lr / 10:g} or --clip-norm 1 (log.csv and loss.png show each epoch)"
    )


@contextmanager
def _deterministic():
    previous = torch.are_deterministic_algorithms_enabled(), torch.is_deterministic_algorithms_warn_only_enabled()
    _set_deterministic(True, warn_only=True)
    try:
        yield
    finally:
        _set_deterministic(*previous)


def _set_deterministic(mode: bool, warn_only: bool) -> None:
    """``torch.use_deterministic_algorithms``, without importing TorchInductor's configuration
    (1.4 s of each training process's start) when nothing imported it: the flag it sets there is
    read only by ``torch.compile``, which kinectdata does not use."""
    if "torch._inductor.config" in sys.modules or not hasattr(torch._C, "_set_deterministic_algorithms"):
        torch.use_deterministic_algorithms(mode, warn_only=warn_only)
    else:
        torch._C._set_deterministic_algorithms(mode, warn_only=warn_only)


def native_bfloat16(device: torch.device) -> bool:
    """Whether ``device`` computes bfloat16 natively: a CPU with AVX-512 BF16, a CUDA device that
    supports it. Elsewhere torch emulates it, slower than float32. (torch names the CPU's check
    privately: a torch without it is taken to have none.)"""
    if device.type == "cuda":
        return torch.cuda.is_bf16_supported()
    return device.type == "cpu" and getattr(torch.cpu, "_is_avx512_bf16_supported", lambda: False)()


def _forward_precision(precision: str, device: torch.device):
    """The context the training step's forward pass runs in: ``torch.autocast`` to bfloat16 for
    ``precision`` ``bfloat16`` where the device has it natively (else float32, with a warning)."""
    wanted = precision == "bfloat16"
    if wanted and not native_bfloat16(device):
        warnings.warn(
            f"--precision bfloat16: this {device.type.upper()} has no native bfloat16 arithmetic (emulated, it "
            "would be slower than float32): training in float32",
            TrainingWarning,
            stacklevel=3,
        )
        wanted = False
    return torch.autocast(device.type, dtype=torch.bfloat16, enabled=wanted)


def _after_context(predict: Callable) -> Callable:
    """A kind's ``predict`` or ``predict_free`` as ``f(net, audio, previous, settings, context)``,
    giving the frames after a window's context. A kind written before they took ``context``
    (``predict(net, audio, previous, settings)``) still trains: its whole window's outputs are cut
    here. Its signature is read once, not every step."""
    if "context" in inspect.signature(predict).parameters:
        return predict

    def cut(net, audio, previous, settings, context):
        out = predict(net, audio, previous, settings)
        return tuple(x[:, context:] for x in out) if isinstance(out, tuple) else out[:, context:]

    return cut


def _start_pose(dataset: Path, manifest: dict[str, Any], facing: bool = False) -> list[float]:
    """Mean normalised pose of the training split's recordings (valid values; 0 where a component
    never is): the output layer's initial bias and the first "previous pose" when generating. With
    ``facing`` (a run that learns its poses facing one way) each pose is faced first
    (:func:`kinectdata.targets.facing.faced`): averaged over the ways the dancers faced, the arms of
    the mean pose would meet at the body's axis."""
    total = np.zeros(manifest["target_dim"])
    count = np.zeros(manifest["target_dim"])
    if facing:
        spec = TargetSpec.from_dict(manifest["config"]["target"])
        norm = Normalizer.from_dict(manifest["normalisation"])
    for r in manifest["recordings"]:
        if r["split"] != "train" or is_copy(r):
            continue
        with h5py.File(dataset / r["shard"], "r") as f:
            rows = slice(r["start"], r["start"] + r["frames"])
            mask = f["mask"][rows]
            current = f["current"][rows].astype(np.float64)
        if facing:
            current = norm.apply(faced(norm.invert(current, spec), spec)[0])
        total += np.where(mask, current, 0.0).sum(axis=0)
        count += mask.sum(axis=0)
    return (total / np.maximum(count, 1)).tolist()


RESUMABLE_CHANGES = ("epochs", "device", "max_minutes")
"""Settings a resumed run may change: none alters what the finished epochs computed."""


def _resumed_config(run: Path, saved: dict[str, Any], asked: TrainConfig | None) -> TrainConfig:
    """The configuration to resume with: the run's own, with only epochs and device changeable."""
    own = TrainConfig.from_dict(saved)
    if asked is None:
        return own
    differ = [
        f"{k} {mine!r} (the run's: {theirs!r})"
        for k, mine, theirs in asked.differences(own)
        if k not in RESUMABLE_CHANGES
    ]
    if differ:
        raise KinectDataError(
            f"{run}: cannot resume with other settings: {'; '.join(differ)}; only "
            f"{' and '.join(RESUMABLE_CHANGES)} may change"
        )
    return asked


def _batches(windows: WindowDataset, config: TrainConfig) -> DataLoader:
    """The windows in order, in batches of ``batch_size`` (validation). Its own generator: validating
    on rank 0 alone leaves every rank's global one (cdhc's dropout) alike."""
    return DataLoader(windows, batch_size=config.batch_size, generator=torch.Generator(), num_workers=0)


def _training_batches(
    windows: WindowDataset,
    config: TrainConfig,
    generator: torch.Generator,
    world: World,
    weights: np.ndarray | None = None,
) -> DataLoader:
    """This rank's share of each global batch of ``batch_size`` windows, shuffled by ``generator``
    (drawn by ``weights``, [windows], when given: ``config.balance``'s)."""
    padded = PaddedWindows(windows)
    return DataLoader(
        padded,
        batch_size=per_rank_batch(config.batch_size, world),
        sampler=WindowSampler(padded, world, generator, weights),
        generator=generator,
        num_workers=0,
        drop_last=False,
    )


def _add_gradient_noise(
    params: list[torch.nn.Parameter], step: int, config: TrainConfig, generator: torch.Generator
) -> None:
    if config.noise_eta <= 0:
        return
    sigma = math.sqrt(config.noise_eta / (1 + step) ** config.noise_gamma)
    for p in params:
        if p.grad is not None:
            p.grad.add_(torch.randn(p.grad.shape, generator=generator).to(p.grad.device) * sigma)


def validate(
    net: torch.nn.Module,
    windows: WindowDataset,
    config: TrainConfig,
    device: torch.device,
    start_pose: list[float] | None = None,
    fps: float = 30.0,
    body: Body | None = None,
    context: int = 0,
    travel: SlowTravel | None = None,
    facing: Facing | None = None,
) -> tuple[float, float, float]:
    """(loss as in training, SMAPE in % free-running, the free-running rhythm loss) over a split's
    windows: the model runs free from each window's first true pose; the rhythm loss
    (:func:`~kinectdata.models.losses.masked_rhythm_loss`) compares how much and how often
    it moves with the real motion, whatever the phase. ``start_pose`` [D] stands in for masked
    previous values (as the model's ``fill_previous`` says); the first ``context`` frames of each
    window are input only (``TrainConfig.context``); ``travel``, ``facing``: the root's slow travel
    taken out of the windows and the poses turned to face one way, as training does for a run that
    draws its travel and turning (:func:`_drawn_out`)."""
    if len(windows) == 0:
        return float("nan"), float("nan"), float("nan")
    kind = model_kind(config.model)
    net.eval()
    losses, weights, generated, real, masks = [], [], [], [], []
    with torch.no_grad():
        for batch in _batches(windows, config):
            batch = _drawn_out(batch, travel, facing)
            audio, pose, mask = batch["audio"].to(device), batch["pose"].to(device), batch["mask"].to(device)
            previous = batch["previous"].to(device)
            if start_pose is not None:
                previous = kind.fill_previous(previous, batch["previous_mask"].to(device), start_pose)
            pred = kind.predict(net, audio, previous, config.settings)
            free = kind.free_batch(net, audio, previous, pred, config.settings)[:, context:]
            pred, pose, mask = pred[:, context:], pose[:, context:], mask[:, context:]
            losses.append(float(kind.loss(net, pred, pose, mask, config.settings)))
            weights.append(float(mask.sum()))
            generated.append(free)
            real.append(pose.cpu().numpy())
            masks.append(mask.cpu().numpy())
    net.train()
    loss = float(np.average(losses, weights=weights))
    generated, real, masks = np.concatenate(generated), np.concatenate(real), np.concatenate(masks)
    if body is not None:  # the free runs are numpy arrays: measured on the CPU
        body = body.to("cpu")
    rhythm = float(
        masked_rhythm_loss(
            torch.from_numpy(np.asarray(generated, np.float32)),
            torch.from_numpy(np.asarray(real, np.float32)),
            torch.from_numpy(masks),
            fps,
            body,
            config.rhythm_weights,
            component_floor=config.component_floor,
        )
    )
    return loss, smape(generated, real, masks), rhythm


def _drawn_out(batch: dict[str, Any], travel: SlowTravel | None, facing: Facing | None) -> dict[str, Any]:
    """A batch without what the run draws at generation: the root's slow travel
    (:func:`~kinectdata.training.augment.without_slow_travel`) and, with ``facing``, where the body
    faces (:func:`~kinectdata.training.augment.facing_windows`)."""
    if travel is not None:
        batch = without_slow_travel(batch, travel)
    if facing is not None:
        batch = facing_windows(batch, facing)
    return batch


def _body(manifest: dict[str, Any], device: torch.device) -> Body | None:
    """What the free-running loss needs to measure a motion's body: the target's positioned bones,
    the normalisation to undo, its feet (:func:`_feet`) and root; None when the target positions
    no bone."""
    from kinectdata.targets.specs import TargetSpec

    spec = TargetSpec.from_dict(manifest["config"]["target"])
    bones = spec.position_bones(root_centred=bool(manifest["config"].get("root_centre")))
    if not bones or spec.position_scale != "none":
        return None  # no bone, or coordinates scaled per recording (no metres to measure in)
    norm = Normalizer.from_dict(manifest["normalisation"])

    def tensor(values):
        return torch.tensor(values, dtype=torch.float32, device=device)

    root = spec.positions.index(spec.root) if spec.root in spec.positions else None
    feet = None if root is None else _feet(spec)
    return Body(
        bones=bones,
        scale=tensor(norm.scale),
        offset=tensor(norm.offset),
        dims=spec.dimensions,
        feet=None if feet is None else torch.tensor(feet, dtype=torch.float32, device=device),
        root=root,
        centred=bool(manifest["config"].get("root_centre")),
    )


def _mirror(dataset: Path, manifest: dict[str, Any]) -> Mirror:
    """The dataset's :class:`Mirror`; ConfigError naming the dataset when its targets have none."""
    try:
        return Mirror.of_dataset(manifest)
    except ConfigError as e:
        raise ConfigError(f"{dataset}: its windows cannot be mirrored: {e}") from None


def _feet(spec) -> np.ndarray | None:
    """[4, P] weights of the SMPL-24 joints EDGE's foot contact score reads (left ankle and foot,
    right ankle and foot: :mod:`kinectdata.evaluation.metrics.foot_contact`) over the target's P
    positioned joints, from its joint set's SMPL-24 mapping; None when the set has no mapping, or a
    foot needs a joint the target does not position (then the free-running loss has no foot term)."""
    from kinectdata.core.joint_mapping import load_smpl24_mapping
    from kinectdata.evaluation.metrics.foot_contact import LEFT_FOOT, RIGHT_FOOT

    if spec.dimensions != 3:
        return None
    try:
        mapping = load_smpl24_mapping(spec.joints)
    except KinectDataError:
        return None
    rows = mapping.weights[[*LEFT_FOOT, *RIGHT_FOOT]]  # [4, J]
    columns = [spec.joints.index(name) for name in spec.positions]
    if np.delete(rows, columns, axis=1).any():
        return None
    return rows[:, columns]


def _energy(net: torch.nn.Module, kind, songs: WholeSongs | None) -> float:
    """The validation songs' energy ratio run free (NaN without songs to measure), by ``kind``: the
    run's model kind with its turning and travel drawn (:func:`~kinectdata.inference.turning.with_turning`),
    so that it is the energy ``evaluate`` gives its alive verdict."""
    return float("nan") if songs is None else songs.energy_ratio(net, kind)


def _alive(row: dict) -> bool:
    """Whether an epoch's validation songs, run whole, moved within the alive verdict's range of
    the real energy (:data:`~kinectdata.evaluation.listening.ALIVE_RANGE`)."""
    energy = row.get("val_energy")
    return energy is not None and ALIVE_RANGE[0] <= energy <= ALIVE_RANGE[1]


def _keep_score(row: dict, energy_weight: float) -> float:
    """An epoch's score for the keep rule (lower is better): its free-running validation rhythm
    loss times ``exp(energy_weight * |ln val_energy|)``, the energy's distance from the real
    motion's in either direction (the loss alone with weight 0 or no energy logged; infinite for
    an epoch that does not move at all)."""
    energy = row.get("val_energy")
    if energy_weight == 0 or energy is None:
        return row["val_rhythm"]
    if not energy > 0:  # still: as far from the real motion as can be
        return math.inf
    return row["val_rhythm"] * math.exp(energy_weight * abs(math.log(energy)))


def _better(history: list[dict], energy_weight: float = 0.0) -> bool:
    """Whether the newest epoch is the one to keep so far: its score (:func:`_keep_score`: the
    free-running validation rhythm loss, the energy counted by ``energy_weight``) is the lowest
    (the first finite one counts) among the epochs whose validation songs are alive
    (:func:`_alive`), or among all of them while none is. The rhythm loss alone can prefer a
    nearly still epoch to one that moves at the wrong moments (the cdhc model on tang2018 kept one
    at 0.05 x the real energy: docs/notebook/2026-11-real-dance.md); an epoch that moves always wins over one that
    does not."""
    last = history[-1]
    if last.get("val_rhythm") is None:
        return False
    rivals = [r for r in history[:-1] if r.get("val_rhythm") is not None]
    if _alive(last):
        rivals = [r for r in rivals if _alive(r)]
    elif any(_alive(r) for r in rivals):
        return False
    score = _keep_score(last, energy_weight)
    return all(score < _keep_score(r, energy_weight) for r in rivals)


def _averager(net: torch.nn.Module, decay: float, state: dict[str, Any] | None):
    """The moving average of ``net``'s weights and buffers a run with ``weight_average`` keeps
    (:class:`torch.optim.swa_utils.AveragedModel` with decay ``decay`` per step), restored from a
    resumed checkpoint's; None without one."""
    if decay == 0:
        return None
    from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

    average = AveragedModel(net, multi_avg_fn=get_ema_multi_avg_fn(decay), use_buffers=True)
    if state is not None and "average" in state:
        average.load_state_dict(state["average"])
    return average


def _write_log(run: Path, history: list[dict]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=LOG_FIELDS, lineterminator="\n")
    writer.writeheader()
    for row in history:
        writer.writerow({k: row.get(k) for k in LOG_FIELDS})
    with atomic_output(run / LOG) as tmp:
        tmp.write_text(buffer.getvalue())


def read_log(run: Path) -> list[dict[str, Any]]:
    """A finished run's ``log.csv`` as the rows :func:`train` returned: ``epoch`` and ``step`` ints,
    ``stopped`` and ``kept`` strings or None (``kept`` is ``best`` on the epoch ``model.pt`` holds),
    the other columns floats (None where empty, as ``val_energy`` of a run that does not keep its
    best)."""
    path = Path(run) / LOG
    try:
        rows = list(csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"))))
    except OSError as exc:
        raise KinectDataError(f"{path}: cannot read the run's log: {exc.strerror or exc}") from None
    history = []
    for number, row in enumerate(rows, start=2):
        try:
            entry: dict[str, Any] = {"epoch": int(row["epoch"]), "step": int(row["step"])}
            for key in LOG_FIELDS:
                if key in ("stopped", "kept"):
                    entry[key] = row.get(key) or None
                elif key not in entry:
                    entry[key] = float(row[key]) if row.get(key) else None
        except (KeyError, TypeError, ValueError) as exc:
            raise KinectDataError(f"{path}, line {number}: not a row of a run's log ({exc})") from None
        history.append(entry)
    return history


def _tensorboard(run: Path):
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError:  # tensorboard is optional
        return None
    return SummaryWriter(str(run / "tensorboard"))


def train(
    dataset: str | Path,
    out: str | Path,
    config: TrainConfig | None = None,
    *,
    resume: bool = False,
    stop_after: int | None = None,
    progress: Callable[[dict], None] | None = None,
    epoch_metrics: Callable[[torch.nn.Module], dict[str, Any]] | None = None,
    checksums: bool = True,
) -> list[dict]:
    """Train a registered model (``config.model``) on a dataset folder into the run folder ``out``.

    Args:
        dataset: a folder written by ``build-dataset``.
        out: the run folder (created; must not hold a run unless ``resume``).
        config: :class:`TrainConfig` (default: the dataset's model with its defaults; when
            resuming, the run's own).
        resume: continue the run in ``out`` from its checkpoint, on the same dataset. Only
            ``epochs`` (to train longer) and ``device`` may differ from the run's settings.
        stop_after: stop after this epoch (as an interruption would; the run stays resumable).
        progress: called with each epoch's log row.
        epoch_metrics: called after each epoch's validation with the network (in evaluation mode,
            on the main process); the values it returns are added to the epoch's row (e.g. beat
            following measured on held-out songs, as ``benchmarks/bench_learning.py`` does).
        checksums: verify the shards' SHA-256 before training (the folder's layout, sizes and
            manifest are always verified): False saves about 1 s per GB.

    Returns:
        The log rows of all epochs so far.
    """
    dataset, run = Path(dataset), Path(out)
    manifest = read_manifest(dataset, checksums=checksums)
    state = None
    if resume:
        state = load_checkpoint(run / CHECKPOINT)
        saved = json.loads(state["config"])
        config = _resumed_config(run, saved["train"], config)
        if saved["dataset"]["build_key"] != manifest["build_key"]:
            raise KinectDataError(
                f"{run}: cannot resume on {dataset}: the run was trained on {saved['dataset']['path']} "
                f"(build key {saved['dataset']['build_key']}, this dataset's is {manifest['build_key']})"
            )
    config = config or TrainConfig(model_for_dataset(manifest))
    world = World.from_environment()
    per_rank_batch(config.batch_size, world)  # an indivisible batch is refused before anything starts
    kind = model_kind(config.model)
    check_fits(kind, manifest, dataset)
    mirror = _mirror(dataset, manifest) if config.mirror_share > 0 else None  # refused before anything starts
    model_config = kind.network_config(config.settings, manifest)
    stride = config.stride or config.sequence
    context = kind.context_frames(model_config) if config.context is None else config.context
    length = config.sequence + context  # the first `context` frames of a window: input only, no loss
    lead = context if config.song_starts else 0  # windows from each song's start, silence before it
    if resume:  # the network the run was started with, as its checkpoint holds it (a newer field's default)
        model_config = saved["model"]
    elif lead:
        model_config = kind.with_song_starts(model_config, lead)
    train_windows = WindowDataset(dataset, "train", length, stride, verify=False, lead=lead)  # verified above
    balance = None if config.balance is None else train_windows.balanced_weights(config.balance)
    val_windows = WindowDataset(dataset, "val", length, config.sequence, verify=False)
    if len(train_windows) == 0:
        with_context = f" ({config.sequence} + {context} of context)" if context else ""
        raise KinectDataError(f"{dataset}: no training window of {length} frames{with_context} (recordings too short?)")
    if config.smooth_hz is not None:
        try:
            check_cutoff(config.smooth_hz, float(manifest["config"]["fps"]))
        except ConfigError as exc:
            raise ConfigError(f"{dataset}: {exc} (--smooth-hz: a lower cutoff, or 0 for none)") from None
    unmeasurable = band_problem(SWAY_BAND_HZ, float(manifest["config"]["fps"])) if config.sway else ""
    if unmeasurable:
        raise ConfigError(f"{dataset}: --sway {unmeasurable}")
    if config.style_tempo is not None:
        config = _style_tempo_kept(config, manifest, dataset, world)
    if config.max_minutes is None:
        _warn_if_too_few_steps(len(train_windows), config, world)
    run_config = {
        "train": config.to_dict(),
        "model": model_config,
        "dataset": dataset_summary(dataset, manifest),
    }

    with process_group(world, config.resolved_device()) as device, _deterministic():
        torch.manual_seed(config.seed)
        net = kind.build(model_config).to(device)
        optimizer = torch.optim.Adam(net.parameters(), lr=config.lr)
        order = torch.Generator().manual_seed(config.seed + 1)
        noise = torch.Generator().manual_seed(config.seed + 2)
        augment = torch.Generator().manual_seed(config.seed + 3)  # silenced windows
        mirrored = torch.Generator().manual_seed(config.seed + 4)  # mirrored windows
        history: list[dict] = []
        step = 0
        best: dict[str, Any] | None = None  # the kept epoch's weights (keep="best")
        if state is not None:
            run_config["dataset"]["start_pose"] = saved["dataset"]["start_pose"]
            for drawn in ("turning", "travel", "drawn_by_metre"):  # as they were fitted when the run started
                if drawn in saved:
                    run_config[drawn] = saved[drawn]
            if world.main:
                write_json(run / CONFIG, run_config)  # with the new epochs or device, if changed
            net.load_state_dict(state["model"])
            optimizer.load_state_dict(state["optimizer"])
            order.set_state(state["order_rng"])
            noise.set_state(state["noise_rng"])
            if "augment_rng" in state:  # checkpoints written before windows were silenced have none
                augment.set_state(state["augment_rng"])
            if "mirror_rng" in state:  # nor had those written before windows were mirrored
                mirrored.set_state(state["mirror_rng"])
            if "best_model" in state:
                best = {"epoch": int(state["best_epoch"]), "model": state["best_model"]}
            torch.set_rng_state(state["torch_rng"])
            history, step = json.loads(state["history"]), int(state["step"])
            if len(history) > config.epochs:
                raise KinectDataError(f"{run}: has trained {len(history)} epochs already, more than {config.epochs}")
        else:
            if (run / CHECKPOINT).exists() or (run / MODEL).exists():
                raise KinectDataError(f"{run}: already holds a run; use --resume to continue it or another folder")
            run_config |= fit_dataset_drawn(
                dataset,
                manifest,
                run_config["dataset"],
                turning=config.turning,
                travel=config.travel,
                by_metre=config.by_metre,
            )
            # facing one way is for a run whose turning is drawn: targets that cannot be turned keep none
            faces = config.facing and "turning" in run_config
            run_config["dataset"]["start_pose"] = _start_pose(dataset, manifest, faces)
            kind.init_output(net, run_config["dataset"]["start_pose"])
            if world.main:
                run.mkdir(parents=True, exist_ok=True)
                write_json(run / CONFIG, run_config)
        run_config = json.loads(json.dumps(run_config))  # as config.json holds it
        start_pose = run_config["dataset"]["start_pose"]
        writer = _tensorboard(run) if world.main else None
        model = replicate(net, world, device)
        net.train()
        params = list(net.parameters())
        average = _averager(net, config.weight_average, state)
        judged = net if average is None else average.module  # what validation, the kept epoch and model.pt use
        fps = float(manifest["config"]["fps"])
        silent = silent_frame(manifest["config"]["features"], fps) if config.silence_share > 0 else None
        body = _body(manifest, device)
        travel = SlowTravel.of_dataset(manifest, fps) if "travel" in run_config else None  # it is drawn
        # facing one way is for a run whose turning is drawn: targets that cannot be turned keep none
        facing = Facing.of_dataset(manifest) if config.facing and "turning" in run_config else None
        drawn_kind = with_turning(kind, run_config)  # whole songs measured with what the run draws, as evaluate
        val_songs = (  # the kept epoch's condition: measured when the run keeps its best
            WholeSongs.of_split(dataset, manifest, "val", kind, run_config["dataset"], start_pose)
            if config.keep == "best"
            else None
        )
        forward_precision = _forward_precision(config.precision, device)
        predict, predict_free = _after_context(kind.predict), _after_context(kind.predict_free)
        deadline = None if config.max_minutes is None else time.monotonic() + 60 * config.max_minutes
        out_of_time = False
        for epoch in range(len(history) + 1, config.epochs + 1):
            started, frames, total, weight = time.perf_counter(), 0, 0.0, 0.0
            for batch in _training_batches(train_windows, config, order, world, balance):
                if deadline is not None and frames and from_main([float(time.monotonic() > deadline)], world)[0]:
                    out_of_time = True  # every rank stops at the same step: the main one decides
                    break
                if silent is not None:
                    batch = silence_windows(batch, silent, config.silence_share, augment, context)
                if mirror is not None:
                    batch = mirror_windows(batch, mirror, config.mirror_share, mirrored)
                batch = _drawn_out(batch, travel, facing)
                audio, pose, mask = batch["audio"].to(device), batch["pose"].to(device), batch["mask"].to(device)
                previous = kind.fill_previous(
                    batch["previous"].to(device), batch["previous_mask"].to(device), start_pose
                )
                if config.previous_noise > 0:  # torch's generator: seeded, and saved in the checkpoint
                    previous = previous + config.previous_noise * torch.randn(previous.shape).to(device)
                pose, mask = pose[:, context:], mask[:, context:]
                if config.free_weight > 0:
                    with forward_precision:
                        pred, free = predict_free(model, audio, previous, config.settings, context)
                    pred, free = pred.float(), free.float()
                    loss = kind.loss(net, pred, pose, mask, config.settings)
                    loss = loss + config.free_weight * masked_rhythm_loss(
                        free,
                        pose,
                        mask,
                        fps,
                        body,
                        config.rhythm_weights,
                        component_floor=config.component_floor,
                    )
                else:
                    with forward_precision:
                        pred = predict(model, audio, previous, config.settings, context)
                    loss = kind.loss(net, pred.float(), pose, mask, config.settings)
                valid = float(mask.sum())
                optimizer.zero_grad(set_to_none=True)
                (loss * share_of_batch(valid, world)).backward()
                if config.clip_norm is not None:
                    torch.nn.utils.clip_grad_norm_(params, config.clip_norm)
                _add_gradient_noise(params, step, config, noise)
                optimizer.step()
                if average is not None:
                    average.update_parameters(net)
                step += 1
                frames += pose.shape[0] * pose.shape[1]
                total += loss.item() * valid
                weight += valid
            total, weight, frames = sum_over_ranks([total, weight, frames], world)
            check_replicas(params, world, epoch)
            figures = (
                (
                    *validate(judged, val_windows, config, device, start_pose, fps, body, context, travel, facing),
                    _energy(judged, drawn_kind, val_songs),
                )
                if world.main
                else (0.0, 0.0, 0.0, 0.0)
            )
            val_loss, val_smape, val_rhythm, val_energy = from_main(list(figures), world)
            seconds = time.perf_counter() - started
            row = {
                "epoch": epoch,
                "step": step,
                "train_loss": total / max(weight, 1.0),
                "val_loss": val_loss if math.isfinite(val_loss) else None,
                "val_smape": val_smape if math.isfinite(val_smape) else None,
                "val_rhythm": val_rhythm if math.isfinite(val_rhythm) else None,
                "val_energy": val_energy if math.isfinite(val_energy) else None,
                "seconds": round(seconds, 3),
                "frames_per_second": round(frames / seconds, 1),
                "stopped": "time budget" if out_of_time else None,
            }
            if epoch_metrics is not None and world.main:
                judged.eval()
                with torch.no_grad():
                    row.update(epoch_metrics(judged))
                judged.train()
            history.append(row)
            if config.keep == "best" and world.main and _better(history, config.keep_energy_weight):
                best = {"epoch": epoch, "model": {k: v.detach().clone().cpu() for k, v in judged.state_dict().items()}}
            for said in (loss_warning(history, config.lr), validation_warning(history)) if world.main else ():
                if said:
                    warnings.warn(said, TrainingWarning, stacklevel=2)
            if world.main:  # the others keep no files
                _write_log(run, history)
                if writer is not None:
                    for key in ("train_loss", "val_loss", "val_smape", "val_rhythm", "val_energy"):
                        if row[key] is not None:
                            writer.add_scalar(key, row[key], epoch)
                save_checkpoint(
                    run / CHECKPOINT,
                    {
                        "model": net.state_dict(),
                        "optimizer": optimizer.state_dict(),
                        "step": step,
                        "order_rng": order.get_state(),
                        "noise_rng": noise.get_state(),
                        "augment_rng": augment.get_state(),
                        "mirror_rng": mirrored.get_state(),
                        "torch_rng": torch.get_rng_state(),
                        **({} if best is None else {"best_epoch": best["epoch"], "best_model": best["model"]}),
                        **({} if average is None else {"average": average.state_dict()}),
                        "history": json.dumps(history),
                        "config": json.dumps(run_config),
                    },
                )
                if progress:
                    progress(row)
            if stop_after is not None and epoch >= stop_after and epoch < config.epochs:
                return history
            if out_of_time:
                break
        if writer is not None:
            writer.close()
    if not world.main:
        return history
    said = ending_warning(history, config.lr)
    if said:
        warnings.warn(said, TrainingWarning, stacklevel=2)
    title = f"{run.name}: {kind.describe(config.settings)}"
    loss_curves(history, run / "loss.png", title=title, loss_name=kind.loss_name(config.settings))
    net = judged.cpu().eval()
    if best is not None:  # keep="best": model.pt and the exports hold that epoch
        net.load_state_dict(best["model"])
        for row in history:
            row["kept"] = "best" if row["epoch"] == best["epoch"] else None
        _write_log(run, history)
    if config.sway:  # the final weights' sway along the floor against the dancers'
        with torch.no_grad():
            sway = fit_run_sway(net, kind, dataset, manifest, run_config)
        if sway is not None:
            run_config["sway"] = sway.to_dict()
            write_json(run / CONFIG, run_config)
    save_checkpoint(run / MODEL, {"model": net.state_dict(), "config": json.dumps(run_config)})
    for name, fmt in kind.run_exports.items():  # e.g. the yalta model's stream.ts, for robots
        export_network(net, run / name, fmt, metadata=stream_metadata(run_config, kind=kind), kind=kind)
    return history


def normalizer_of(run_config: dict[str, Any]) -> Normalizer:
    return Normalizer.from_dict(run_config["dataset"]["normalisation"])
