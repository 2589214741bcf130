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
corpus gives twice the bodies. Whether that helps depends on the corpus: docs/benchmarks.md
("mirrored dancers") has what it did on ballroom dance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from kinectdata.features.silence import silence_features
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
