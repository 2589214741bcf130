"""Changes made to training windows as they are drawn (the dataset on disk stays as built).

:func:`silence_windows`: in a share of the windows the music stops at a random frame and the
dancer holds the pose it had there. Dance corpora hold no silence (the music plays from the first
frame of a dance to its last), so without it nothing tells a model that silence means standing
still, and a model that learned to keep moving on its own keeps moving when the music stops.
Yalta et al. (2016) show their model stopping in silence (their Figure 7); ``evaluate``'s silence
test and the listening controls check it.

:func:`mirror_windows`: in a share of the windows the dancer is replaced by their mirror image (the
body reflected across the plane x = 0, left and right swapped: :class:`Mirror`), to the same
music. A dance mirrored is a dance to the same song (a dancer leading with the other foot), so a
corpus gives twice the bodies. Whether that helps depends on the corpus: docs/notebook/2026-11-real-dance.md
("mirrored dancers") has what it did on ballroom dance.

:func:`without_slow_travel`: in every window the root's slow travel across the floor is taken out of
its targets, for a run that draws its travel at generation (:mod:`kinectdata.targets.travel`): the
network is not asked for what it will be given. Asked for the real dancers' speeds along the floor
with their travel in them, a network that cannot know which way a dancer goes made them up with a
fast sway of its body instead (docs/notebook/2026-12-real-dance-variety.md, "What the field's kinetic
features measure here").

:func:`facing_windows`: every frame of every window turned about the vertical so that the body faces
one way (its left-right axis, from its hips and shoulders, along x), for a run that draws its
turning (:mod:`kinectdata.targets.turning`): in the world's frame a network that cannot know which
way a dancer faces learns a body averaged over the ways, a fraction as wide as the dancers'
(docs/notebook/2026-11-real-dance.md, "Tried since, on the folds: poses in the body's facing frame").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from kinectdata.core.errors import ConfigError
from kinectdata.features.silence import silence_features
from kinectdata.targets.facing import trunk_pairs, xz_columns
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec

MIN_MUSIC_FRACTION = 0.25
"""A silenced window keeps at least this share of its frames with music (the pose to hold comes from them)."""
MIN_SILENT_FRAMES = 30
"""And goes silent for at least this many frames (a second at 30 fps: long enough to see the stop)."""


def silent_frame(features: dict, fps: float) -> torch.Tensor:
    """The features [*F] of one motion frame of digital silence, for a dataset's feature settings
    (its manifest's ``config.features``) and frame rate: what the build computes for silence."""
    return torch.from_numpy(silence_features(features, fps))


def silence_windows(
    batch: dict[str, torch.Tensor], silent: torch.Tensor, share: float, generator: torch.Generator, context: int = 0
) -> dict[str, torch.Tensor]:
    """A training batch with the music of about ``share`` of its windows silenced from a random frame
    on, and their poses held from there.

    Args:
        batch: a :class:`~kinectdata.dataset.windows.WindowDataset` batch: ``audio`` [B, L, *F],
            ``pose`` / ``previous`` / ``mask`` / ``previous_mask`` [B, L, D].
        silent: one frame of silence's features [*F] (:func:`silent_frame`).
        share: probability that a window is silenced, 0..1.
        generator: the draws (seeded: a run stays reproducible and resumable).
        context: the windows' first frames that no loss counts (``TrainConfig.context``): the
            silence starts after them, in the part the losses see, with the music before it
            (:data:`MIN_MUSIC_FRACTION` of that part). Silence from inside the context would leave
            the losses a window of one held pose, whose spectra have nothing to compare with.

    Returns:
        A new batch (the given tensors are not changed). In a silenced window from frame s on the
        audio is ``silent``, the pose is the pose of frame s - 1 (held; its mask too), and the
        previous pose is the held pose from frame s + 1 on, and the next pose from frame s - 1 on;
        rhythm labels (``rhythm_valid``), where the batch has them, are invalid from frame s on.
    """
    audio, pose = batch["audio"], batch["pose"]
    B, L = pose.shape[:2]
    first = context + max(1, int(np.ceil(MIN_MUSIC_FRACTION * (L - context))))
    last = L - MIN_SILENT_FRAMES
    draws = torch.rand(B, generator=generator)
    starts = torch.randint(first, max(first + 1, last + 1), (B,), generator=generator)
    chosen = [(b, int(s)) for b, s in enumerate(starts) if draws[b] < share and first <= int(s) <= last]
    if not chosen:
        return batch
    changed = ("audio", "pose", "previous", "next", "mask", "previous_mask", "rhythm_valid")
    out = {k: v.clone() if k in changed else v for k, v in batch.items()}
    for b, s in chosen:
        out["audio"][b, s:] = silent.to(audio.dtype)
        out["pose"][b, s:] = pose[b, s - 1]
        out["mask"][b, s:] = batch["mask"][b, s - 1]
        if s + 1 < L:
            out["previous"][b, s + 1 :] = pose[b, s - 1]
            out["previous_mask"][b, s + 1 :] = batch["mask"][b, s - 1]
        if "next" in out:
            out["next"][b, s - 1 :] = pose[b, s - 1]
        if "rhythm_valid" in out:
            out["rhythm_valid"][b, s:] = False
    return out


@dataclass(frozen=True)
class Mirror:
    """A dataset's normalised targets [..., D] in the motion's mirror image:
    ``mirrored = targets[..., source] * gain + shift`` (the mirror of
    :meth:`~kinectdata.targets.specs.TargetSpec.mirror_columns`, through the normalisation).

    Attributes:
        source: [D] long, the column each component is read from.
        gain, shift: [D] float32.
    """

    source: torch.Tensor
    gain: torch.Tensor
    shift: torch.Tensor

    @classmethod
    def of_dataset(cls, manifest: dict[str, Any]) -> Mirror:
        """The mirror of a dataset's targets, from its manifest (target spec and normalisation).

        Raises:
            ConfigError: the target cannot be mirrored (:meth:`TargetSpec.mirror_columns`).
        """
        source, sign = TargetSpec.from_dict(manifest["config"]["target"]).mirror_columns()
        norm = Normalizer.from_dict(manifest["normalisation"])
        scale, offset = norm.scale, norm.offset
        # y = (x - offset) * scale for each column; the mirrored x is sign * x[source]
        gain = sign * scale / scale[source]
        shift = (sign * offset[source] - offset) * scale
        return cls(torch.from_numpy(source), torch.from_numpy(gain).float(), torch.from_numpy(shift).float())

    def poses(self, values: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
        """Normalised poses [..., D] in the mirror image; 0 where ``mask`` [..., D] (the given
        poses' mask, when known) leaves the mirrored component unknown, as the shards store it."""
        mirrored = values[..., self.source] * self.gain.to(values.dtype) + self.shift.to(values.dtype)
        if mask is None:
            return mirrored
        return torch.where(mask[..., self.source], mirrored, torch.zeros((), dtype=values.dtype))


def mirror_windows(
    batch: dict[str, torch.Tensor], mirror: Mirror, share: float, generator: torch.Generator
) -> dict[str, torch.Tensor]:
    """A training batch with about ``share`` of its windows danced by the mirror image of their
    dancer (``pose``, ``previous``, ``next`` and their masks), to the same music.

    Args:
        batch: a :class:`~kinectdata.dataset.windows.WindowDataset` batch (poses [B, L, D];
            ``next`` has no mask of its own and is mirrored as it is).
        mirror: the dataset's :class:`Mirror`.
        share: probability that a window is mirrored, 0..1.
        generator: the draws (seeded: a run stays reproducible and resumable).

    Returns:
        A new batch (the given tensors are not changed).
    """
    chosen = torch.rand(batch["pose"].shape[0], generator=generator) < share
    if not chosen.any():
        return batch
    out = dict(batch)
    for values, mask in (("pose", "mask"), ("previous", "previous_mask"), ("next", None)):
        if values in batch:
            out[values] = batch[values].clone()
            out[values][chosen] = mirror.poses(batch[values][chosen], None if mask is None else batch[mask][chosen])
    for mask in ("mask", "previous_mask"):
        out[mask] = batch[mask].clone()
        out[mask][chosen] = batch[mask][chosen][..., mirror.source]
    return out


SLOW_TRAVEL_S = 2.0
"""The slow travel is the root's horizontal place averaged over this many seconds (centred): a
moving average whose first zero is at 0.5 Hz, the travel process's cut-off."""


@dataclass(frozen=True)
class SlowTravel:
    """What :func:`without_slow_travel` needs of a dataset: the root's x and z columns, their
    normalisation (``y = (x - offset) * scale``) and the moving average's width in frames."""

    columns: tuple[int, int]
    scale: tuple[float, float]
    offset: tuple[float, float]
    frames: int

    @classmethod
    def of_dataset(cls, manifest: dict[str, Any], fps: float) -> SlowTravel:
        spec = TargetSpec.from_dict(manifest["config"]["target"])
        norm = Normalizer.from_dict(manifest["normalisation"])
        start = spec.columns(spec.root, "position").start
        columns = (start, start + 2)
        width = max(3, int(round(SLOW_TRAVEL_S * fps)) | 1)  # odd: centred
        return cls(
            columns,
            tuple(float(norm.scale[c]) for c in columns),
            tuple(float(norm.offset[c]) for c in columns),
            width,
        )


def _moving_average(values: torch.Tensor, valid: torch.Tensor, frames: int) -> torch.Tensor:
    """[N, L] centred moving average over ``frames`` of the valid values (fewer at the edges)."""
    kernel = torch.ones(1, 1, frames, dtype=values.dtype, device=values.device)
    total = torch.nn.functional.conv1d((values * valid)[:, None], kernel, padding=frames // 2)[:, 0]
    count = torch.nn.functional.conv1d(valid[:, None], kernel, padding=frames // 2)[:, 0]
    return total / count.clamp(min=1.0)


def _as_sequence(values: dict[str, torch.Tensor]) -> torch.Tensor:
    """The poses before, in and after a window as one sequence [B, L + 1 (+ 1), ...]: ``previous``'s
    first, ``pose``'s, and ``next``'s last when the batch has it."""
    parts = [values["previous"][:, :1], values["pose"]]
    if "next" in values:
        parts.append(values["next"][:, -1:])
    return torch.cat(parts, dim=1)


def _from_sequence(out: dict[str, torch.Tensor], sequence: torch.Tensor, frames: int) -> None:
    """Write a :func:`_as_sequence` sequence back into ``out``'s ``previous``, ``pose`` and ``next``."""
    out["previous"] = sequence[:, :frames]
    out["pose"] = sequence[:, 1 : frames + 1]
    if "next" in out:
        out["next"] = sequence[:, 2 : frames + 2]


def without_slow_travel(batch: dict[str, torch.Tensor], travel: SlowTravel) -> dict[str, torch.Tensor]:
    """A batch (``pose``, ``previous`` and ``next`` [B, L, D] normalised, with the first two's masks)
    whose root's x and z are its place less its moving average over ``travel.frames``: its sway and
    steps about where it is going, not the going (the poses before, in and after the window taken as
    one sequence, so that a window's ``previous`` is its ``pose`` a frame later). A new batch; the
    given tensors are not changed."""
    frames = batch["pose"].shape[1]
    sequence = _as_sequence(batch).clone()
    masks = {"previous": batch["previous_mask"], "pose": batch["mask"]}
    if "next" in batch:
        masks["next"] = torch.ones_like(batch["next"], dtype=torch.bool)  # the last pose, known where any is
        masks["next"][:, -1:] = batch["mask"][:, -1:]
    valid = _as_sequence(masks)
    for column, scale, offset in zip(travel.columns, travel.scale, travel.offset):
        places, known = sequence[..., column], valid[..., column].to(sequence.dtype)
        slow = _moving_average(places, known, travel.frames)
        # in metres: x - average(x); normalised: y - average(y) - offset * scale
        sequence[..., column] = (places - slow - offset * scale) * known
    out = dict(batch)
    _from_sequence(out, sequence, frames)
    return out


FACING_SMOOTHING_S = 0.5
"""The heading a frame is turned by is the trunk's, averaged over this many seconds (centred): the
turning the run draws is slow (its speed correlated over about 0.4 s on tang2018), and a heading
read frame by frame from four tracked joints shakes; turned by it, every joint shook with it (jerk
2.3 x the real dancers' on a fold, docs/notebook/2026-12-real-dance-variety.md)."""


@dataclass(frozen=True)
class Facing:
    """What :func:`facing_windows` needs of a dataset's targets: the x and z columns of the joints
    turned (every positioned joint but the root, whose values are its travel), the left and right
    joints of the pairs the facing is read from (indices into those joints), the columns'
    normalisation (``y = (x - offset) * scale``) and the heading's smoothing in frames."""

    x: torch.Tensor
    z: torch.Tensor
    left: torch.Tensor
    right: torch.Tensor
    scale: torch.Tensor
    offset: torch.Tensor
    frames: int = 1

    @classmethod
    def of_dataset(cls, manifest: dict[str, Any]) -> Facing:
        """Raises ConfigError: the targets are not 3-D positions centred on their root, or name no
        left and right joint."""
        spec = TargetSpec.from_dict(manifest["config"]["target"])
        if not manifest["config"].get("root_centre"):
            raise ConfigError("facing: the targets must be 3-D joint positions centred on their root (--root-centre)")
        left, right = trunk_pairs(spec)
        norm = Normalizer.from_dict(manifest["normalisation"])
        columns = xz_columns(spec)  # [J, 2]
        return cls(
            torch.tensor(columns[:, 0]),
            torch.tensor(columns[:, 1]),
            torch.tensor(left),
            torch.tensor(right),
            torch.tensor(norm.scale[columns], dtype=torch.float32),
            torch.tensor(norm.offset[columns], dtype=torch.float32),
            max(1, int(round(FACING_SMOOTHING_S * float(manifest["config"]["fps"]))) | 1),
        )


def _smooth_heading(heading: torch.Tensor, known: torch.Tensor, frames: int) -> torch.Tensor:
    """[B, S] headings (rad) unwrapped along the frames and averaged over ``frames`` centred (the
    known ones; fewer at the edges); 0 where unknown."""
    step = torch.diff(heading, dim=1)
    step = torch.remainder(step + math.pi, 2 * math.pi) - math.pi  # the shortest way round
    step = torch.where(known[:, 1:] & known[:, :-1], step, torch.zeros_like(step))
    unwrapped = torch.cat([heading[:, :1], heading[:, :1] + torch.cumsum(step, dim=1)], dim=1)
    if frames > 1:
        unwrapped = _moving_average(unwrapped, known.to(unwrapped.dtype), frames)
    return torch.where(known, unwrapped, torch.zeros_like(unwrapped))


def facing_windows(batch: dict[str, torch.Tensor], facing: Facing) -> dict[str, torch.Tensor]:
    """A batch whose every pose (``pose``, ``previous``, ``next``) is turned about the vertical
    through its root by the trunk's heading (the angle of the sum of its trunk pairs'
    left-minus-right vectors, averaged over ``facing.frames``: :func:`_smooth_heading`), so that
    the body faces one way; a frame where a pair's joint is unknown is left as it is. A new batch."""
    frames = batch["pose"].shape[1]
    sequence = _as_sequence(batch).clone()
    known = _as_sequence({"previous": batch["previous_mask"], "pose": batch["mask"],
                          **({"next": batch["mask"]} if "next" in batch else {})})  # fmt: skip
    scale, offset = facing.scale.to(sequence), facing.offset.to(sequence)
    x = sequence[..., facing.x] / scale[:, 0] + offset[:, 0]  # [B, S, J] metres about the root
    z = sequence[..., facing.z] / scale[:, 1] + offset[:, 1]
    across_x = (x[..., facing.left] - x[..., facing.right]).sum(dim=-1)
    across_z = (z[..., facing.left] - z[..., facing.right]).sum(dim=-1)
    pair_known = (known[..., facing.x[facing.left]] & known[..., facing.x[facing.right]]).all(dim=-1)
    heading = _smooth_heading(torch.atan2(across_z, across_x), pair_known, facing.frames)
    cos, sin = torch.cos(heading)[..., None], torch.sin(heading)[..., None]
    turned_x, turned_z = cos * x + sin * z, -sin * x + cos * z  # by -heading
    turned = pair_known[..., None]  # a frame whose trunk is unknown is left as it is
    valid_x, valid_z = known[..., facing.x] & turned, known[..., facing.z] & turned
    sequence[..., facing.x] = torch.where(valid_x, (turned_x - offset[:, 0]) * scale[:, 0], sequence[..., facing.x])
    sequence[..., facing.z] = torch.where(valid_z, (turned_z - offset[:, 1]) * scale[:, 1], sequence[..., facing.z])
    out = dict(batch)
    _from_sequence(out, sequence, frames)
    return out
